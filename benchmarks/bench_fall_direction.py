#!/usr/bin/env python3
"""The learned fall direction: chosen by cross-validation on development data, then held out.

For a model (its triggers: first falling output in ``[t_push, t_fallen)``, its recommended
tau_his, estimated state):

1. **Development** (``--dev``; ``--no-cv`` skips it): 5-fold cross-validation (``--repeats`` shuffles) over the
   triggered falls of the direction learner at its settings
   (:data:`~fall_predictor.learning.direction_training.DIRECTION_LEARNER_PARAMS`) and at
   neighbouring ones, without the mirror images, and with one input left out at a time (which
   inputs carry the information); the momentum's direction as the reference.
2. **Held out** (``--test``): the direction fitted on all development falls, against the
   momentum's and the capture point's, at the test triggers: median and p90 angular error with
   95 % bootstrap intervals over trajectories.

3. **A reference for the time to fall** (not shipped): the same learner on the same inputs fitted
   on the time left (``t_fallen - t``) at the development triggers, and at every 10th sample from
   each trigger until fallen, against the model's own regressor and a constant (the development
   triggers' median): errors at the test triggers and over the test samples after them.

Writes JSON (``--out``).

    python benchmarks/bench_fall_direction.py --dev data/d1000s --test data/t1000s_2026 \\
        --model models/default_model.json --out docs/time_and_direction/fall_direction_cv_asimo_like.json
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fall_predictor.data.dataset import robot_total_mass_kg
from fall_predictor.learning.direction_training import DIRECTION_LEARNER_PARAMS, fit_learned_direction
from fall_predictor.learning.time_to_fall_training import time_left_after_triggers
from fall_predictor.learning.training import load_dataset
from fall_predictor.learning.when_where import (DirectionSamples, direction_errors_deg,
                                                direction_samples, trigger_indices)
from fall_predictor.monitor.fall_direction import (DIRECTION_INPUT_NAMES, direction_inputs,
                                                   momentum_direction)
from fall_predictor.monitor.model_file import load_model

from bench_time_to_fall import spread      # median and p90 with bootstrap intervals

VARIANTS = {
    'shipped settings': {},
    '200 trees, rate 0.03': {'max_iter': 200, 'learning_rate': 0.03},
    '100 trees, rate 0.1': {'learning_rate': 0.1},
    'depth 2': {'max_depth': 2},
    '40 a leaf': {'min_samples_leaf': 40},
}


def time_to_fall_reference(dev, test, regressor) -> dict:
    """Absolute time-to-fall errors [s] at the test triggers and over every 10th sample from
    the trigger until fallen: boosting on the direction inputs fitted at the development
    triggers only and on all those samples, the model's regressor, a constant."""
    from sklearn.ensemble import HistGradientBoostingRegressor

    def inputs(X):
        values = [direction_inputs(x.tolist()) for x in X]
        return np.array([v if v is not None else (np.nan,) * len(DIRECTION_INPUT_NAMES)
                         for v in values])
    (X_dev, _, left_dev, trig_dev), (X_test, mode_test, left_test, trig_test) = dev, test
    predictions = {'constant (the development triggers\' median)':
                   np.full(left_test.size, np.median(left_dev[trig_dev]))}
    for name, rows in (('boosting fitted at the triggers', trig_dev),
                       ('boosting fitted from the trigger to fallen', np.ones_like(trig_dev))):
        fitted = HistGradientBoostingRegressor(**DIRECTION_LEARNER_PARAMS, early_stopping=False,
                                               random_state=0).fit(inputs(X_dev[rows]), left_dev[rows])
        predictions[name] = fitted.predict(inputs(X_test))
    if regressor is not None:
        predictions['model regressor'] = np.array(
            [regressor.predict_one(x.tolist(), m) for x, m in zip(X_test, mode_test)])
    return {name: {'at_triggers': spread(np.abs(p - left_test)[trig_test]),
                   'trigger_to_fallen_median_s': float(np.median(np.abs(p - left_test)))}
            for name, p in predictions.items()}


def cross_validated(samples: DirectionSamples, repeats: int, **fit) -> dict[str, float]:
    """Median error [deg] over 5-fold CV (``repeats`` shuffles) of the learned direction
    (``fit``: :func:`fit_learned_direction` arguments)."""
    errors, momentum = [], []
    n = samples.X.shape[0]
    for repeat in range(repeats):
        order = np.random.default_rng(repeat).permutation(n)
        for fold in np.array_split(order, 5):
            train = np.setdiff1d(order, fold)
            train_s = DirectionSamples(samples.X[train], samples.actual[train])
            test_s = DirectionSamples(samples.X[fold], samples.actual[fold])
            learned = fit_learned_direction(train_s, **fit)
            errors.append(direction_errors_deg(test_s, learned.direction))
            momentum.append(direction_errors_deg(test_s, momentum_direction))
    return {'median_deg': float(np.median(np.concatenate(errors))),
            'momentum_median_deg': float(np.median(np.concatenate(momentum)))}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--dev', type=Path, required=True)
    parser.add_argument('--test', type=Path, required=True)
    parser.add_argument('--model', type=Path, required=True)
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--no-cv', action='store_true',
                        help='skip the cross-validation on the development data (step 1)')
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    lists, metadata = load_model(args.model)
    tau_his, guard = metadata.recommended_tau_his_s, metadata.feature_settings.guard_com_height_m
    sets, time_left = {}, {}
    for name, data in (('dev', args.dev), ('test', args.test)):
        report = load_dataset(data, args.jobs, progress=True, state='estimated')
        triggers = trigger_indices(report.trajectories, lists, tau_his, guard)
        sets[name] = direction_samples(data, report.trajectories, triggers)
        time_left[name] = time_left_after_triggers(report.trajectories, triggers)
    dev, test = sets['dev'], sets['test']
    result: dict = {'model': str(args.model), 'dev': str(args.dev), 'test': str(args.test),
                    'tau_his_s': tau_his, 'state': 'estimated', 'inputs': list(DIRECTION_INPUT_NAMES),
                    'learner': DIRECTION_LEARNER_PARAMS, 'aim_median_deg': 15.0,
                    'triggered_falls': {'dev': int(dev.X.shape[0]), 'test': int(test.X.shape[0])}}
    if not args.no_cv:
        cv = {name: cross_validated(dev, args.repeats, params=params)
              for name, params in VARIANTS.items()}
        cv['without the mirror images'] = cross_validated(dev, args.repeats, mirror=False)
        for name in DIRECTION_INPUT_NAMES:
            cv[f'without {name}'] = cross_validated(dev, args.repeats, ignore_inputs=(name,))
        result['dev_cross_validation'] = cv
    learned = fit_learned_direction(dev)
    mass = robot_total_mass_kg(args.test)
    result['held_out'] = {
        'learned': spread(direction_errors_deg(test, learned.direction)),
        'momentum': spread(direction_errors_deg(test, momentum_direction)),
        'capture_point': spread(direction_errors_deg(test, 'capture_point', mass)),
    }
    result['time_to_fall_reference_s'] = time_to_fall_reference(
        time_left['dev'], time_left['test'], metadata.time_to_fall)
    text = json.dumps(result, indent=1)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')
    print(text)
    return result


if __name__ == '__main__':
    main()
