"""Prediction on the estimated state against the true state: same trajectories, same settings.

The side-by-side of the two state sources. For each state source (``true``: the simulator's exact state;
``estimated``: the state estimator over the bags' sensor topics, as the live node runs it) the
predictor at fixed settings (default: FP-L2's tau_plus -0.25 s, tau_his 0.06 s; no selection)
is

* cross-validated on ``--data`` (k folds by trajectory, the sweep's folds and learner; FPR and
  tau_lead pooled over the held-out folds with Wilson / bootstrap 95 % intervals), and
* trained on all of ``--data`` and evaluated on ``--test`` (another seed).

The fold assignment depends only on the trajectories' outcomes, so both states see the same
folds. Writes one JSON object (also printed): per state the cross-validated and test figures,
and the differences estimated - true against the aim (|d tau_lead| <= 0.05 s, |d FPR| <= 0.02).

Usage::

    python benchmarks/bench_true_vs_estimated.py --data data/d1000s --test data/t204s \
        --jobs 2 --out docs/estimation/true_vs_estimated.json
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from fall_predictor.data.dataset import dataset_guard_com_height_m
from fall_predictor.learning.crossval import DEFAULT_SAMPLE_STRIDE, cross_validate_grid
from fall_predictor.learning.metrics import evaluate_lists
from fall_predictor.learning.nested import fixed_setting, pool_results, pooled_json
from fall_predictor.learning.training import fit_strided, load_dataset, make_learner

#: The aim for the estimated-state figures against the true-state ones.
AIM_LEAD_S, AIM_FPR = 0.05, 0.02


def _figures(state: str, args: argparse.Namespace) -> dict:
    started = time.monotonic()
    train = load_dataset(args.data, jobs=args.jobs, state=state).trajectories
    test = load_dataset(args.test, jobs=args.jobs, state=state).trajectories
    learner = make_learner('tree')
    guard = dataset_guard_com_height_m(args.data)       # the training robot's, as a model records it
    setting = (args.tau_plus, args.tau_his)
    fits = cross_validate_grid(train, learner, (args.tau_plus,), (args.tau_his,), args.folds,
                               args.seed, DEFAULT_SAMPLE_STRIDE, jobs=args.jobs, progress=True,
                               guard_com_height_m=guard)
    cross_validated = pooled_json(fixed_setting(fits, setting))
    lists = fit_strided(train, args.tau_plus, learner, DEFAULT_SAMPLE_STRIDE)
    result = evaluate_lists(test, lists, (args.tau_his,), guard_com_height_m=guard)[args.tau_his]
    held_out = pooled_json(pool_results([result]))
    held_out['mean_rule_size'] = float(lists.mean_rule_size)
    return {'cross_validated': cross_validated, 'test_set': held_out,
            'n_train': len(train), 'n_test': len(test), 'seconds': time.monotonic() - started}


def _difference(estimated: dict, true: dict) -> dict:
    d_fpr = estimated['fpr'] - true['fpr']
    d_lead = estimated['tau_lead_s'] - true['tau_lead_s']
    return {'fpr': d_fpr, 'tau_lead_s': d_lead,
            'aim_met': bool(abs(d_fpr) <= AIM_FPR and abs(d_lead) <= AIM_LEAD_S)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--data', type=Path, required=True, help='training / cross-validation dataset')
    parser.add_argument('--test', type=Path, required=True, help='held-out test dataset (another seed)')
    parser.add_argument('--tau-plus', type=float, default=-0.25)
    parser.add_argument('--tau-his', type=float, default=0.06)
    parser.add_argument('--folds', type=int, default=10)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--jobs', type=int, default=1)
    parser.add_argument('--out', type=Path, default=Path('docs/estimation/true_vs_estimated.json'))
    args = parser.parse_args()
    states = {state: _figures(state, args) for state in ('true', 'estimated')}
    document = {
        'command': 'python benchmarks/bench_true_vs_estimated.py ' + ' '.join(
            f'--{k.replace("_", "-")} {v}' for k, v in vars(args).items() if k != 'out'),
        'tau_plus_s': args.tau_plus, 'tau_his_s': args.tau_his, 'folds': args.folds,
        'aim': {'abs_d_tau_lead_s': AIM_LEAD_S, 'abs_d_fpr': AIM_FPR},
        'states': states,
        'estimated_minus_true': {
            where: _difference(states['estimated'][where], states['true'][where])
            for where in ('cross_validated', 'test_set')},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(document, indent=1) + '\n')
    print(json.dumps(document))


if __name__ == '__main__':
    main()
