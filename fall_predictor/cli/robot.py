"""``fall-predictor robustness``: the push robustness table of the simulated robot's C_bal."""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from fall_predictor.cli import args as argtypes
from fall_predictor.cli.args import emit, fail


def cmd_robustness(args) -> int:
    from joblib import delayed

    from fall_predictor.data.parallel import compute_backend, compute_parallel, progress_bar
    from fall_predictor.sim.robustness import RobustnessGrid, run_robustness

    grid = RobustnessGrid(impulses_ns=tuple(args.impulses), n_phases=args.phases,
                          height_m=args.height, horizon_s=args.horizon)
    n_cells = len(grid.impulses_ns) * len(grid.directions_deg) * grid.n_phases

    def parallel_map(function, items):
        results = []
        with progress_bar(len(items), desc='pushes', unit='push', disable=args.json) as bar:
            for result in compute_parallel(args.jobs, return_as='generator')(
                    delayed(function)(item) for item in items):
                results.append(result)
                bar.update(1)
        return results

    start = time.perf_counter()
    try:
        with compute_backend(args.scheduler):
            summary = run_robustness(grid, parallel_map)
    except RuntimeError as error:
        return fail('robustness', error)
    summary['wall_s'] = time.perf_counter() - start
    summary['pushes'] = n_cells
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(summary, indent=1, sort_keys=True) + '\n')
    lines = [f'{n_cells} pushes in {summary["wall_s"]:.0f} s; largest impulse survived at every phase:']
    lines += [f'  direction {angle:>5} deg: {value:g} N s'
              for angle, value in summary['largest_impulse_survived_at_every_phase_ns'].items()]
    lines += ['survival fraction by impulse: ' + ', '.join(
        f'{k} N s {v:.2f}' for k, v in summary['survival_fraction_by_impulse'].items())]
    verdict = {True: 'met', False: 'missed', None: 'not in the grid'}
    lines += [f'aim 15 N s everywhere: {verdict[summary["aim_15_ns_everywhere"]]}; '
              f'aim 30 N s forward/backward at every phase: {verdict[summary["aim_30_ns_forward_backward"]]}']
    emit(args, summary, lines)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser('robustness', help='survival table of pushes over impulse, direction and gait phase',
                       description='Push the walking robot (default gait, C_bal) with every impulse of a grid '
                                   'from 8 directions at N phases of its walk cycle; report which it survives '
                                   'and, per direction, the largest impulse survived at every phase.')
    p.add_argument('--impulses', type=argtypes.positive, nargs='+',
                   default=[float(i) for i in range(5, 55, 5)], help='impulses [N s] (force x 0.1 s)')
    p.add_argument('--phases', type=argtypes.positive_int, default=8, help='onsets per walk cycle')
    p.add_argument('--height', type=argtypes.finite(float), default=0.1,
                   help='application height above the CoM [m]')
    p.add_argument('--horizon', type=argtypes.positive, default=3.0,
                   help='seconds after the push ends that the robot must stay up')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='parallel processes')
    argtypes.add_scheduler_argument(p, 'the pushes')
    p.add_argument('--out', type=Path, help='also write the JSON summary here')
    p.add_argument('--json', action='store_true', help='print one JSON summary object')
    p.set_defaults(func=cmd_robustness)
