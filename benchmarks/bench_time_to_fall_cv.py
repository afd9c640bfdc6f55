#!/usr/bin/env python3
"""Which samples the time-to-fall regressor should learn from: cross-validation on development
data at a model's own triggers.

The monitor reports a time to fall from its trigger on; the shipped regressor (per-mode trees,
:func:`~fall_predictor.learning.time_to_fall_training.fit_time_to_fall`) learns from every
falling state, from the push on. For a model (its triggers: first falling output in
``[t_push, t_fallen)`` at its recommended tau_his, estimated state) this compares, by
``--folds``-fold cross-validation over the development trajectories (``--repeats`` shuffles),
regressors fitted on the training folds:

* ``per-mode trees, every falling state``: the shipped method;
* ``per-mode trees, trigger to fallen``: the same trees on every 10th sample from each training
  trigger until fallen (what the monitor reports on);
* ``boosting <settings>, trigger to fallen``: scikit-learn's gradient boosting on those samples
  and the 15 features, at the settings of :data:`BOOSTING` (small trees, as the monitor runs
  them at every falling sample; the absolute-error loss fits the median the aim is stated in);
* ``boosting (shipped settings), weighted ... / the first ... after the trigger only``: the
  shipped settings with samples nearer the trigger weighing more (:data:`NEAR_TRIGGER`): the
  trigger's own time to fall is the one the FALLING event carries;
* ``constant``: the training triggers' median time to fall;
* with ``--push-time``, ``boosting (shipped settings) + the time since the push``: the shipped
  regressor given the time since the push's onset beside the features, which the monitor is
  never told (a privileged reference: what knowing when the push came would buy);
* with ``--physics``, ``boosting (shipped settings) + physics``: the same regressor given inputs
  its trees cannot form from single features (:func:`_physics_inputs`: the capture point relative
  to the CoP, a linear inverted pendulum's time for it to reach 0.3 m, the CoM's lean, a
  ballistic drop time): whether the time to fall lacks a learner's arithmetic or information.

Errors at the test folds' triggers (median and p90 of the absolute error, pooled over folds and
repeats) and over every 10th sample from each test trigger until fallen. Writes JSON (``--out``).

    python benchmarks/bench_time_to_fall_cv.py --dev data/g1_dev1000 \\
        --model models/g1_attitude_model.json --out docs/time_and_direction/time_to_fall_cv_g1.json
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fall_predictor.data.dataset import robot_total_mass_kg
from fall_predictor.learning.time_to_fall_training import (TIME_TO_FALL_LEARNER_PARAMS,
                                                           fit_time_to_fall, fit_time_to_fall_samples,
                                                           time_left_after_triggers)
from fall_predictor.learning.training import load_dataset
from fall_predictor.learning.when_where import trigger_indices
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2

#: Gradient-boosting settings compared (scikit-learn's ``HistGradientBoostingRegressor``).
BOOSTING = {
    '200 trees of 31 leaves, rate 0.05, squared error': {'max_iter': 200, 'learning_rate': 0.05},
    '100 trees of depth 3, rate 0.05, absolute error': {
        'max_iter': 100, 'learning_rate': 0.05, 'max_depth': 3, 'min_samples_leaf': 20,
        'loss': 'absolute_error'},
    '100 trees of depth 3, rate 0.1, absolute error': {
        'max_iter': 100, 'learning_rate': 0.1, 'max_depth': 3, 'min_samples_leaf': 20,
        'loss': 'absolute_error'},
    '200 trees of depth 3, rate 0.05, absolute error': {
        'max_iter': 200, 'learning_rate': 0.05, 'max_depth': 3, 'min_samples_leaf': 20,
        'loss': 'absolute_error'},
    '100 trees of depth 3, rate 0.1, squared error': {
        'max_iter': 100, 'learning_rate': 0.1, 'max_depth': 3, 'min_samples_leaf': 20},
    '100 trees of 31 leaves, rate 0.1, squared error': {'max_iter': 100, 'learning_rate': 0.1},
    '200 trees of 15 leaves, rate 0.05, squared error': {
        'max_iter': 200, 'learning_rate': 0.05, 'max_leaf_nodes': 15},
    '400 trees of 31 leaves, rate 0.025, squared error': {'max_iter': 400, 'learning_rate': 0.025},
    '100 trees of 63 leaves, rate 0.1, squared error': {
        'max_iter': 100, 'learning_rate': 0.1, 'max_leaf_nodes': 63},
    '50 trees of 31 leaves, rate 0.2, squared error': {'max_iter': 50, 'learning_rate': 0.2},
}


#: Samples nearer the trigger weigh more (the trigger's time to fall goes out with the FALLING
#: event): weight of a sample ``s`` seconds after its trigger.
NEAR_TRIGGER = {
    'weighted exp(-s / 0.2 s)': lambda s: np.exp(-s / 0.2),
    'weighted exp(-s / 0.1 s)': lambda s: np.exp(-s / 0.1),
    'the first 0.3 s after the trigger only': lambda s: (s <= 0.3).astype(float),
    'the first 0.1 s after the trigger only': lambda s: (s <= 0.1).astype(float),
}


def _since_trigger(left: np.ndarray, at_trigger: np.ndarray) -> np.ndarray:
    """Seconds since each sample's trigger (the rows of one fall follow its trigger's row)."""
    since = np.empty_like(left)
    start = 0.0
    for k, (value, first) in enumerate(zip(left.tolist(), at_trigger.tolist())):
        if first:
            start = value
        since[k] = start - value
    return since


def _since_push(left: np.ndarray, at_trigger: np.ndarray, push_to_fallen: np.ndarray) -> np.ndarray:
    """Seconds since the push at each row of :func:`time_left_after_triggers` (the rows of one fall
    follow its trigger's row; ``push_to_fallen``: t_fallen - t_push of each triggered fall, in
    order)."""
    return push_to_fallen[np.cumsum(at_trigger) - 1] - left


def _physics_inputs(X: np.ndarray, mass_kg: float) -> np.ndarray:
    """Per row of features (the CoM and its momentum relative to the CoP, method §6): the capture
    point's x, y and distance from the CoP (the linear inverted pendulum at the CoM's height), the
    pendulum's time for it to grow to 0.3 m, the CoM's lean from the vertical over the CoP, and
    the time a free fall from the CoM's height and vertical speed takes to 0.33 m."""
    g = STANDARD_GRAVITY_M_S2
    height = np.maximum(X[:, 2], 0.05)
    omega = np.sqrt(g / height)
    vx, vy, vz = (X[:, 3:6] / mass_kg).T
    xi_x, xi_y = X[:, 0] + vx / omega, X[:, 1] + vy / omega
    xi = np.hypot(xi_x, xi_y)
    t_pendulum = np.log(np.maximum(0.3 / np.maximum(xi, 1e-3), 1e-3)) / omega
    lean = np.arctan2(np.hypot(X[:, 0], X[:, 1]), height)
    t_drop = (vz + np.sqrt(vz ** 2 + 2 * g * np.maximum(height - 0.33, 0.0))) / g
    return np.column_stack([xi_x, xi_y, xi, t_pendulum, lean, t_drop])


