"""fall-predictor: offline tools of the fall_predictor package (simulate, generate, train, ...)."""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np


def _finite(kind):
    def parse(text: str):
        value = kind(text)
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f'{text!r} is not a finite number')
        return value
    return parse


def _positive(text: str) -> float:
    value = _finite(float)(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text!r} must be > 0')
    return value


def _emit(args, payload: dict, lines: list[str]) -> None:
    if getattr(args, 'json', False):
        print(json.dumps(payload, sort_keys=True))
    else:
        print('\n'.join(lines))


# -- simulate --------------------------------------------------------------------------------
def cmd_simulate(args) -> int:
    from fall_predictor.pushes import PushDistribution
    from fall_predictor.records import PushSpec
    from fall_predictor.simulator import SimulatorConfig
    from fall_predictor.trajectory import run_trajectory

    rng = np.random.default_rng(args.seed)
    push = None
    if args.push_force > 0:
        onset = args.push_time if args.push_time is not None else PushDistribution().onset(rng)
        push = PushSpec(args.push_force, args.push_angle, args.push_height, onset)
        if push.t_force_end > args.duration:
            print(f'error: the push ends at {push.t_force_end:.3f} s, after --duration {args.duration} s',
                  file=sys.stderr)
            return 2
    start = time.perf_counter()
    result = run_trajectory(push, args.duration, sim_config=SimulatorConfig(gui=args.gui))
    wall = time.perf_counter() - start
    simulated = result.measurements[-1].t
    payload = {
        'fallen': result.fallen,
        't_fallen': result.t_fallen,
        't_push': None if push is None else push.t_push,
        't_force_end': None if push is None else push.t_force_end,
        't_reflex': result.t_reflex,
        'push': None if push is None else {'force_n': push.force_n, 'angle_deg': push.angle_deg,
                                            'height_m': push.height_m, 'impulse_ns': push.impulse_ns},
        'simulated_s': simulated,
        'min_com_height_m': float(result.com[:, 2].min()),
        'wall_s': wall,
        'real_time_factor': simulated / wall if wall > 0 else None,
        'seed': args.seed,
    }
    lines = [f'simulated {simulated:.3f} s in {wall:.1f} s ({payload["real_time_factor"]:.2f}x real time)']
    if push is not None:
        lines.append(f'push: {push.force_n:.0f} N for {push.duration_s:.1f} s at {push.t_push:.3f} s, '
                     f'{push.angle_deg:.0f} deg from the heading, {push.height_m:+.2f} m above the CoM')
    lines.append('reflex: ' + ('none' if result.t_reflex is None else f'fired at {result.t_reflex:.3f} s'))
    lines.append(f'outcome: FALLEN at {result.t_fallen:.3f} s' if result.fallen else 'outcome: balanced')
    _emit(args, payload, lines)
    return 0


# -- generate -----------------------------------------------------------------------------
def _positive_int(text: str) -> int:
    value = int(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text!r} must be a positive integer')
    return value


def cmd_generate(args) -> int:
    from fall_predictor.dataset import GenerationConfig, generate_dataset

    config = GenerationConfig(seed=args.seed, horizon_after_push_s=args.horizon)
    start = time.perf_counter()
    rows = generate_dataset(args.out, args.trajectories, args.seed, jobs=args.jobs, config=config,
                            progress=not args.json)
    wall = time.perf_counter() - start
    rows = [r for r in rows if int(r.trajectory_id.split('_')[1]) < args.trajectories]
    fallen = sum(r.fallen for r in rows)
    size = sum(f.stat().st_size for f in Path(args.out).rglob('*') if f.is_file() and 'cache' not in f.parts)
    payload = {'out': str(args.out), 'trajectories': len(rows), 'fallen': fallen,
               'fall_fraction': fallen / len(rows) if rows else None, 'wall_s': wall,
               'disk_bytes': size, 'seed': args.seed, 'jobs': args.jobs}
    _emit(args, payload, [f'{len(rows)} trajectories in {args.out} ({fallen} fallen, '
                          f'{size / 1e6:.0f} MB) in {wall:.0f} s'])
    return 0


