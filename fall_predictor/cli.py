"""fall-predictor: offline tools of the fall_predictor package (simulate, generate, train, ...)."""
from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path
from typing import Optional

import numpy as np

from fall_predictor import cli_args as argtypes
from fall_predictor.cli_args import add_robot_argument, emit as _emit, fail as _fail

# Sub-commands that live in their own front-end module (``fall_predictor/cli_<area>.py``), each
# exposing ``register(subparsers)``. Keeps this file short and each area's options with its code.
COMMAND_MODULES: tuple[str, ...] = ('cli_sweep', 'cli_robot', 'cli_bag', 'cli_estimation')


# -- simulate --------------------------------------------------------------------------------
def cmd_simulate(args) -> int:
    from fall_predictor.sim.pushes import PushDistribution
    from fall_predictor.monitor.records import PushSpec
    from fall_predictor.sim.simulator import SimulatorConfig
    from fall_predictor.sim.trajectory import run_trajectory

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


def _sensor_timing(args) -> Optional[dict]:
    """``--sensor-timing robot``: the drivers of a robot (sim/drivers.py) at ``--joint-rate-hz``,
    joint states split into legs and upper body, IMU and foot sensors 0.3 / 0.4 ms after them."""
    if args.sensor_timing == 'simulator':
        return None
    from fall_predictor.profiles import asimo_like_urdf as rm
    from fall_predictor.sim.drivers import DriverTiming
    legs = tuple(f'{s}_{j}' for s in rm.SIDES for j in rm.LEG_JOINTS)
    groups = (legs, tuple(n for n in rm.JOINT_NAMES if n not in legs))
    return DriverTiming.robot(args.joint_rate_hz, groups, clock_offset_ns=0).to_dict()


def cmd_generate(args) -> int:
    from fall_predictor.data.dataset import DatasetError, read_manifest
    from fall_predictor.data.generation import GenerationConfig, generate_dataset

    from fall_predictor.profiles import DEFAULT_ROBOT, load_profile
    from fall_predictor.sim.pushes import PushDistribution

    profile = load_profile(args.robot)
    # Another robot: its push range; a robot whose controller only stands draws no gait.
    standing = bool(profile.controller.get('gait', {}).get('standing', False))
    extra = {} if args.robot == DEFAULT_ROBOT else {
        'robot': args.robot, 'push_distribution': PushDistribution.for_robot(profile)}
    config = GenerationConfig(seed=args.seed, horizon_after_push_s=args.horizon,
                              gait_variety=not (args.fixed_gait or standing),
                              sensor_noise_scale=args.sensor_noise,
                              sensor_timing=_sensor_timing(args), **extra)
    start = time.perf_counter()
    try:
        rows = generate_dataset(args.out, args.trajectories, args.seed, jobs=args.jobs, config=config,
                                progress=not args.json, scheduler=args.scheduler)
    except (DatasetError, RuntimeError) as error:
        return _fail('generate', error)
    wall = time.perf_counter() - start
    rows = [r for r in rows if int(r.trajectory_id.split('_')[1]) < args.trajectories]
    fallen = sum(r.fallen for r in rows)
    size = sum(f.stat().st_size for f in Path(args.out).rglob('*') if f.is_file() and 'cache' not in f.parts)
    cost = read_manifest(args.out).get('generation', {})
    payload = {'out': str(args.out), 'trajectories': len(rows), 'fallen': fallen,
               'fall_fraction': fallen / len(rows) if rows else None, 'wall_s': wall,
               'disk_bytes': size, 'seed': args.seed, 'jobs': args.jobs, 'scheduler': args.scheduler,
               'gait_variety': config.gait_variety, 'cpu_s': cost.get('cpu_s'),
               'cpu_per_simulated_s': cost.get('cpu_per_simulated_s'),
               'machines': cost.get('machines', {})}
    machines = ', '.join(f'{host} ({m["cores"]} cores, {m["trajectories"]} traj)'
                         for host, m in payload['machines'].items())
    _emit(args, payload, [f'{len(rows)} trajectories in {args.out} ({fallen} fallen, '
                          f'{size / 1e6:.0f} MB) in {wall:.0f} s',
                          f'CPU {payload["cpu_s"]:.0f} s in all ({payload["cpu_per_simulated_s"]:.3f} s per '
                          f'simulated s) on {machines}' if payload['cpu_s'] is not None else 'CPU: not recorded'])
    return 0


