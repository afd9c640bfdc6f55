#!/usr/bin/env python3
"""Time to fall and fall direction at the trigger, on held-out data, against naive references,
and which inputs carry the information.

A model (default the shipped one) triggers on the development and the test data (its first
falling output in ``[t_push, t_fallen)``, its recommended tau_his; estimated state). At each test
trigger ``k``:

**Time to fall** (target ``t_fallen - t_k``), absolute error of:

* ``naive``: a constant, the median time to fall at the development triggers
  (``naive_hindsight``: the test triggers' own median, the best constant there is);
* ``shipped``: the model file's regressor (trained on every falling state, push to fall);
* ``trigger_tree[<inputs>]``: a regression tree fitted on development samples from each trigger
  to ``--window`` after it (the states the monitor reports a time to fall on when it matters),
  on all 15 features and on groups of them: which inputs carry the information;
* ``trigger_boosting[all]``: gradient boosting on the same samples (a reference for what a
  larger learner could get, not a shippable model).

**Direction** (the CoM's horizontal displacement from ``t_k`` to ``t_fallen``, heading frame),
angular error of the momentum direction, the capture-point bearing, a naive constant (the
development falls' circular-mean direction) and ``boosting[all]``: the momentum direction turned
by an angle that gradient boosting predicts from all 15 features at the trigger (two regressors,
the cosine and sine of the training falls' turn from their momentum direction to the actual one:
does the state know more about the direction than the momentum does?).

The references (naive constants, trees, boosting) are fitted on the development data
(``--dev``), or without it by ``--folds``-fold cross-validation over the test set's trajectories
(each fold predicted by what the others taught). Each: median and p90 with 95 % bootstrap
intervals over trajectories. Writes JSON (``--out``).

    python benchmarks/bench_time_to_fall.py --dev data/d1000s --test data/t1000s_2026 \\
        --model models/default_model.json --out docs/time_and_direction/time_to_fall_default_model.json
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


def _angle(v) -> float:
    return math.atan2(float(v[1]), float(v[0]))


def _turn_regressors(trajs, triggers, actual, mass_kg: float, regressor):
    """Two regressors fitted at the training triggers: the cosine and the sine of the turn from
    the momentum direction to the direction the CoM actually left in."""
    xs, turns = [], []
    for traj, k, a in zip(trajs, triggers, actual):
        if k is None or a is None:
            continue
        m = momentum_direction(traj.X[k].tolist(), mass_kg)
        if np.all(np.isfinite(m[:2])):
            xs.append(traj.X[k])
            turns.append(_angle(a) - _angle(m))
    X, turns = np.array(xs), np.array(turns)
    fitted = []
    for y in (np.cos(turns), np.sin(turns)):
        model = regressor(max_iter=200, learning_rate=0.05, min_samples_leaf=10, random_state=0)
        fitted.append(model.fit(X, y))
    return fitted


def _turned(direction, turn, x) -> np.ndarray:
    """``direction`` turned by the angle the regressors predict for features ``x``."""
    if not np.all(np.isfinite(direction[:2])):
        return direction
    row = np.asarray(x, dtype=float).reshape(1, -1)
    c, s = (float(model.predict(row)[0]) for model in turn)
    angle = _angle(direction) + math.atan2(s, c)
    return np.array([math.cos(angle), math.sin(angle), 0.0])


def main(argv: list[str] | None = None) -> dict:
    from sklearn.ensemble import HistGradientBoostingRegressor
    from sklearn.tree import DecisionTreeRegressor

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--dev', type=Path, default=None,
                        help='development data for the references (default: CV over --test)')
    parser.add_argument('--folds', type=int, default=5, help='CV folds without --dev')
    parser.add_argument('--test', type=Path, required=True)
    parser.add_argument('--model', type=Path, default=MODELS / 'default_model.json')
    parser.add_argument('--window', type=float, default=0.1, help='trigger-time training window [s]')
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)

    lists, metadata = load_model(args.model)
    tau_his = metadata.recommended_tau_his_s or 0.0
    mass_kg = metadata.robot_mass_kg
    guard = metadata.feature_settings.guard_com_height_m
    test = load_dataset(args.test, jobs=args.jobs, state='estimated').trajectories
    test_triggers = trigger_indices(test, lists, tau_his, guard)
    test_actual = actual_directions(args.test, test, test_triggers)
    # The learned references are fitted on the development data (--dev), else by K-fold
    # cross-validation over the test set's trajectories: each fold predicted by what the
    # other folds taught.
    if args.dev is not None:
        dev = load_dataset(args.dev, jobs=args.jobs, state='estimated').trajectories
        dev_triggers = trigger_indices(dev, lists, tau_his, guard)
        splits = [(dev, dev_triggers, actual_directions(args.dev, dev, dev_triggers),
                   list(range(len(test))))]
    else:
        fold_of = np.arange(len(test)) % args.folds
        splits = []
        for f in range(args.folds):
            train = [i for i in range(len(test)) if fold_of[i] != f]
            splits.append(([test[i] for i in train], [test_triggers[i] for i in train],
                           [test_actual[i] for i in train], [i for i in range(len(test)) if fold_of[i] == f]))
    names = ['naive'] + [f'trigger_tree[{g}]' for g in GROUPS] + ['trigger_boosting[all]']
    ttf_errors: dict[str, list] = {name: [] for name in names}
    dir_errors: dict[str, list] = {'momentum': [], 'capture_point': [], 'naive': [], 'boosting[all]': []}
    y_all, window_samples_n, importances = [], 0, np.zeros(len(FEATURE_NAMES))
    for train, train_triggers, train_actual, held in splits:
        held = [i for i in held if test_triggers[i] is not None]
        if not held:
            continue
        X_held = np.array([test[i].X[test_triggers[i]] for i in held])
        y_held = np.array([test[i].t_fallen - test[i].t[test_triggers[i]] for i in held])
        y_all.extend(y_held)
        _, y_train = at_triggers(train, train_triggers)
        ttf_errors['naive'].extend(np.abs(float(np.median(y_train)) - y_held))
        X_win, y_win = window_samples(train, train_triggers, args.window)
        window_samples_n += y_win.size
        for group, cols_names in GROUPS.items():
            cols = [FEATURE_NAMES.index(n) for n in cols_names]
            tree = DecisionTreeRegressor(max_depth=6, min_samples_leaf=20, random_state=0)
            tree.fit(X_win[:, cols], y_win)
            ttf_errors[f'trigger_tree[{group}]'].extend(np.abs(tree.predict(X_held[:, cols]) - y_held))
            if group == 'all':
                importances += tree.feature_importances_ / len(splits)
        boost = HistGradientBoostingRegressor(max_iter=300, learning_rate=0.05, random_state=0)
        boost.fit(X_win, y_win)
        ttf_errors['trigger_boosting[all]'].extend(np.abs(boost.predict(X_held) - y_held))
        # Direction: the naive constant is the training falls' circular-mean direction.
        known = [a for a in train_actual if a is not None]
        mean_angle = math.atan2(sum(a[1] for a in known), sum(a[0] for a in known))
        naive = np.array([math.cos(mean_angle), math.sin(mean_angle)])
        turn = _turn_regressors(train, train_triggers, train_actual, mass_kg, HistGradientBoostingRegressor)
        for i in held:
            actual = test_actual[i]
            if actual is None:
                continue
            x = test[i].X[test_triggers[i]].tolist()
            for name, predicted in (('momentum', momentum_direction(x, mass_kg)),
                                    ('capture_point', capture_point_direction(x, mass_kg)),
                                    ('naive', naive),
                                    ('boosting[all]', _turned(momentum_direction(x, mass_kg), turn, x))):
                if np.all(np.isfinite(predicted[:2])):
                    dir_errors[name].append(math.degrees(angular_error_rad(predicted, actual)))
    y_test = np.array(y_all)
    ttf = {name: spread(v) for name, v in ttf_errors.items()}
    ttf['naive_hindsight'] = spread(np.abs(float(np.median(y_test)) - y_test))
    if metadata.time_to_fall is not None:
        predicted = np.array([metadata.time_to_fall.predict_one(traj.X[k].tolist(), int(traj.mode[k]))
                              for traj, k in zip(test, test_triggers) if k is not None])
        y_in_order = np.array([traj.t_fallen - traj.t[k] for traj, k in zip(test, test_triggers)
                               if k is not None])
        ttf['shipped'] = spread(np.abs(predicted - y_in_order))
    result = {
        'dev': None if args.dev is None else str(args.dev), 'test': str(args.test),
        'references_fitted': 'on --dev' if args.dev is not None else f'{args.folds}-fold CV over --test',
        'model': str(args.model), 'tau_his_s': tau_his, 'guard_com_height_m': guard,
        'triggers': {'test': int(sum(k is not None for k in test_triggers)),
                     'test_fallen': int(sum(t.fallen for t in test))},
        'time_to_fall_at_trigger_s': {'median': float(np.median(y_test)),
                                      'p10': float(np.percentile(y_test, 10)),
                                      'p90': float(np.percentile(y_test, 90))},
        'trigger_window_s': args.window, 'trigger_window_samples': int(window_samples_n),
        'time_to_fall_error_s': ttf,
        'trigger_tree_importances': dict(zip(FEATURE_NAMES, (round(float(v), 3) for v in importances))),
        'direction_error_deg': {name: spread(v) for name, v in dir_errors.items()},
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