# -- stats --------------------------------------------------------------------------------
def cmd_stats(args) -> int:
    from fall_predictor.dataset import load_features, read_index
    from fall_predictor.stats import dataset_stats, plot_fig6

    rows = read_index(args.data)
    report = load_features(args.data, jobs=args.jobs, progress=not args.json)
    stats = dataset_stats(rows, report.trajectories)
    stats['unreadable_bags'] = report.errors
    plots_dir = Path(args.plots) if args.plots else Path(args.data) / 'plots'
    stats['plots'] = [str(p) for p in plot_fig6(report.trajectories, plots_dir)]
    lines = [f"{stats['trajectories']} trajectories, {stats['fallen']} fallen "
             f"(fall fraction {stats['fall_fraction']:.3f}), {stats['samples']} samples"]
    for key in ('duration_s', 'oracle_lead_s', 'fall_after_force_end_s'):
        d = stats[key]
        if d:
            lines.append(f"{key}: median {d['median']:.3f}, p95 {d['p95']:.3f}, max {d['max']:.3f}")
    lines.append('contact-mode occupancy: ' + ', '.join(
        f'{k} {v:.3f}' for k, v in stats['contact_mode_occupancy'].items() if v > 0))
    for tid, error in report.errors.items():
        lines.append(f'UNREADABLE {tid}: {error}')
    lines.append('plots: ' + ', '.join(stats['plots']))
    _emit(args, stats, lines)
    return 1 if report.errors else 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='fall-predictor', description=__doc__)
    sub = parser.add_subparsers(dest='command', metavar='<command>')

    p = sub.add_parser('simulate', help='walk, optionally push once, and report the outcome',
                       description='Simulate the humanoid walking under C_bal; optionally push it once '
                                   '(a constant force for 0.1 s on the torso) and report whether it fell.')
    p.add_argument('--duration', type=_positive, default=6.0, help='simulated seconds (default 6)')
    p.add_argument('--push-force', type=_finite(float), default=0.0, help='push force [N]; 0 = no push')
    p.add_argument('--push-angle', type=_finite(float), default=0.0,
                   help='push direction [deg] from the heading, counter-clockwise (90 = to the left)')
    p.add_argument('--push-height', type=_finite(float), default=0.1, help='height above the CoM [m]')
    p.add_argument('--push-time', type=_finite(float), default=None,
                   help='push onset [s]; default: a random instant of the walk cycle drawn from --seed')
    p.add_argument('--seed', type=int, default=0, help='random seed (push onset)')
    p.add_argument('--gui', action='store_true', help='open the PyBullet GUI')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser('generate', help='generate push trajectories as rosbag2 (MCAP) bags',
                       description='Generate N push trajectories (SPEC §3, C_bal throughout) into DIR: one '
                                   'rosbag2 bag per trajectory plus an index. Deterministic per seed; '
                                   'rerunning finishes an interrupted run without redoing finished trajectories.')
    p.add_argument('--trajectories', type=_positive_int, required=True)
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--out', type=Path, required=True, help='dataset directory')
    p.add_argument('--jobs', type=_positive_int, default=1, help='parallel processes')
    p.add_argument('--horizon', type=_positive, default=4.0,
                   help='simulated seconds after the push ends before a trajectory counts as balanced')
    p.add_argument('--json', action='store_true')
    p.set_defaults(func=cmd_generate)

    p = sub.add_parser('stats', help='statistics and Fig. 6 plots of a dataset',
                       description='Trajectories, fall fraction, duration and oracle-lead distributions, '
                                   'contact-mode occupancy, and PNG plots like the paper\'s Fig. 6. '
                                   'Exits 1 if some bags are unreadable (they are listed).')
    p.add_argument('data', type=Path, help='dataset directory')
    p.add_argument('--plots', default=None, help='where to write PNGs (default DATA/plots)')
    p.add_argument('--jobs', type=_positive_int, default=1)
    p.add_argument('--json', action='store_true')
    p.set_defaults(func=cmd_stats)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, 'func', None):
        parser.print_help()
        return 2
    if getattr(args, 'push_force', 0) < 0:
        parser.error('--push-force must be >= 0')
    return int(args.func(args) or 0)


if __name__ == '__main__':
    sys.exit(main())
