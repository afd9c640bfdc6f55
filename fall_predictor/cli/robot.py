"""``fall-predictor robustness`` and ``calibrate``: how hard a robot under its controller can be
pushed: its robustness table, and the push range that fells about half of its runs."""
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

    from fall_predictor.profiles.profile import ProfileError
    try:
        controller, simulator = argtypes.controller_of(args)
        argtypes.checked_profile(args.robot, controller)
    except ProfileError as error:
        return fail('robustness', error)
    grid = RobustnessGrid(impulses_ns=tuple(args.impulses), n_phases=args.phases,
                          height_m=args.height, horizon_s=args.horizon, robot=args.robot,
                          controller=controller, simulator=simulator,
                          command=tuple(args.command or (0.0, 0.0, 0.0)))
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


def cmd_calibrate(args) -> int:
    from joblib import delayed

    from fall_predictor.data.parallel import compute_parallel, progress_bar
    from fall_predictor.profiles.profile import ProfileError
    from fall_predictor.sim.calibration import PROBE_FORCE_N_PER_KG, CalibrationSetup, calibrate

    try:
        controller, simulator = argtypes.controller_of(args)
        profile = argtypes.checked_profile(args.robot, controller)
    except ProfileError as error:
        return fail('calibrate', error)
    def parallel_map(function, items):
        results = []
        with progress_bar(len(items), desc='runs', unit='run', disable=args.json) as bar:
            for result in compute_parallel(args.jobs, return_as='generator')(
                    delayed(function)(item) for item in items):
                results.append(result)
                bar.update(1)
        return results

    if args.cause != 'push':
        return _calibrate_cause(args, profile, controller, simulator, parallel_map)
    probe = args.probe_force or PROBE_FORCE_N_PER_KG * profile.total_mass_kg
    setup = CalibrationSetup(args.robot, controller, simulator, probe, args.seed, args.horizon)
    start = time.perf_counter()
    summary = calibrate(setup, args.trajectories, parallel_map, args.target)
    summary['wall_s'] = time.perf_counter() - start
    _write(args.out, summary)
    where = (f'controllers.{controller}.push_force_n' if profile.controller_profile(controller)
             else 'push_force_n')
    lines = [f'{summary["runs"]} pushes of up to {probe:.0f} N ({probe * 0.1:.0f} N s) of {profile.name} '
             f'under {controller} in {simulator}: {summary["fall_fraction"]:.2f} fell '
             f'(push to fall, median: {summary["push_to_fall_s_median"]} s)']
    lines += [f'  {b["force_n"][0]:6.0f}-{b["force_n"][1]:6.0f} N: {b["runs"]:4d} runs, '
              + ('-' if b['fall_fraction'] is None else f'{b["fall_fraction"]:.2f} fell')
              for b in summary['fall_probability_by_force']]
    low, high = summary['suggested_push_force_n']
    lines.append(f'suggested: {where}: [{low:g}, {high:g}] (predicted fall fraction '
                 f'{summary["predicted_fall_fraction"]:.2f}; put it in the robot profile)')
    emit(args, {k: v for k, v in summary.items() if k != 'rows'} if args.json else summary, lines)
    return 0


def _write(out, summary: dict) -> None:
    if out:
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        Path(out).write_text(json.dumps(summary, indent=1, sort_keys=True) + '\n')


