#!/usr/bin/env python3
"""Does a window of the recent past help? The same learners on the 15 features of one sample and
on the features with their changes over the last 50, 100 and 200 ms, train / held-out test.

Each learner is fitted per contact mode on ``--train`` (method §8's weighted samples, every
``--stride``-th, tau_plus ``--tau-plus``) and evaluated on ``--test`` (another seed) over the
tau_his grid, CoM guard on, Wilson / bootstrap intervals:

* ``tree``: a CART tree per mode (the shipped learner's tree, before it is rewritten as a
  decision list: depth 8, 5 samples a leaf, entropy);
* ``tree_window``: the same on the windowed features (15 + 3 x 15: ``x(t) - x(t - lag)``);
* ``hgb``, ``hgb_window``: scikit-learn's HistGradientBoostingClassifier on both, a reference
  for what a larger learner extracts.

Per learner, the test FPR / lead / misses at every tau_his (its trade-off curve), and the best
lead at test FPR <= 0.01 and <= 0.06 over tau_his: a comparison of the learners along their
curves, chosen in hindsight on the test set, so **not** a held-out figure of any one of them.
Writes JSON (``--out``).

    python benchmarks/bench_temporal_window.py --test data/t1000s_2026 --out data/temporal_window.json

(without ``--train``, one dataset split by trajectory: the even ones train, the odd ones test).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from fall_predictor.data.dataset import dataset_guard_com_height_m
from fall_predictor.learning.evaluation import evaluation_result_json
from fall_predictor.learning.learners import training_set
from fall_predictor.learning.metrics import evaluate_atomic
from fall_predictor.learning.training import load_dataset, subsample
from fall_predictor.monitor.records import FALLING, N_CONTACT_MODES

LAGS_S = (0.05, 0.1, 0.2)
BUDGETS = (0.01, 0.06)
TAU_HIS_S = (0.0, 0.016, 0.03, 0.044, 0.06, 0.08, 0.1, 0.15, 0.2)
KEEP = ('n_balanced', 'n_fallen', 'n_false_positives', 'fpr', 'fpr_ci95', 'tau_lead_s',
        'tau_lead_ci95', 'n_missed', 'lead_fraction')


def windowed(traj, lags_s=LAGS_S):
    """``traj`` with its features and their changes over each lag (the first sample's features
    before the start)."""
    parts = [traj.X]
    for lag in lags_s:
        j = np.searchsorted(traj.t, traj.t - lag - 1e-9)
        parts.append(traj.X - traj.X[np.clip(j, 0, len(traj.t) - 1)])
    return dataclasses.replace(traj, X=np.hstack(parts))


def fit(trajs, kind: str, tau_plus_s: float, stride: int):
    from sklearn.ensemble import HistGradientBoostingClassifier
    from sklearn.tree import DecisionTreeClassifier

    X, y, w, modes, _ = training_set([subsample(t, stride) for t in trajs], tau_plus_s,
                                     4.0 * stride, 1.0 * stride)
    models = {}
    for m in range(N_CONTACT_MODES):
        rows = modes == m
        if (y[rows] == FALLING).any() and (y[rows] != FALLING).any():
            model = (DecisionTreeClassifier(max_depth=8, min_samples_leaf=5, criterion='entropy',
                                            random_state=0) if kind == 'tree'
                     else HistGradientBoostingClassifier(max_iter=100, random_state=0))
            models[m] = model.fit(X[rows], y[rows] == FALLING, sample_weight=w[rows])
    return models


def atomic(models, trajs):
    out = []
    for t in trajs:
        a = np.zeros(len(t.mode), dtype=bool)
        for m, model in models.items():
            rows = t.mode == m
            if rows.any():
                a[rows] = model.predict(t.X[rows])
        out.append(a)
    return out


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--train', type=Path, default=None,
                        help='training data (default: the even trajectories of --test; the odd ones test)')
    parser.add_argument('--test', type=Path, required=True)
    parser.add_argument('--tau-plus', type=float, default=-0.25)
    parser.add_argument('--budget', type=float, default=0.06, help='FPR printed per learner')
    parser.add_argument('--stride', type=int, default=10)
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    guard = dataset_guard_com_height_m(args.test)
    test = load_dataset(args.test, jobs=args.jobs, state='estimated').trajectories
    if args.train is not None:
        base = {'train': load_dataset(args.train, jobs=args.jobs, state='estimated').trajectories,
                'test': test}
    else:
        # One dataset, split by trajectory: the even ones train, the odd ones test.
        base = {'train': test[0::2], 'test': test[1::2]}
    window = {k: [windowed(t) for t in v] for k, v in base.items()}
    result = {'train': str(args.train) if args.train else f'{args.test}, even trajectories',
              'test': str(args.test) if args.train else f'{args.test}, odd trajectories', 'tau_plus_s': args.tau_plus,
              'lags_s': LAGS_S, 'budget': args.budget, 'learners': {}}
    for name, kind, sets in (('tree', 'tree', base), ('tree_window', 'tree', window),
                             ('hgb', 'hgb', base), ('hgb_window', 'hgb', window)):
        start = time.perf_counter()
        models = fit(sets['train'], kind, args.tau_plus, args.stride)
        fit_s = time.perf_counter() - start
        on_test = evaluate_atomic(sets['test'], atomic(models, sets['test']), TAU_HIS_S, 0.001, guard)
        row = {'fit_s': round(fit_s, 1),
               'test_by_tau_his': {str(h): [round(on_test[h].fpr, 4), round(on_test[h].tau_lead_s, 3),
                                            on_test[h].n_missed] for h in TAU_HIS_S}}
        for budget in BUDGETS:
            ok = [h for h in TAU_HIS_S if on_test[h].fpr <= budget]
            if ok:
                best = max(ok, key=lambda h: on_test[h].tau_lead_s)
                payload = evaluation_result_json(on_test[best])
                row[f'best_at_test_fpr_le_{budget}'] = {'tau_his_s': best,
                                                       **{k: payload[k] for k in KEEP if k in payload}}
        result['learners'][name] = row
        chosen = min(TAU_HIS_S, key=lambda h: abs(on_test[h].fpr - args.budget))
        print(name, chosen, round(on_test[chosen].fpr, 3), round(on_test[chosen].tau_lead_s, 3), flush=True)
    text = json.dumps(result, indent=1, default=float)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')
    print(text)
    return result


if __name__ == '__main__':
    main()