# -- stats --------------------------------------------------------------------------------
def cmd_stats(args) -> int:
    from fall_predictor.data.dataset import load_features, read_index, robot_total_mass_kg
    from fall_predictor.data.stats import dataset_stats, plot_fig6

    rows = read_index(args.data)
    report = load_features(args.data, jobs=args.jobs, progress=not args.json)
    stats = dataset_stats(rows, report.trajectories, robot_total_mass_kg(args.data))
    stats['unreadable_bags'] = report.errors
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
    for tid, error in report.errors.items():
        lines.append(f'UNREADABLE {tid}: {error}')
    lines.append('plots: ' + ', '.join(stats['plots']))
    _emit(args, stats, lines)
    return 1 if report.errors else 0


# -- train, rules, evaluate, sweep --------------------------------------------------------


def cmd_train(args) -> int:
    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.learning.training import make_learner, train_model
    from fall_predictor.monitor.model_file import ModelFileError, save_model

    try:
        make_learner(args.learner, dict(args.param))
    except ValueError as error:
        return _fail('train', error)
    start = time.perf_counter()
    try:
        state = argtypes.resolved_state(args)
        lists, metadata = train_model(args.data, args.tau_plus, args.learner, dict(args.param),
                                      args.stride, jobs=args.jobs,
                                      recommended_tau_his_s=args.tau_his_recommended,
                                      skip_unreadable=args.skip_unreadable, progress=not args.json,
                                      state=state, mirror=args.mirror)
        save_model(args.out, lists, metadata)
    except (DatasetError, ModelFileError) as error:
        return _fail('train', error)
    wall = time.perf_counter() - start
    payload = {'model': str(args.out), 'tau_plus_s': metadata.tau_plus_s,
               'recommended_tau_his_s': metadata.recommended_tau_his_s,
               'learner': {'name': metadata.learner_name, 'params': metadata.learner_params},
               'sample_stride': args.stride, 'state': metadata.state, 'mirror': metadata.mirror,
               'dataset_fingerprint': metadata.dataset_fingerprint,
               'mean_rule_size': lists.mean_rule_size, 'rule_sizes': list(lists.rule_sizes),
               'depths': list(lists.depths), 'wall_s': wall}
    _emit(args, payload, [f'wrote {args.out}: {metadata.learner_name} on the {metadata.state} state, tau_plus '
                          f'{metadata.tau_plus_s:+.3f} s, stride {args.stride}, mean rule size '
                          f'{lists.mean_rule_size:.1f}, depths {list(lists.depths)} ({wall:.1f} s)'])
    return 0


def cmd_rules(args) -> int:
    from fall_predictor.learning.training import rules_summary
    from fall_predictor.monitor.model_file import ModelFileError, load_model

    try:
        lists, metadata = load_model(args.model)
    except ModelFileError as error:
        return _fail('rules', error)
    summary = rules_summary(lists)
    payload = {'model': str(args.model), **summary,
               'training': {'tau_plus_s': metadata.tau_plus_s, 'learner': metadata.learner_name,
                            'params': metadata.learner_params,
                            'recommended_tau_his_s': metadata.recommended_tau_his_s}}
    lines = [f'# {args.model}: {metadata.learner_name}, tau_plus {metadata.tau_plus_s:+.3f} s']
    for mode in summary['modes']:
        lines += ['', f'# {mode["mode"]}: rule size {mode["rule_size"]}, depth {mode["depth"]}', mode['text']]
    lines += ['', f'mean rule size {summary["mean_rule_size"]:.2f} (over the 16 modes); mean depth '
                  f'{summary["mean_depth"]:.1f} (non-empty lists), max depth {summary["max_depth"]}']
    _emit(args, payload, lines)
    return 0


