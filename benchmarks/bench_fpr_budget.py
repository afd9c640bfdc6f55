"""Does an FPR budget hold held out? The operating point chosen on the point estimate of the
cross-validated FPR against the one chosen on its upper confidence bound (method §11 "A budget
that holds").

On the development data (``--data``, repeatable: one training set, as ``train --data``), the boosted trees' cross-validation that ``train``
runs (:func:`~fall_predictor.learning.crossval.cross_validate_grid`, one training per fold, every
(decision threshold, tau_his) evaluated on the held-out fold), with folds stratified by outcome
(the sweep's) and grouped by cause and push impulse band
(:func:`~fall_predictor.learning.run_groups.fold_groups`). Per budget (``--max-fpr``), each fold
scheme and each rule (:func:`~fall_predictor.learning.nested.choose_setting`: ``point``, the
pooled FPR within the budget; ``ucb``, its one-sided Wilson upper bound at ``--level``) chooses
an operating point on all the folds, as ``train`` does. One model is trained on all the
development data (the threshold and the window are run-time settings: one model serves every
choice), then evaluated held out (``--test``, a draw of another seed) at each choice:

* on every held-out run (the generator's own sampler; several ``--test`` sets pooled);
* on the held-out pushes of the ambiguous band only (the band in which 20-80 % of the held-out
  pushes fell, found from them: :func:`~fall_predictor.learning.run_groups.ambiguous_band`), a
  second sampler: the pushes a policy sometimes recovers from, where false alarms concentrate.

Each figure is an FPR over survived runs with its Wilson 95 % interval, beside the falls caught
and the lead. Writes JSON (``--out``):

    .venv/bin/python benchmarks/bench_fpr_budget.py --data data/g1pol150_s11 \\
        --data data/g1pol400_s12 --test data/g1pol400_s13 --test data/g1pol160_s8 --attitude --mirror \\
        --out docs/prediction/g1_unitree_rl/fpr_budget.json
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from fall_predictor.data.dataset import read_index
from fall_predictor.learning.crossval import cross_validate_grid
from fall_predictor.learning.deployment import cause_figures, run_outcomes
from fall_predictor.learning.intervals import wilson_upper_bound
from fall_predictor.learning.metrics import evaluate_atomic
from fall_predictor.learning.nested import choose_setting, pool_results, pooled_json
from fall_predictor.learning.run_groups import ambiguous_band, disturbances
from fall_predictor.learning.sweep_results import DEFAULT_TAU_HIS_VALUES_S
from fall_predictor.learning.training import (fit_strided, load_training_data, make_learner,
                                              model_inputs)
from fall_predictor.learning.window_choice import training_groups

sys.path.insert(0, str(Path(__file__).resolve().parent))
from portable_paths import portable_path as portable  # noqa: E402

RULES = ('point', 'ucb')
FOLDS_BY = ('outcome', 'cause_band')


def choices(trajs, groups, learner, args, guard_m) -> dict[str, Any]:
    """Per fold scheme, per budget, per rule: the operating point chosen on all the folds and its
    cross-validated figures."""
    out: dict[str, Any] = {}
    for folds_by in FOLDS_BY:
        fits = cross_validate_grid(trajs, learner, (args.tau_plus,), DEFAULT_TAU_HIS_VALUES_S,
                                   args.folds, args.seed, mirror=args.mirror, jobs=args.jobs,
                                   guard_com_height_m=guard_m, decision_thresholds=args.thresholds,
                                   groups=groups if folds_by == 'cause_band' else None)
        pooled = {(d, tau): pool_results([fit.by_threshold[d][tau] for fit in fits])
                  for d in args.thresholds for tau in DEFAULT_TAU_HIS_VALUES_S}
        out[folds_by] = {'folds': len({fit.fold for fit in fits}), 'budgets': {}}
        for budget in args.max_fpr:
            per_rule = {}
            for rule in RULES:
                d, tau = choose_setting(pooled, budget, rule, args.level)
                figures = pooled[d, tau]
                per_rule[rule] = {'decision_threshold': d, 'tau_his_s': tau,
                                  'cv': pooled_json(figures),
                                  'cv_fpr_upper_bound': wilson_upper_bound(
                                      figures.n_false_positives, figures.n_balanced, args.level)}
            out[folds_by]['budgets'][str(budget)] = per_rule
        print(folds_by, json.dumps(out[folds_by]), flush=True)
    return out


def held_out(model, test, runs, setting, guard_m) -> dict[str, Any]:
    """The model at ``setting`` on every held-out run and on the ambiguous band's pushes."""
    d, tau = setting
    atomic = [model.score(t.X, t.mode) > d for t in test]
    result = evaluate_atomic(test, atomic, (tau,), guard_com_height_m=guard_m, keep_alarms=True)[tau]
    outcomes = run_outcomes(test, result.alarms, runs)
    band = ambiguous_band([o.disturbance.impulse_ns for o in outcomes],
                          [o.fallen for o in outcomes])
    inside = [o for o in outcomes if band is not None and band.contains(o.disturbance.impulse_ns)]
    return {'all_runs': cause_figures(outcomes),
            'ambiguous_band': None if band is None else {**band.to_json(), **cause_figures(inside)}}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--data', type=Path, action='append', required=True,
                        help='development data (repeatable)')
    parser.add_argument('--test', type=Path, action='append', required=True,
                        help='held-out data (other seeds; repeatable: pooled)')
    parser.add_argument('--max-fpr', type=float, action='append', default=None,
                        help='FPR budget (repeatable; default 0.02 and 0.06)')
    parser.add_argument('--level', type=float, default=0.95, help='level of the one-sided bound')
    parser.add_argument('--tau-plus', type=float, default=-0.5)
    parser.add_argument('--thresholds', type=lambda s: tuple(float(v) for v in s.split(',')),
                        default=(0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0))
    parser.add_argument('--folds', type=int, default=10)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--mirror', action='store_true')
    parser.add_argument('--attitude', action='store_true')
    parser.add_argument('--state', default='estimated', choices=('estimated', 'true'))
    parser.add_argument('--jobs', type=int, default=1)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    args.max_fpr = tuple(args.max_fpr or (0.02, 0.06))
    data = load_training_data(args.data, jobs=args.jobs, state=args.state)
    guard_m = data.guard_com_height_m
    trajs = model_inputs(data.report.trajectories, args.attitude)
    groups = training_groups(data, args.folds)
    learner = make_learner('boosting')
    chosen = choices(trajs, groups, learner, args, guard_m)
    model = fit_strided(trajs, args.tau_plus, learner, mirror=args.mirror)
    test_data = load_training_data(args.test, jobs=args.jobs, state=args.state)
    test = model_inputs(test_data.report.trajectories, args.attitude)
    test_runs = {}
    for part in test_data.parts:
        test_runs.update(disturbances(read_index(part.data_dir), part.prefix))
    test_guard_m = test_data.guard_com_height_m
    for folds_by in FOLDS_BY:
        for budget, per_rule in chosen[folds_by]['budgets'].items():
            for rule, choice in per_rule.items():
                choice['held_out'] = held_out(model, test, test_runs,
                                              (choice['decision_threshold'], choice['tau_his_s']),
                                              test_guard_m)
                print(folds_by, budget, rule, json.dumps(choice['held_out']), flush=True)
    out = {'data': [portable(d) for d in args.data], 'test': [portable(d) for d in args.test],
           'n_dev': len(trajs), 'n_dev_fallen': sum(t.fallen for t in trajs),
           'n_test': len(test), 'n_test_fallen': sum(t.fallen for t in test),
           'state': args.state, 'attitude': args.attitude, 'mirror': args.mirror,
           'tau_plus_s': args.tau_plus, 'decision_thresholds': list(args.thresholds),
           'tau_his_values_s': list(DEFAULT_TAU_HIS_VALUES_S), 'level': args.level,
           'seed': args.seed, 'folds': args.folds,
           'rules': {'point': 'the longest cross-validated lead at a pooled FPR <= the budget',
                     'ucb': f'the longest cross-validated lead where the one-sided {100 * args.level:g} % '
                            'Wilson upper bound of the pooled FPR is <= the budget'},
           'else': 'no setting within the budget: the lowest FPR (point) or bound (ucb)',
           'choices': chosen, 'command': 'benchmarks/bench_fpr_budget.py ' + ' '.join(
               portable(a) if a.startswith('/') else a for a in (argv or sys.argv[1:]))}
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(out, indent=1, allow_nan=False) + '\n')
    return out


if __name__ == '__main__':
    main()
