"""``fall-predictor generate``, ``stats`` and ``import-bags``: datasets."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Optional

from fall_predictor.cli import args as argtypes
from fall_predictor.cli.args import add_robot_argument, emit as _emit, fail as _fail
from fall_predictor.errors import one_line


def _sensor_timing(args, profile) -> Optional[dict]:
    """``--sensor-timing robot``: the drivers of a robot (sim/drivers.py) at ``--joint-rate-hz``,
    joint states split into the robot's legs and upper body (its profile's joint groups), IMU and
    foot sensors 0.3 / 0.4 ms after them."""
    if args.sensor_timing == 'simulator':
        return None
    from fall_predictor.sim.drivers import DriverTiming
    return DriverTiming.robot(args.joint_rate_hz, profile.legs_and_upper_body(),
                              clock_offset_ns=0).to_dict()


def generation_config(args):
    """The ``GenerationConfig`` of ``generate``'s arguments: another robot's push range (or
    ``--push-force-n``'s), and no gait draws for a robot whose controller only stands or whose
    profile says so (``gait_variety``)."""
    from fall_predictor.data.generation import GenerationConfig
    from fall_predictor.profiles.profile import DEFAULT_ROBOT
    from fall_predictor.sim.pushes import PushDistribution

    from fall_predictor.profiles.profile import C_BAL

    controller, simulator = argtypes.controller_of(args)
    profile = argtypes.checked_profile(args.robot, controller)
    standing = bool(profile.controller.get('gait', {}).get('standing', False))
    extra = {} if args.robot == DEFAULT_ROBOT else {
        'robot': args.robot, 'push_distribution': PushDistribution.for_robot(profile)}
    if controller != C_BAL:
        extra['controller'] = controller
    if simulator != 'pybullet':
        extra['simulator'] = simulator
    if args.causes is not None:
        from fall_predictor.data.disturbance_generation import parse_causes
        extra['causes'] = parse_causes(args.causes)      # ValueError: generate says why
        extra['walk_s'] = args.walk_s
    if args.randomize:
        extra['randomize'] = True
    if args.push_force_n is not None:
        extra['push_force_n'] = args.push_force_n
    noise = args.sensor_noise
    if controller != C_BAL and noise is None:
        noise = 1.0                 # a learned policy walks on its sensors: the bags hold them
    return GenerationConfig(seed=args.seed, horizon_after_push_s=args.horizon,
                            settle_extension_s=args.settle_extension,
                            gait_variety=not (args.fixed_gait or standing) and profile.gait_variety,
                            sensor_noise_scale=noise,
                            sensor_timing=_sensor_timing(args, profile), **extra)


def cmd_generate(args) -> int:
    from fall_predictor.data.dataset import CAUSE_WALK, DatasetError, read_manifest
    from fall_predictor.data.dataset_writer import WriterStopped
    from fall_predictor.data.generation import generate_dataset

    from fall_predictor.profiles.profile import ProfileError
    try:
        config = generation_config(args)
    except (ProfileError, ValueError) as error:
        return _fail('generate', error)
    start = time.perf_counter()
    try:
        rows = generate_dataset(args.out, args.trajectories, args.seed, jobs=args.jobs, config=config,
                                progress=not args.json, scheduler=args.scheduler)
    except (DatasetError, RuntimeError) as error:
        return _fail('generate', error)
    except WriterStopped as stop:
        print(f'fall-predictor generate: {stop}', file=sys.stderr)
        return 128 + stop.signum            # the shell's convention for a process a signal ended
    from fall_predictor.data.stats import stats_by_cause
    wall = time.perf_counter() - start
    rows = [r for r in rows if int(r.trajectory_id.split('_')[1]) < args.trajectories]
    fallen = sum(r.fallen for r in rows)
    # Runs still moving at the horizon, recorded on until they settled or fell (method §4); a
    # long walk has no horizon: it lasts as long as it was asked to.
    went_on = [r for r in rows if r.cause != CAUSE_WALK
               and r.t_end - r.t_force_end > config.horizon_after_push_s + 1e-6]
    size = sum(f.stat().st_size for f in Path(args.out).rglob('*') if f.is_file() and 'cache' not in f.parts)
    cost = read_manifest(args.out).get('generation', {})
    payload = {'out': str(args.out), 'trajectories': len(rows), 'fallen': fallen,
               'fall_fraction': fallen / len(rows) if rows else None, 'wall_s': wall,
               'disk_bytes': size, 'seed': args.seed, 'jobs': args.jobs, 'scheduler': args.scheduler,
               'gait_variety': config.gait_variety, 'cpu_s': cost.get('cpu_s'),
               'cpu_per_simulated_s': cost.get('cpu_per_simulated_s'),
               'machines': cost.get('machines', {}), 'by_cause': stats_by_cause(rows),
               'recorded_past_horizon': {r.trajectory_id: {'fallen': r.fallen, 'after_push_end_s': round(
                   r.t_end - r.t_force_end, 3)} for r in went_on}}
    # (a run that fell before its disturbance acted is recorded as a walk that fell, the
    # disturbance it was meant to have in its parameters: data/generation.py)
    before_push = [r for r in rows if r.fallen and r.t_fallen is not None
                   and (r.t_fallen < r.t_push or 'fell_before_onset_of' in (r.params or {}))]
    payload['fell_before_push'] = len(before_push)
    machines = ', '.join(f'{host} ({m["cores"]} cores, {m["trajectories"]} traj)'
                         for host, m in payload['machines'].items())
    _emit(args, payload, [f'{len(rows)} trajectories in {args.out} ({fallen} fallen, '
                          f'{size / 1e6:.0f} MB) in {wall:.0f} s',
                          f'CPU {payload["cpu_s"]:.0f} s in all ({payload["cpu_per_simulated_s"]:.3f} s per '
                          f'simulated s) on {machines}' if payload['cpu_s'] is not None else 'CPU: not recorded',
                          f'{len(went_on)} still moving at the {config.horizon_after_push_s:g} s horizon, '
                          f'recorded until they settled or fell ({sum(r.fallen for r in went_on)} fell)',
                          *_cause_lines(payload['by_cause'], config.causes)])
    if before_push:
        # A robot that falls before any push has its files wrong (or walks beyond itself): the
        # dataset's falls are not those of pushes.
        from fall_predictor.profiles.profile import load_profile
        profile = load_profile(args.robot)
        controller = argtypes.controller_of(args)[0]
        print(f'warning: {len(before_push)} of {len(rows)} runs fell before their push (first at '
              f'{min(r.t_fallen for r in before_push):.2f} s): run `fall-predictor check --robot '
              f'{args.robot}` (likely: {argtypes.unpushed_fall_causes(profile, controller)})',
              file=sys.stderr)
    return 0


def _cause_lines(by_cause: dict, causes) -> list:
    if causes is None and set(by_cause) <= {'push'}:
        return []
    lines = []
    for cause, c in by_cause.items():
        text = f'{cause}: {c["runs"]} runs, {c["fallen"]} fallen ({c["fall_fraction"]:.2f})'
        if c['without_onset']:
            text += f', {c["without_onset"]} never disturbed (no onset)'
        if c['onset_to_fall_s_median'] is not None:
            text += f', onset to fall {c["onset_to_fall_s_median"]:.2f} s (median)'
        if cause == 'walk':
            text += f', {c["hours"]:.3f} h walked'
        lines.append(text)
    return lines


def cmd_stats(args) -> int:
    from fall_predictor.data.dataset import load_features, read_index, robot_total_mass_kg
    from fall_predictor.data.stats import dataset_stats, plot_fig6, stats_by_cause

    rows = read_index(args.data)
    report = load_features(args.data, jobs=args.jobs, progress=not args.json)
    stats = dataset_stats(rows, report.trajectories, robot_total_mass_kg(args.data))
    stats['unreadable_bags'] = report.errors
    stats['by_cause'] = stats_by_cause(rows)
    plots_dir = Path(args.plots) if args.plots else Path(args.data) / 'plots'
    stats['plots'] = [str(p) for p in plot_fig6(report.trajectories, plots_dir)]
    lines = [f"{stats['trajectories']} trajectories, {stats['fallen']} fallen "
             f"(fall fraction {stats['fall_fraction']:.3f}), {stats['samples']} samples"]
    for key in ('duration_s', 'oracle_lead_s', 'fall_after_force_end_s'):
        d = stats[key]
        if d:
            lines.append(f"{key}: median {d['median']:.3f}, p95 {d['p95']:.3f}, max {d['max']:.3f}")
    for key in ('com_rise_m', 'touchdown_force_peak_bw'):
        d = stats[key]
        if d:
            lines.append(f"{key}: p50 {d['p50']:.3f}, p95 {d['p95']:.3f}, p99 {d['p99']:.3f}, max {d['max']:.3f}")
    if stats['airborne_upright_fraction'] is not None:
        lines.append(f"airborne_upright_fraction: {stats['airborne_upright_fraction']:.4f}")
    lines.append('contact-mode occupancy: ' + ', '.join(
        f'{k} {v:.3f}' for k, v in stats['contact_mode_occupancy'].items() if v > 0))
    lines += _cause_lines(stats['by_cause'], None)
    for tid, error in report.errors.items():
        lines.append(f'UNREADABLE {tid}: {error}')
    lines.append('plots: ' + ', '.join(stats['plots']))
    _emit(args, stats, lines)
    return 1 if report.errors else 0


def cmd_import_bags(args) -> int:
    from fall_predictor.data.dataset import PUSH_UNKNOWN, DatasetError, read_manifest
    from fall_predictor.data.recording_import import ImportReport, import_recordings
    from fall_predictor.data.robot_import import (import_robot_recordings, is_robot_recording,
                                                  read_push_times)
    from fall_predictor.profiles.profile import ProfileError

    try:
        if args.urdf is not None:                   # a broken URDF said now, not per recording
            _check_urdf(args.urdf)
        push_times = read_push_times(args.push_times) if args.push_times is not None else None
        if all(is_robot_recording(bag) for bag in args.bags):       # a robot's own topics
            urdf = args.urdf.read_text() if args.urdf is not None else None
            report = ImportReport(*import_robot_recordings(args.bags, args.out, urdf, args.robot,
                                                           push_times))
        elif push_times is not None:
            return _fail('import-bags', '--push-times is for a robot\'s own recordings; these '
                                        'recorder_node bags carry their pushes')
        else:
            report = import_recordings(args.bags, args.out, args.robot)
    except (DatasetError, OSError, ProfileError) as error:
        return _fail('import-bags', error)
    pushes = read_manifest(args.out).get('push_times')
    no_push = [r.trajectory_id for r in report.rows if r.push_source == PUSH_UNKNOWN]
    payload = {'out': str(args.out), 'imported': len(report.rows),
               'fallen': sum(r.fallen for r in report.rows), 'rejected': report.rejected,
               'push_times': pushes, 'without_push_time': no_push}
    lines = [f'{len(report.rows)} recordings imported into {args.out} ({payload["fallen"]} fallen)']
    if pushes is not None:
        lines.append(f'push times: {pushes["push_topic"]} from the push topic, {pushes["push_times_file"]} '
                     f'from --push-times, {pushes["unknown"]} without one')
        if no_push:
            lines.append(f'{len(no_push)} recordings without a push time ({", ".join(no_push[:5])}'
                         f'{" ..." if len(no_push) > 5 else ""}): their t_push is the recording\'s start, '
                         'as before (alarms count from it; none is "before the push")')
        for name in pushes.get('file_entries_unused', []):
            lines.append(f'warning: --push-times names {name}, which is not among the recordings')
    lines += [f'REJECTED {bag}: {why}' for bag, why in report.rejected.items()]
    _emit(args, payload, lines)
    if not report.rows and report.rejected:         # nothing imported: said on stderr too
        bag, why = next(iter(report.rejected.items()))
        more = f' ({len(report.rejected) - 1} more rejected)' if len(report.rejected) > 1 else ''
        print(f'fall-predictor import-bags: error: no recording imported: {one_line(why)}{more}',
              file=sys.stderr)
    return 0 if report.rows else 1


def _check_urdf(path: Path) -> None:
    """ProfileError-like one line (TeamFileError) unless ``path`` is a URDF that parses."""
    import xml.etree.ElementTree as ET

    from fall_predictor.errors import TeamFileError
    try:
        text = path.read_text()
        root = ET.fromstring(text) if text.strip() else None
    except (ET.ParseError, OSError, UnicodeDecodeError) as error:
        raise TeamFileError(f'not a readable URDF: {error}', file=path, field='--urdf',
                            fix='give the robot\'s URDF (an intact XML file)') from None
    if root is None or root.tag != 'robot':
        raise TeamFileError('not a URDF (no <robot> element)', file=path, field='--urdf',
                            fix='give the robot\'s URDF')


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser('generate', help='generate push trajectories as rosbag2 (MCAP) bags',
                       description='Generate N push trajectories (method §3, the walking controller '
                                   'throughout: C_bal, or a learned policy at a commanded velocity drawn '
                                   'per run) into DIR: one rosbag2 bag per trajectory plus an index. '
                                   'Deterministic per seed; rerunning finishes an interrupted run without '
                                   'redoing finished trajectories.')
    p.add_argument('--trajectories', type=argtypes.positive_int, required=True)
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--out', type=Path, required=True, help='dataset directory')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='parallel processes')
    p.add_argument('--horizon', type=argtypes.positive, default=4.0,
                   help='simulated seconds after the push ends before a trajectory counts as balanced')
    p.add_argument('--settle-extension', type=argtypes.nonnegative, default=3.0, metavar='SECONDS',
                   help='a trajectory still moving at the horizon is simulated on until it settles or '
                        'falls, for up to this much longer (0: stop at the horizon)')
    p.add_argument('--sensor-noise', type=float, default=None, metavar='SCALE', help='also record the sensor topics (noise x SCALE; 1 = default sensors)')
    p.add_argument('--sensor-timing', choices=('simulator', 'robot'), default='simulator',
                   help='how the sensor topics are published: the simulator\'s timing (all at 1 kHz, one '
                        'stamp per step) or a robot\'s drivers (joint states at --joint-rate-hz split '
                        'into legs and upper body, IMU and foot sensors 0.3 / 0.4 ms after them)')
    p.add_argument('--joint-rate-hz', type=argtypes.positive, default=500.0,
                   help='joint state rate with --sensor-timing robot [Hz]')
    add_robot_argument(p)
    argtypes.add_controller_arguments(p)
    p.add_argument('--causes', default=None, metavar='CAUSE[:WEIGHT],...',
                   help='what disturbs the runs, with mix weights: push, trip, slip, step, fault, walk '
                        '(e.g. push:0.4,trip:0.15,slip:0.15,step:0.1,fault:0.1,walk:0.1; no weights: '
                        'equal); default: pushes only, as datasets made before')
    p.add_argument('--walk-s', type=argtypes.positive, default=60.0, metavar='SECONDS',
                   help='length of a long walk (the cause walk; default 60 s)')
    p.add_argument('--randomize', action='store_true',
                   help='randomise each run\'s world as legged_gym-style training does (ground friction, '
                        'link masses, base payload, motor strength, PD gains, sensor latency, IMU bias: '
                        'sim/randomization.py), its draw in the index')
    p.add_argument('--push-force-n', type=argtypes.force_range, default=None, metavar='LOW,HIGH',
                   help='draw each push\'s force uniformly from [LOW, HIGH] N instead of the robot '
                        'profile\'s range (push_force_n, or controllers.<name>.push_force_n): a second '
                        'sampler of the same robot, e.g. only the ambiguous band\'s pushes, to check a '
                        'model\'s false-alarm budget on runs drawn otherwise (method §11); other causes '
                        'keep their ranges; dataset.json records the range drawn')
    p.add_argument('--fixed-gait', action='store_true',
                   help='every trajectory walks the default gait (faster: the walk is simulated once per '
                        'process) instead of drawing its gait (method §3 amendment)')
    argtypes.add_scheduler_argument(p, 'the simulations (bags come back here and are written to --out)')
    p.add_argument('--json', action='store_true')
    p.set_defaults(func=cmd_generate)

    p = sub.add_parser('stats', help='statistics and Fig. 6 plots of a dataset',
                       description='Trajectories, fall fraction, duration and oracle-lead distributions, '
                                   'contact-mode occupancy, and PNG plots like the paper\'s Fig. 6. '
                                   'Exits 1 if some bags are unreadable (they are listed).')
    p.add_argument('data', type=Path, help='dataset directory')
    p.add_argument('--plots', default=None, help='where to write PNGs (default DATA/plots)')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1)
    p.add_argument('--json', action='store_true')
    p.set_defaults(func=cmd_stats)

    p = sub.add_parser('import-bags', help='make a dataset from recordings (recorder_node or a robot\'s own)',
                       description='Copy recorded bags into a new dataset directory with an index, so that '
                                   'train/evaluate/sweep can use them: recorder_node bags (one push each, '
                                   'C_bal throughout: `bringup --record DIR --no-fall-trigger`), or a robot\'s '
                                   '`ros2 bag record` of /joint_states, /imu/data, /left_foot/wrench, '
                                   '/right_foot/wrench (and /robot_description): falls are then found from the '
                                   'estimated CoM height and the IMU tilt (docs/method.md), the push onset '
                                   'from a /fall_predictor/push message (geometry_msgs/WrenchStamped, its '
                                   'stamp the onset) or --push-times; without one a recording\'s push time '
                                   'is its start.')
    p.add_argument('bags', nargs='+', type=Path, help='bag directories')
    p.add_argument('--urdf', type=Path, default=None, help='the robot\'s URDF, for recordings without '
                   '/robot_description')
    p.add_argument('--out', type=Path, required=True, help='new dataset directory')
    p.add_argument('--push-times', type=Path, default=None, metavar='CSV',
                   help='push onsets of a robot\'s recordings without a /fall_predictor/push message: a '
                        'CSV with a header and the columns bag (the recording as given here, or its '
                        'directory name) and t_push_s (the onset in the recording\'s own stamp time, '
                        'seconds, e.g. 1718000012.250) or t_push_ns (the same as an integer stamp); a '
                        'time outside the recording refuses it')
    add_robot_argument(p)
    p.add_argument('--json', action='store_true')
    p.set_defaults(func=cmd_import_bags)