def cmd_evaluate(args) -> int:
    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.learning.evaluation import evaluate_model, evaluation_json
    from fall_predictor.learning.when_where import when_where_lines
    from fall_predictor.monitor.model_file import ModelFileError, load_model

    try:
        lists, metadata = load_model(args.model)
        tau_his = args.tau_his if args.tau_his is not None else metadata.recommended_tau_his_s
        if tau_his is None:
            return _fail('evaluate', f'{args.model} recommends no tau_his: give --tau-his')
        state = argtypes.resolved_state(args)
        evaluation = evaluate_model(args.data, lists, tau_his, baselines=args.baselines,
                                    jobs=args.jobs, skip_unreadable=args.skip_unreadable,
                                    progress=not args.json, time_to_fall=metadata.time_to_fall,
                                    robot_mass_kg=metadata.robot_mass_kg, state=state)
    except (DatasetError, ModelFileError) as error:
        return _fail('evaluate', error)
    payload = {'model': str(args.model), 'data': str(args.data), 'state': state,
               'model_state': metadata.state, **evaluation_json(evaluation),
               'trained_on_this_dataset': metadata.dataset_fingerprint == evaluation.dataset_fingerprint}
    r = evaluation.result
    lines = [f'{r.n_trajectories} trajectories ({r.n_fallen} fallen), {state} state (model trained on '
             f'the {metadata.state} state), tau_his {tau_his:.3f} s',
             f'FPR {r.fpr:.3f} ({r.n_false_positives}/{r.n_balanced} balanced trajectories), '
             f'Wilson 95 % [{r.fpr_ci95[0]:.3f}, {r.fpr_ci95[1]:.3f}]',
             f'tau_lead {r.tau_lead_s:.3f} s (bootstrap 95 % [{r.tau_lead_ci95[0]:.3f}, '
             f'{r.tau_lead_ci95[1]:.3f}]), oracle lead {r.oracle_lead_s:.3f} s, lead fraction '
             f'{r.lead_fraction:.2f}, misses {r.n_missed}/{r.n_fallen}',
             f'decision lists alone (CoM guard off): tau_lead {r.tau_lead_lists_only_s:.3f} s, '
             f'misses {r.n_missed_lists_only}/{r.n_fallen}; CoM guard alone: tau_lead '
             f'{r.tau_lead_guard_only_s:.3f} s',
             f'pre-push false alarms: {r.n_pre_push_alarms_balanced} balanced, '
             f'{r.n_pre_push_alarms_fallen} fallen trajectories',
             f'mean rule size {r.mean_rule_size:.2f}']
    lines += when_where_lines(payload)
    if payload['trained_on_this_dataset']:
        lines.append('warning: the model was trained on this dataset; these numbers are not a '
                     'held-out estimate (use `fall-predictor sweep` for cross-validation)')
    for name, front in payload.get('baselines', {}).items():
        lines.append(f'baseline {name}, Pareto front (FPR, tau_lead): ' + ', '.join(
            f'({p["fpr"]:.2f}, {p["tau_lead_s"]:.2f})' for p in front
            if p['fpr'] is not None and p['tau_lead_s'] is not None))
    for tid, error in evaluation.unreadable.items():
        lines.append(f'SKIPPED {tid}: {error}')
    _emit(args, payload, lines)
    return 0