def _trees(regressor):
    return lambda X, modes: np.array([regressor.predict_one(x.tolist(), int(m))
                                      for x, m in zip(X, modes)])


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--dev', type=Path, required=True)
    parser.add_argument('--model', type=Path, required=True)
    parser.add_argument('--folds', type=int, default=5)
    parser.add_argument('--repeats', type=int, default=2)
    parser.add_argument('--push-time', action='store_true',
                        help='also the shipped regressor with the time since the push (privileged)')
    parser.add_argument('--physics', action='store_true',
                        help='also the shipped regressor with inputs from the pendulum and free fall')
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    from sklearn.ensemble import HistGradientBoostingRegressor

    lists, metadata = load_model(args.model)
    report = load_dataset(args.dev, args.jobs, progress=True, state='estimated')
    trajs = [t for t in report.trajectories if t.fallen]
    triggers = trigger_indices(trajs, lists, metadata.recommended_tau_his_s,
                               metadata.feature_settings.guard_com_height_m)
    pooled: dict[str, list] = {}
    for repeat in range(args.repeats):
        order = np.random.default_rng(repeat).permutation(len(trajs))
        for fold in np.array_split(order, args.folds):
            test = set(fold.tolist())
            train_idx = [i for i in order if i not in test]
            train = [trajs[i] for i in train_idx]
            train_left = time_left_after_triggers(train, [triggers[i] for i in train_idx])
            test_left = time_left_after_triggers([trajs[i] for i in fold],
                                                 [triggers[i] for i in fold])
            X, modes, left, at_trigger = train_left
            constant = float(np.median(left[at_trigger]))
            predictors = {
                'per-mode trees, every falling state': _trees(fit_time_to_fall(train)),
                'per-mode trees, trigger to fallen': _trees(
                    fit_time_to_fall_samples(X, modes, left)),
                "constant (the training triggers' median)":
                    lambda X, modes: np.full(len(X), constant),
            }
            for name, params in BOOSTING.items():
                fitted = HistGradientBoostingRegressor(**params, random_state=0).fit(X, left)
                predictors[f'boosting {name}, trigger to fallen'] = (
                    lambda X, modes, fitted=fitted: fitted.predict(X))
            since = _since_trigger(left, at_trigger)
            for name, weight in NEAR_TRIGGER.items():
                w = weight(since)
                fitted = HistGradientBoostingRegressor(
                    **TIME_TO_FALL_LEARNER_PARAMS, random_state=0).fit(X[w > 0], left[w > 0],
                                                                      sample_weight=w[w > 0])
                predictors[f'boosting (shipped settings), {name}'] = (
                    lambda X, modes, fitted=fitted: fitted.predict(X))
            if args.push_time:
                def with_push(rows, idx):
                    X_rows, _, left_rows, trigger_rows = rows
                    push_to_fallen = np.array([trajs[i].t_fallen - trajs[i].t_push for i in idx
                                               if triggers[i] is not None])
                    return np.hstack([X_rows, _since_push(left_rows, trigger_rows,
                                                          push_to_fallen)[:, None]])
                fitted = HistGradientBoostingRegressor(**TIME_TO_FALL_LEARNER_PARAMS, random_state=0
                                                       ).fit(with_push(train_left, train_idx), left)
                test_with_push = with_push(test_left, fold)
                # Called, as every predictor below, on test_left's rows: their push times are these.
                predictors['boosting (shipped settings) + the time since the push'] = (
                    lambda X, modes, fitted=fitted, Xp=test_with_push: fitted.predict(Xp))
            if args.physics:
                mass_kg = robot_total_mass_kg(args.dev)
                fitted = HistGradientBoostingRegressor(**TIME_TO_FALL_LEARNER_PARAMS, random_state=0
                                                       ).fit(np.hstack([X, _physics_inputs(X, mass_kg)]), left)
                predictors['boosting (shipped settings) + physics'] = (
                    lambda X, modes, fitted=fitted, m=mass_kg:
                        fitted.predict(np.hstack([X, _physics_inputs(X, m)])))
            for name, predict in predictors.items():
                X_t, modes_t, left_t, trig_t = test_left
                pooled.setdefault(name, []).append((np.abs(predict(X_t, modes_t) - left_t), trig_t))
    result = {'model': str(args.model), 'dev': str(args.dev), 'folds': args.folds,
              'repeats': args.repeats, 'state': 'estimated',
              'triggered_falls': int(sum(k is not None for k in triggers)),
              'falls': len(trajs)}
    for name, parts in pooled.items():
        error = np.concatenate([e for e, _ in parts])
        at = np.concatenate([t for _, t in parts])
        result[name] = {'at_triggers_median_s': float(np.median(error[at])),
                        'at_triggers_p90_s': float(np.percentile(error[at], 90)),
                        'trigger_to_fallen_median_s': float(np.median(error)),
                        'n_trigger_predictions': int(at.sum())}
    text = json.dumps(result, indent=1)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')
    print(text)
    return result


if __name__ == '__main__':
    main()
