"""``fall-predictor estimation-error``: the state estimator against the recorded ground truth."""
from __future__ import annotations

import argparse
from pathlib import Path

from fall_predictor.cli import args as argtypes
from fall_predictor.cli.args import emit, fail

#: The state estimator's aims (method §10), for the human-readable verdicts.
AIMS = {'com_p99_m': 0.010, 'lin_mom_median': 0.3, 'lin_mom_p99': 1.5, 'contact_mode_agreement': 0.97}


def cmd_estimation_error(args) -> int:
    from joblib import delayed

    from fall_predictor.data.bagio import BagError
    from fall_predictor.data.dataset import DatasetError, dataset_robot, read_index
    from fall_predictor.data.estimation import error_samples, estimate_bag, summarise
    from fall_predictor.data.parallel import compute_parallel, progress_bar

    try:
        rows = read_index(args.data)
    except DatasetError as error:
        return fail('estimation-error', error)
    if args.limit:
        rows = rows[:args.limit]
    if not rows:
        return fail('estimation-error', f'{args.data}: no trajectories')

    robot = dataset_robot(Path(args.data))

    def one(row):
        return error_samples(estimate_bag(Path(args.data) / row.bag, robot=robot), row.t_push)

    per_bag = []
    try:
        with progress_bar(len(rows), desc='estimating', unit='traj', disable=args.json) as bar:
            for result in compute_parallel(args.jobs, return_as='generator')(delayed(one)(r) for r in rows):
                per_bag.append(result)
                bar.update(1)
    except BagError as error:
        return fail('estimation-error', error)
    summary = summarise(per_bag)
    c, p = summary['com_m'], summary['linear_momentum_kg_m_s']

    def verdict(ok):
        return 'met' if ok else 'missed'
    lines = [f'{len(rows)} trajectories of {args.data}; errors as Euclidean norms (median / p99, '
             'post-push 0.5 s median / p99):']
    for key, s in summary.items():
        if isinstance(s, dict):
            lines.append(f'  {key}: {s["median"]:.4g} / {s["p99"]:.4g}; post-push '
                         f'{s["post_push_median"]:.4g} / {s["post_push_p99"]:.4g}')
    lines.append(f'  contact mode agreement {summary["contact_mode_agreement"]:.4f}')
    lines.append(f'aims: CoM p99 <= 10 mm {verdict(c["p99"] <= AIMS["com_p99_m"])}; linear momentum median '
                 f'<= 0.3 {verdict(p["median"] <= AIMS["lin_mom_median"])}, p99 <= 1.5 '
                 f'{verdict(p["p99"] <= AIMS["lin_mom_p99"])}; contact modes >= 97 % '
                 f'{verdict(summary["contact_mode_agreement"] >= AIMS["contact_mode_agreement"])}')
    emit(args, summary, lines)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser('estimation-error', help='state estimation error against the ground truth of a dataset',
                       description='Run the state estimator over the sensor topics of every bag of a dataset '
                                   'generated with --sensor-noise and compare with the recorded ground truth: '
                                   'CoM, linear and angular momentum, CoP (median, p99, and over the 0.5 s after '
                                   'each push) and contact mode agreement.')
    p.add_argument('--data', type=Path, required=True, help='dataset directory (generate --sensor-noise)')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='parallel processes')
    p.add_argument('--limit', type=argtypes.positive_int, default=None, help='only the first N trajectories')
    p.add_argument('--json', action='store_true', help='print the result as JSON')
    p.set_defaults(func=cmd_estimation_error)
