"""Mirror augmentation and a third learner on a train / held-out test split.

Trains on ``--train`` (every ``--stride``-th sample, tau_plus ``--tau-plus``) and evaluates on
``--test`` (another seed) at ``--tau-his``, CoM guard on, with Wilson / bootstrap intervals:

* ``tree``: the shipped learner (TreeListLearner decision lists);
* ``tree_mirror``: the same with left-right mirror augmentation
  (:mod:`fall_predictor.learning.mirror`);
* ``hgb``: scikit-learn HistGradientBoostingClassifier per contact mode on the same weighted
  samples (a reference upper bound), with its per-sample prediction cost (one sample at a time,
  as the 1 kHz monitor would call it, and batched).

With ``--folds K`` the three are also cross-validated on ``--train`` over the sweep's folds
(:func:`~fall_predictor.learning.crossval.stratified_trajectory_folds`, ``--seed``), each
learner fitted on the same K-1 folds and evaluated on the same held-out fold, FPR and tau_lead
pooled over the folds with Wilson / bootstrap intervals (``cross_validated`` in the JSON);
``--test`` may then be left out.

Usage: ``python benchmarks/bench_mirror_hgb.py --train D [--test T] [--folds 10] [--state true]
[--out F.json]``
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from fall_predictor.data.dataset import dataset_guard_com_height_m
from fall_predictor.learning.crossval import stratified_trajectory_folds
from fall_predictor.learning.evaluation import evaluation_result_json
from fall_predictor.learning.learners import training_set
from fall_predictor.learning.metrics import evaluate_atomic, evaluate_lists
from fall_predictor.learning.nested import pool_results, pooled_json
from fall_predictor.learning.training import fit_strided, load_dataset, make_learner, subsample
from fall_predictor.monitor.records import FALLING, N_CONTACT_MODES

KEEP = ('n_trajectories', 'n_balanced', 'n_fallen', 'n_false_positives', 'fpr', 'fpr_ci95',
        'tau_lead_s', 'tau_lead_ci95', 'n_missed', 'misses_lists_only', 'tau_lead_lists_only',
        'n_pre_push_alarms_balanced', 'mean_rule_size')


def short(result) -> dict:
    payload = evaluation_result_json(result)
    return {k: payload[k] for k in KEEP if k in payload}


def fit_hgb(train, tau_plus_s, stride):
    from sklearn.ensemble import HistGradientBoostingClassifier

    X, y, w, modes, _ = training_set([subsample(t, stride) for t in train], tau_plus_s,
                                     4.0 * stride, 1.0 * stride)
    models = {}
    for m in range(N_CONTACT_MODES):
        rows = modes == m
        if (y[rows] == FALLING).any() and (y[rows] != FALLING).any():
            models[m] = HistGradientBoostingClassifier(max_iter=100, random_state=0).fit(
                X[rows], y[rows] == FALLING, sample_weight=w[rows])
    return models


def predict_hgb(models, X, mode):
    out = np.zeros(len(mode), dtype=bool)
    for m, model in models.items():
        rows = mode == m
        if rows.any():
            out[rows] = model.predict(X[rows])
    return out


def _fit_and_evaluate(train, test, args) -> dict:
    """Each learner fitted on ``train`` and evaluated on ``test``: {name: (result, extra)}."""
    out = {}
    for name, mirror in (('tree', False), ('tree_mirror', True)):
        start = time.perf_counter()
        lists = fit_strided(train, args.tau_plus, make_learner('tree'), args.stride, mirror=mirror)
        out[name] = (evaluate_lists(test, lists, (args.tau_his,), guard_com_height_m=args.guard)[args.tau_his],
                     {'fit_s': round(time.perf_counter() - start, 1),
                      'empty_modes': [m for m, dl in enumerate(lists.lists) if not dl.rules]})
    start = time.perf_counter()
    models = fit_hgb(train, args.tau_plus, args.stride)
    fit_s = time.perf_counter() - start
    atomic = [predict_hgb(models, t.X, t.mode) for t in test]
    out['hgb'] = (evaluate_atomic(test, atomic, (args.tau_his,), guard_com_height_m=args.guard)[args.tau_his],
                  {'fit_s': round(fit_s, 1), 'models': models})
    return out


def _cross_validated(train, args) -> dict:
    per_learner: dict[str, list] = {'tree': [], 'tree_mirror': [], 'hgb': []}
    sizes: dict[str, list] = {'tree': [], 'tree_mirror': []}
    for k, test_index in enumerate(stratified_trajectory_folds(train, args.folds, args.seed)):
        held = set(test_index.tolist())
        fold_train = [t for i, t in enumerate(train) if i not in held]
        fold_test = [train[i] for i in test_index]
        for name, (result, _) in _fit_and_evaluate(fold_train, fold_test, args).items():
            per_learner[name].append(result)
            if name in sizes:
                sizes[name].append(result.mean_rule_size)
        print(f'fold {k + 1}/{args.folds} done', flush=True)
    out = {name: pooled_json(pool_results(results)) for name, results in per_learner.items()}
    for name, values in sizes.items():
        out[name]['mean_rule_size'] = float(np.mean(values))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--train', required=True)
    parser.add_argument('--test', default=None)
    parser.add_argument('--folds', type=int, default=0, help='also cross-validate on --train (0: no)')
    parser.add_argument('--seed', type=int, default=0, help='fold assignment (the sweep\'s default)')
    parser.add_argument('--tau-plus', type=float, default=-0.25)
    parser.add_argument('--tau-his', type=float, default=0.06)
    parser.add_argument('--stride', type=int, default=10)
    parser.add_argument('--state', choices=('estimated', 'true'), default='estimated',
                        help='features from the estimated (default) or the true state')
    parser.add_argument('--out', default=None)
    args = parser.parse_args()
    if args.test is None and args.folds < 2:
        parser.error('give --test, --folds K (K >= 2), or both')
    train = load_dataset(args.train, jobs=2, state=args.state).trajectories
    args.guard = dataset_guard_com_height_m(args.train)   # the training robot's CoM guard
    result = {'train': Path(args.train).name, 'state': args.state,
              'n_train': len(train), 'tau_plus_s': args.tau_plus, 'tau_his_s': args.tau_his,
              'stride': args.stride}
    if args.folds >= 2:
        result['folds'] = args.folds
        result['cross_validated'] = _cross_validated(train, args)
    if args.test is not None:
        test = load_dataset(args.test, jobs=2, state=args.state).trajectories
        result['test'] = Path(args.test).name
        fitted = _fit_and_evaluate(train, test, args)
        for name, (evaluation, extra) in fitted.items():
            result[name] = {**short(evaluation), **{k: v for k, v in extra.items() if k != 'models'}}
        models = fitted['hgb'][1]['models']
        some = next(iter(models.values()))
        x = test[0].X[:1]
        start = time.perf_counter()
        for _ in range(200):
            some.predict(x)
        result['hgb']['per_sample_us_one_at_a_time'] = round((time.perf_counter() - start) / 200 * 1e6, 1)
        batch = np.concatenate([t.X for t in test[:5]])
        start = time.perf_counter()
        some.predict(batch)
        result['hgb']['per_sample_us_batched'] = round((time.perf_counter() - start) / len(batch) * 1e6, 3)
    result['command'] = ('python benchmarks/bench_mirror_hgb.py --train ' + args.train
                         + (f' --test {args.test}' if args.test else '')
                         + (f' --folds {args.folds}' if args.folds else ''))
    text = json.dumps(result, indent=1)
    print(text)
    if args.out:
        Path(args.out).write_text(text + '\n')


if __name__ == '__main__':
    main()