def cmd_import_bags(args) -> int:
    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.data.generation import ImportReport, import_recordings
    from fall_predictor.data.robot_import import import_robot_recordings, is_robot_recording
    from fall_predictor.profiles import ProfileError

    try:
        if all(is_robot_recording(bag) for bag in args.bags):       # a robot's own topics
            urdf = args.urdf.read_text() if args.urdf is not None else None
            report = ImportReport(*import_robot_recordings(args.bags, args.out, urdf, args.robot))
        else:
            report = import_recordings(args.bags, args.out)
    except (DatasetError, OSError, ProfileError) as error:
        return _fail('import-bags', error)
    payload = {'out': str(args.out), 'imported': len(report.rows),
               'fallen': sum(r.fallen for r in report.rows), 'rejected': report.rejected}
    lines = [f'{len(report.rows)} recordings imported into {args.out} ({payload["fallen"]} fallen)']
    lines += [f'REJECTED {bag}: {why}' for bag, why in report.rejected.items()]
    _emit(args, payload, lines)
    return 0 if report.rows else 1


def cmd_bringup(args) -> int:
    try:
        from fall_predictor.ros.bringup import cmd_bringup as run
    except ImportError as error:
        return _fail('bringup', f'bringup needs ROS 2 (rclpy and common_interfaces): {error}')
    return run(args)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='fall-predictor', description=__doc__)
    sub = parser.add_subparsers(dest='command', metavar='<command>')

    p = sub.add_parser('simulate', help='walk, optionally push once, and report the outcome',
                       description='Simulate the humanoid walking under C_bal; optionally push it once '
                                   '(a constant force for 0.1 s on the torso) and report whether it fell.')
    p.add_argument('--duration', type=argtypes.positive, default=6.0, help='simulated seconds (default 6)')
    p.add_argument('--push-force', type=argtypes.finite(float), default=0.0, help='push force [N]; 0 = no push')
    p.add_argument('--push-angle', type=argtypes.finite(float), default=0.0,
                   help='push direction [deg] from the heading, counter-clockwise (90 = to the left)')
    p.add_argument('--push-height', type=argtypes.finite(float), default=0.1, help='height above the CoM [m]')
    p.add_argument('--push-time', type=argtypes.finite(float), default=None,
                   help='push onset [s]; default: a random instant of the walk cycle drawn from --seed')
    p.add_argument('--seed', type=int, default=0, help='random seed (push onset)')
    p.add_argument('--gui', action='store_true', help='open the PyBullet GUI')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser('generate', help='generate push trajectories as rosbag2 (MCAP) bags',
                       description='Generate N push trajectories (method §3, C_bal throughout) into DIR: one '
                                   'rosbag2 bag per trajectory plus an index. Deterministic per seed; '
                                   'rerunning finishes an interrupted run without redoing finished trajectories.')
    p.add_argument('--trajectories', type=argtypes.positive_int, required=True)
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--out', type=Path, required=True, help='dataset directory')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='parallel processes')
    p.add_argument('--horizon', type=argtypes.positive, default=4.0,
                   help='simulated seconds after the push ends before a trajectory counts as balanced')
    p.add_argument('--sensor-noise', type=float, default=None, metavar='SCALE', help='also record the sensor topics (noise x SCALE; 1 = default sensors)')
    p.add_argument('--sensor-timing', choices=('simulator', 'robot'), default='simulator',
                   help='how the sensor topics are published: the simulator\'s timing (all at 1 kHz, one '
                        'stamp per step) or a robot\'s drivers (joint states at --joint-rate-hz split '
                        'into legs and upper body, IMU and foot sensors 0.3 / 0.4 ms after them)')
    p.add_argument('--joint-rate-hz', type=argtypes.positive, default=500.0,
                   help='joint state rate with --sensor-timing robot [Hz]')
    add_robot_argument(p)
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
                                   'estimated CoM height and the IMU tilt (docs/method.md).')
    p.add_argument('bags', nargs='+', type=Path, help='bag directories')
    p.add_argument('--urdf', type=Path, default=None, help='the robot\'s URDF, for recordings without '
                   '/robot_description')
    p.add_argument('--out', type=Path, required=True, help='new dataset directory')
    add_robot_argument(p)
    p.add_argument('--json', action='store_true')
    p.set_defaults(func=cmd_import_bags)

    p = sub.add_parser('bringup', help='start the ROS 2 nodes and push the robot N times',
                       description='Start simulator, feature, predictor and controller nodes (and '
                                   'optionally the recorder) as separate processes with the shipped '
                                   'config and model, push the robot N times and print one JSON '
                                   'line per push.')
    argtypes.add_bringup_arguments(p)
    p.set_defaults(func=cmd_bringup)

    p = sub.add_parser('train', help='learn per-mode decision lists and write a model file',
                       description='Train one decision list per foot contact mode (method §8) on every '
                                   'trajectory of a dataset and write the JSON model file. Falling states '
                                   'before t_height_drop + tau_plus are withheld; balanced states weigh 4, '
                                   'falling states 1 (per 1 kHz sample). Exit code 2 if the dataset or a '
                                   'setting cannot be used.')
    p.add_argument('--data', type=Path, required=True, help='dataset directory')
    p.add_argument('--tau-plus', type=argtypes.finite(float), required=True,
                   help='tau_plus [s]: falling states are trained on from t_height_drop + tau_plus '
                        '(may be < 0; write --tau-plus=-0.25)')
    p.add_argument('--out', type=Path, required=True, help='model file to write (JSON)')
    argtypes.add_learner_arguments(p)
    argtypes.add_state_argument(p)
    p.add_argument('--mirror', action='store_true',
                   help='also learn from each trajectory\'s left-right mirror image (modes, y components '
                        'and signs mirrored)')
    p.add_argument('--tau-his-recommended', type=argtypes.nonnegative, default=None,
                   help='history window [s] to store as the model\'s run-time default')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='processes loading features')
    p.add_argument('--skip-unreadable', action='store_true',
                   help='leave out unreadable bags instead of failing')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_train)

    p = sub.add_parser('rules', help='print a model\'s decision lists (the paper\'s Fig. 8 form)',
                       description='Print the decision list of every foot contact mode of a model file '
                                   'in the paper\'s Fig. 8 form, with each list\'s rule size (number of '
                                   'comparisons) and depth (number of rules), and the mean rule size over '
                                   'the 16 modes. Exit code 2 if the file is not a valid model.')
    p.add_argument('model', type=Path, help='model file (JSON)')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_rules)

    p = sub.add_parser('evaluate', help='FPR, lead time and misses of a model on a dataset',
                       description='Run a model over every trajectory of a dataset (the online predictor: '
                                   'decision lists, history window tau_his, CoM guard) and report method §5\'s '
                                   'metrics: FPR, tau_lead, misses, pre-push false alarms, oracle lead, lead '
                                   'fraction and mean rule size; with --baselines also the Pareto fronts of '
                                   'the hand-coded baselines. Not cross-validated: use a dataset the model '
                                   'was not trained on. Exit code 2 if the model or dataset cannot be used.')
    p.add_argument('--data', type=Path, required=True, help='dataset directory')
    p.add_argument('--model', type=Path, required=True, help='model file (JSON)')
    p.add_argument('--tau-his', type=argtypes.nonnegative, default=None,
                   help='history window [s] (default: the model\'s recommended value)')
    p.add_argument('--baselines', action='store_true',
                   help='also evaluate the CoM-height, momentum and capture-point baselines')
    argtypes.add_state_argument(p)
    p.add_argument('--jobs', type=argtypes.positive_int, default=1)
    p.add_argument('--skip-unreadable', action='store_true',
                   help='leave out unreadable bags instead of failing')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_evaluate)

    for name in COMMAND_MODULES:
        importlib.import_module(f'fall_predictor.{name}').register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)   # recorded by sweep
    if not getattr(args, 'func', None):
        parser.print_help()
        return 2
    if getattr(args, 'push_force', 0) < 0:
        parser.error('--push-force must be >= 0')
    return int(args.func(args) or 0)


if __name__ == '__main__':
    sys.exit(main())