def _calibrate_cause(args, profile, controller, simulator, parallel_map) -> int:
    """``calibrate --cause``: the cause's severity range (sim/cause_calibration.py)."""
    from fall_predictor.sim.cause_calibration import CauseCalibrationSetup, calibrate_cause
    if args.cause == 'walk':
        return fail('calibrate', 'a long walk has no disturbance to calibrate')
    setup = CauseCalibrationSetup(args.robot, controller, simulator, args.cause,
                                  None if args.probe is None else tuple(sorted(args.probe)),
                                  args.seed, args.horizon)
    start = time.perf_counter()
    target = 0.45 if args.target == 0.5 else args.target
    summary = calibrate_cause(setup, args.trajectories, parallel_map, target)
    summary['wall_s'] = time.perf_counter() - start
    _write(args.out, summary)
    key = summary['parameter']
    where = (f'controllers.{controller}.causes.{args.cause}.{key}' if profile.controller_profile(controller)
             else f'causes.{args.cause}.{key}')
    lines = [f'{summary["runs"]} {args.cause} runs of {profile.name} under {controller} in {simulator}, '
             f'{key} drawn over {summary["probe"]}: {summary["fall_fraction"]:.2f} fell '
             f'(onset to fall, median: {summary["onset_to_fall_s_median"]} s; '
             f'{summary["without_onset"]} never disturbed, {summary["fell_before_onset"]} fell before the onset)']
    lines += [f'  {b[key][0]:8.4f}-{b[key][1]:8.4f}: {b["runs"]:4d} runs, '
              + ('-' if b['fall_fraction'] is None else f'{b["fall_fraction"]:.2f} fell')
              for b in summary['fall_probability_by_band']]
    if summary['can_fell']:
        low, high = summary['suggested'][key]
        lines.append(f'suggested: {where}: [{low:g}, {high:g}] (predicted fall fraction '
                     f'{summary["predicted_fall_fraction"]:.2f}; put it in the robot profile)')
    else:
        lines.append(f'{args.cause} cannot fell {profile.name} under {controller} within the probe: '
                     f'its severest band fells fewer than 30 % of the runs')
    emit(args, {k: v for k, v in summary.items() if k != 'rows'} if args.json else summary, lines)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser('calibrate', help='the push range that fells about half of a robot\'s runs',
                       description='Push the robot under its controller N times with the dataset '
                                   'protocol (its commanded velocities or gaits, directions, heights, '
                                   'onsets), forces drawn up to --probe-force, and suggest the push '
                                   'range [0, F] whose uniform draws fell --target of the runs (the '
                                   'robot profile\'s push_force_n, per controller).')
    p.add_argument('--trajectories', type=argtypes.positive_int, default=200)
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--probe-force', type=argtypes.positive, default=None, metavar='N',
                   help='largest force drawn [N] (default: 30 N per kg of robot)')
    p.add_argument('--target', type=argtypes.positive, default=0.5,
                   help='fall fraction wanted (default 0.5 for pushes, 0.45 for another --cause)')
    p.add_argument('--cause', choices=('push', 'trip', 'slip', 'step', 'fault'), default='push',
                   help='the disturbance calibrated (default push): trip height, slip friction, step '
                        'height, fault\'s remaining torque share (sim/cause_calibration.py)')
    p.add_argument('--probe', type=argtypes.nonnegative, nargs=2, default=None, metavar=('LOW', 'HIGH'),
                   help='with --cause: the range its parameter is drawn over (default: a wide probe)')
    p.add_argument('--horizon', type=argtypes.positive, default=4.0,
                   help='seconds after the push ends before a run counts as survived')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='parallel processes')
    argtypes.add_robot_argument(p)
    argtypes.add_controller_arguments(p)
    p.add_argument('--out', type=Path, help='also write the JSON (every run) here')
    p.add_argument('--json', action='store_true', help='print one JSON summary object')
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser('robustness', help='survival table of pushes over impulse, direction and gait phase',
                       description='Report, per direction, the largest impulse survived at every '
                                   'phase of the walk cycle, and which pushes of a grid the walking robot '
                                   '(C_bal\'s default gait, or a learned policy at --command) survives: '
                                   'every impulse from 8 directions at N phases.')
    p.add_argument('--impulses', type=argtypes.positive, nargs='+',
                   default=[float(i) for i in range(5, 55, 5)], help='impulses [N s] (force x 0.1 s)')
    p.add_argument('--phases', type=argtypes.positive_int, default=8, help='onsets per walk cycle')
    p.add_argument('--height', type=argtypes.finite(float), default=0.1,
                   help='application height above the CoM [m]')
    p.add_argument('--horizon', type=argtypes.positive, default=3.0,
                   help='seconds after the push ends that the robot must stay up')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='parallel processes')
    argtypes.add_robot_argument(p)
    argtypes.add_controller_arguments(p)
    p.add_argument('--command', type=argtypes.finite(float), nargs=3, default=None,
                   metavar=('VX', 'VY', 'YAW_RATE'),
                   help='a learned policy\'s velocity command [m/s, m/s, rad/s] (default 0 0 0)')
    argtypes.add_scheduler_argument(p, 'the pushes')
    p.add_argument('--out', type=Path, help='also write the JSON summary here')
    p.add_argument('--json', action='store_true', help='print one JSON summary object')
    p.set_defaults(func=cmd_robustness)
