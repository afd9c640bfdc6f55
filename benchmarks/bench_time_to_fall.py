#!/usr/bin/env python3
"""Time to fall and fall direction at the trigger, on held-out data, against naive references,
and which inputs carry the information.

A model (default the shipped one) triggers on the development and the test data (its first
falling output in ``[t_push, t_fallen)``, its recommended tau_his; estimated state). At each test
trigger ``k``:

**Time to fall** (target ``t_fallen - t_k``), absolute error of:

* ``naive``: a constant, the median time to fall at the development triggers;
* ``shipped``: the model file's regressor (trained on every falling state, push to fall);
* ``trigger_tree[<inputs>]``: a regression tree fitted on development samples from each trigger
  to ``--window`` after it (the states the monitor reports a time to fall on when it matters),
  on all 15 features and on groups of them: which inputs carry the information;
* ``trigger_boosting[all]``: gradient boosting on the same samples (a reference for what a
  larger learner could get, not a shippable model).

**Direction** (the CoM's horizontal displacement from ``t_k`` to ``t_fallen``, heading frame),
angular error of the momentum direction, the capture-point bearing and a naive constant (the
development falls' circular-mean direction).

Each: median and p90 with 95 % bootstrap intervals over trajectories. Writes JSON (``--out``).

    python benchmarks/bench_time_to_fall.py --dev data/d1000s --test data/t1000s_2026 \\
        --out docs/time_to_fall_t1000.json
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from fall_predictor.learning.intervals import bootstrap_quantile_interval
from fall_predictor.learning.training import load_dataset
from fall_predictor.learning.when_where import actual_directions, trigger_indices
from fall_predictor.monitor.fall_direction import (angular_error_rad, capture_point_direction,
                                                   momentum_direction)
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import FEATURE_NAMES

MODELS = Path(__file__).resolve().parents[1] / 'models'
GROUPS = {
    'all': FEATURE_NAMES,
    'com_height': ('com_z',),
    'com_position': ('com_x', 'com_y', 'com_z'),
    'linear_momentum': ('lin_mom_x', 'lin_mom_y', 'lin_mom_z'),
    'com_and_linear_momentum': ('com_x', 'com_y', 'com_z', 'lin_mom_x', 'lin_mom_y', 'lin_mom_z'),
    'angular_momentum': ('ang_mom_x', 'ang_mom_y', 'ang_mom_z'),
    'momentum_rates': ('d_lin_mom_x', 'd_lin_mom_y', 'd_lin_mom_z',
                       'd_ang_mom_x', 'd_ang_mom_y', 'd_ang_mom_z'),
}


def spread(errors) -> dict:
    """Median and p90 with bootstrap 95 % intervals (one error per trajectory)."""
    e = np.asarray(errors, dtype=float)
    if e.size == 0:
        return {'n': 0}
    return {'n': int(e.size), 'median': float(np.median(e)),
            'median_ci95': bootstrap_quantile_interval(e, 0.5),
            'p90': float(np.percentile(e, 90)), 'p90_ci95': bootstrap_quantile_interval(e, 0.9)}


def window_samples(trajs, triggers, window_s: float):
    """Features (n, 15) and time to fall (n,) from each trigger to ``window_s`` after it (before
    the fall)."""
    xs, ys = [], []
    for traj, k in zip(trajs, triggers):
        if k is None:
            continue
        idx = np.flatnonzero((traj.t >= traj.t[k]) & (traj.t < min(traj.t[k] + window_s, traj.t_fallen)))
        xs.append(traj.X[idx])
        ys.append(traj.t_fallen - traj.t[idx])
    return np.concatenate(xs), np.concatenate(ys)


def at_triggers(trajs, triggers):
    rows = [(traj.X[k], traj.t_fallen - traj.t[k]) for traj, k in zip(trajs, triggers) if k is not None]
    return np.array([r[0] for r in rows]), np.array([r[1] for r in rows])


def main(argv: list[str] | None = None) -> dict:
    from sklearn.ensemble import HistGradientBoostingRegressor
    from sklearn.tree import DecisionTreeRegressor

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--dev', type=Path, required=True)
    parser.add_argument('--test', type=Path, required=True)
    parser.add_argument('--model', type=Path, default=MODELS / 'default_model.json')
    parser.add_argument('--window', type=float, default=0.1, help='trigger-time training window [s]')
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)

    lists, metadata = load_model(args.model)
    tau_his = metadata.recommended_tau_his_s or 0.0
    mass_kg = metadata.robot_mass_kg
    data = {}
    for name, folder in (('dev', args.dev), ('test', args.test)):
        trajs = load_dataset(folder, jobs=args.jobs, state='estimated').trajectories
        data[name] = (trajs, trigger_indices(trajs, lists, tau_his,
                                             metadata.feature_settings.guard_com_height_m))
    dev, dev_triggers = data['dev']
    test, test_triggers = data['test']
    X_test, y_test = at_triggers(test, test_triggers)
    _, y_dev_triggers = at_triggers(dev, dev_triggers)

    ttf = {'naive': spread(np.abs(float(np.median(y_dev_triggers)) - y_test))}
    if metadata.time_to_fall is not None:
        predicted = np.array([metadata.time_to_fall.predict_one(traj.X[k].tolist(), int(traj.mode[k]))
                              for traj, k in zip(test, test_triggers) if k is not None])
        ttf['shipped'] = spread(np.abs(predicted - y_test))
    X_win, y_win = window_samples(dev, dev_triggers, args.window)
    importances = {}
    for group, names in GROUPS.items():
        cols = [FEATURE_NAMES.index(n) for n in names]
        tree = DecisionTreeRegressor(max_depth=6, min_samples_leaf=20, random_state=0)
        tree.fit(X_win[:, cols], y_win)
        ttf[f'trigger_tree[{group}]'] = spread(np.abs(tree.predict(X_test[:, cols]) - y_test))
        if group == 'all':
            importances = dict(zip(names, (round(float(v), 3) for v in tree.feature_importances_)))
    boost = HistGradientBoostingRegressor(max_iter=300, learning_rate=0.05, random_state=0)
    boost.fit(X_win, y_win)
    ttf['trigger_boosting[all]'] = spread(np.abs(boost.predict(X_test) - y_test))

    # Direction: the naive constant is the development falls' circular-mean direction.
    dev_actual = [a for a in actual_directions(args.dev, dev, dev_triggers) if a is not None]
    mean_angle = math.atan2(sum(a[1] for a in dev_actual), sum(a[0] for a in dev_actual))
    naive = np.array([math.cos(mean_angle), math.sin(mean_angle)])
    errors = {'momentum': [], 'capture_point': [], 'naive': []}
    for traj, k, actual in zip(test, test_triggers, actual_directions(args.test, test, test_triggers)):
        if actual is None:
            continue
        x = traj.X[k].tolist()
        for name, predicted in (('momentum', momentum_direction(x, mass_kg)),
                                ('capture_point', capture_point_direction(x, mass_kg)),
                                ('naive', naive)):
            if np.all(np.isfinite(predicted[:2])):
                errors[name].append(math.degrees(angular_error_rad(predicted, actual)))
    result = {
        'dev': str(args.dev), 'test': str(args.test), 'model': str(args.model), 'tau_his_s': tau_his,
        'triggers': {'dev': int(sum(k is not None for k in dev_triggers)),
                     'test': int(sum(k is not None for k in test_triggers)),
                     'test_fallen': int(sum(t.fallen for t in test))},
        'time_to_fall_at_trigger_s': {'median': float(np.median(y_test)),
                                      'p10': float(np.percentile(y_test, 10)),
                                      'p90': float(np.percentile(y_test, 90))},
        'naive_constant_s': float(np.median(y_dev_triggers)),
        'trigger_window_s': args.window, 'trigger_window_samples': int(y_win.size),
        'time_to_fall_error_s': ttf, 'trigger_tree_importances': importances,
        'direction_error_deg': {name: spread(v) for name, v in errors.items()},
        'naive_direction_deg': math.degrees(mean_angle),
        'aims': {'time_to_fall_median_s': 0.05, 'time_to_fall_p90_s': 0.2, 'direction_median_deg': 15.0},
    }
    text = json.dumps(result, indent=1, default=float)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')
    print(text)
    return result


if __name__ == '__main__':
    main()
