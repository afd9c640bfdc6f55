"""``fall-predictor sweep``: the cross-validated tau_plus x tau_his sweep, with a held-out test set."""
from __future__ import annotations

import argparse
from pathlib import Path

from fall_predictor.cli import args as argtypes
from fall_predictor.cli.args import emit, fail


def cmd_sweep(args) -> int:
    import shlex

    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.learning.selection import pareto_mean_lead
    from fall_predictor.learning.sweep_files import run_sweep
    from fall_predictor.learning.sweep_results import SweepConfig

    settings = {'folds': args.folds, 'seed': args.seed, 'learner_name': args.learner,
                'learner_params': dict(args.param), 'sample_stride': args.stride,
                'capture_point': not args.no_capture_point, 'state': args.state,
                'mirror': args.mirror, 'nested_baselines': not args.no_nested_baselines}
    if args.tau_plus is not None:
        settings['tau_plus_values_s'] = args.tau_plus
    if args.tau_his is not None:
        settings['tau_his_values_s'] = args.tau_his
    if args.learning_curve is not None:
        settings['learning_curve_sizes'] = args.learning_curve
    if args.no_learning_curve:
        settings['learning_curve_sizes'] = ()
    command = shlex.join(['fall-predictor', *args.argv])
    try:
        config = SweepConfig.quick(**settings) if args.quick else SweepConfig(**settings)
    except ValueError as error:
        return fail('sweep', error)
    try:
        argtypes.resolved_state(args)        # says so when the dataset has no sensor topics
        result = run_sweep(args.data, args.out, config, jobs=args.jobs,
                           skip_unreadable=args.skip_unreadable, progress=not args.json,
                           command=command, scheduler=args.scheduler)
        test_set = None
        if args.test_data is not None:
            import json

            from fall_predictor.monitor.fileio import atomic_write_text
            from fall_predictor.learning.heldout import evaluate_on_test_set
            from fall_predictor.learning.report import sweep_json
            test_set = evaluate_on_test_set(result, sweep_json(result)['nested_selection'],
                                            args.test_data, args.jobs, args.skip_unreadable,
                                            progress=not args.json)
            atomic_write_text(args.out / 'test_set.json', json.dumps(test_set, indent=1) + '\n')
    except DatasetError as error:
        return fail('sweep', error)
    t = result.timing
    payload = {'out': str(args.out), 'files': list(result.files),
               'n_trajectories': result.n_trajectories, 'n_fallen': result.n_fallen,
               'state': result.config.state, 'scheduler': args.scheduler,
               'n_predictors': len(result.points), 'n_pareto': len(result.pareto),
               'pareto_mean_lead_s': pareto_mean_lead(result.points),
               'selected': [{'name': paper.name, 'tau_plus_s': p.tau_plus_s, 'tau_his_s': p.tau_his_s,
                             'fpr': p.fpr, 'tau_lead_s': p.tau_lead_s, 'mean_rule_size': p.mean_rule_size}
                            for paper, p in result.selected],
               'timing': {'total_s': t.total_s, 'n_fits': t.n_fits, 'fit_s_mean_full': t.fit_s_mean_full,
                          'jobs': t.jobs}}
    if test_set is not None:
        payload['test_set'] = test_set
    lines = [f'{len(result.points)} predictors ({result.config.folds}-fold CV over '
             f'{result.n_trajectories} trajectories, {result.n_fallen} fallen) in {t.total_s:.0f} s '
             f'with {t.jobs} job(s): {t.n_fits} trainings, mean full-size fit {t.fit_s_mean_full:.2f} s']
    for paper, p in result.selected:
        lines.append(f'{paper.name} analogue: tau_plus {p.tau_plus_s:+.2f} s, tau_his {p.tau_his_s:.3f} s: '
                     f'FPR {p.fpr:.3f}, tau_lead {p.tau_lead_s:.2f} s, mean rule size {p.mean_rule_size:.1f} '
                     f'(paper: FPR {paper.fpr}, tau_lead {paper.tau_lead_s} s, '
                     f'rule size {paper.mean_rule_size})')
    lines.append(f'mean best lead over FPR budgets 0-0.5: {payload["pareto_mean_lead_s"]:.3f} s')
    lines.append('wrote ' + ', '.join(result.files))
    emit(args, payload, lines)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser('sweep', help='cross-validated tau_plus x tau_his sweep, figures and tables',
                       description='k-fold cross-validation by trajectory over a grid of tau_plus '
                                   '(training) and tau_his (run time): one training per fold and tau_plus, '
                                   'every tau_his evaluated from it. Also a learning curve at FP-L2\'s '
                                   'settings and the hand-coded baselines on the same trajectories. Writes '
                                   'sweep.json, table.md (with the paper\'s Table 2 next to the analogues) and '
                                   'PNGs (Fig. 10 and Fig. 11 analogues) to --out. Exit code 2 if the dataset '
                                   'or a setting cannot be used.')
    p.add_argument('--data', type=Path, required=True, help='dataset directory')
    p.add_argument('--out', type=Path, required=True, help='output directory')
    p.add_argument('--folds', type=argtypes.at_least_two, default=10, help='cross-validation folds (default 10)')
    p.add_argument('--seed', type=int, default=0, help='fold assignment and learning-curve subsets')
    argtypes.add_learner_arguments(p)
    argtypes.add_state_argument(p)
    p.add_argument('--tau-plus', type=argtypes.list_of(argtypes.finite(float)), default=None, metavar='LIST',
                   help='comma-separated tau_plus values [s]; write --tau-plus=-1.5,-0.25 (a leading '
                        'minus needs the =); default -1.5,-1.25,...,0.5')
    p.add_argument('--tau-his', type=argtypes.list_of(argtypes.nonnegative), default=None, metavar='LIST',
                   help='comma-separated tau_his values [s] '
                        '(default 0,0.004,0.008,0.016,0.03,0.044,0.06,0.08,0.1)')
    p.add_argument('--learning-curve', type=argtypes.list_of(argtypes.positive_int), default=None, metavar='LIST',
                   help='training-set sizes of the learning curve (default 50,100,250,500,900)')
    p.add_argument('--no-learning-curve', action='store_true', help='skip the learning curve')
    p.add_argument('--test-data', type=Path, default=None, metavar='DIR',
                   help='held-out test dataset (another seed): the chosen predictors are trained on '
                        'all of --data and evaluated on DIR, written to test_set.json')
    p.add_argument('--mirror', action='store_true',
                   help='every training also learns from its trajectories\' left-right mirror images '
                        '(as train --mirror); the test folds stay as recorded')
    p.add_argument('--no-nested-baselines', action='store_true',
                   help='skip choosing the baselines\' thresholds and tau_his on training folds (the '
                        'longest part; e.g. for a learner-only sweep such as --mirror)')
    p.add_argument('--no-capture-point', action='store_true',
                   help='skip the capture-point baseline (it reads every bag once to fill its cache)')
    p.add_argument('--quick', action='store_true',
                   help='reduced grid: 5 tau_plus, 5 tau_his, learning curve 10,25,50, coarse baselines '
                        '(explicit --tau-plus/--tau-his/--learning-curve still apply)')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='parallel trainings')
    argtypes.add_scheduler_argument(p, 'the trainings (features are read here and sent to the workers)')
    p.add_argument('--skip-unreadable', action='store_true',
                   help='leave out unreadable bags instead of failing')
    p.add_argument('--json', action='store_true', help='print one JSON summary object')
    p.set_defaults(func=cmd_sweep)
