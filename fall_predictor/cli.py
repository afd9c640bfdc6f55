"""fall-predictor: offline tools of the fall_predictor package (simulate, generate, train, ...)."""
from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path

import numpy as np

from fall_predictor import cli_args as argtypes
from fall_predictor.cli_args import emit as _emit, fail as _fail

# Sub-commands that live in their own front-end module (``fall_predictor/cli_<area>.py``), each
# exposing ``register(subparsers)``. Keeps this file short and each area's options with its code.
COMMAND_MODULES: tuple[str, ...] = ('cli_robot', 'cli_bag', 'cli_estimation')


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


def cmd_generate(args) -> int:
    from fall_predictor.data.dataset import DatasetError, read_manifest
    from fall_predictor.data.generation import GenerationConfig, generate_dataset

    config = GenerationConfig(seed=args.seed, horizon_after_push_s=args.horizon,
                              gait_variety=not args.fixed_gait, sensor_noise_scale=args.sensor_noise)
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


def _add_learner_arguments(p: argparse.ArgumentParser) -> None:
    from fall_predictor.learning.training import DEFAULT_SAMPLE_STRIDE, LEARNER_CLASSES
    p.add_argument('--learner', choices=sorted(LEARNER_CLASSES), default='tree',
                   help='tree: CART tree rewritten as a list; covering: RIPPER-like sequential '
                        'covering (default tree)')
    p.add_argument('--param', type=argtypes.learner_param, action='append', default=[], metavar='KEY=VALUE',
                   help='learner hyper-parameter, repeatable (e.g. --param max_depth=10); VALUE is JSON')
    p.add_argument('--stride', type=argtypes.positive_int, default=DEFAULT_SAMPLE_STRIDE,
                   help=f'train on every K-th 1 kHz sample, weights x K (default {DEFAULT_SAMPLE_STRIDE})')


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
        lists, metadata = train_model(args.data, args.tau_plus, args.learner, dict(args.param),
                                      args.stride, jobs=args.jobs,
                                      recommended_tau_his_s=args.tau_his_recommended,
                                      skip_unreadable=args.skip_unreadable, progress=not args.json)
        save_model(args.out, lists, metadata)
    except (DatasetError, ModelFileError) as error:
        return _fail('train', error)
    wall = time.perf_counter() - start
    payload = {'model': str(args.out), 'tau_plus_s': metadata.tau_plus_s,
               'recommended_tau_his_s': metadata.recommended_tau_his_s,
               'learner': {'name': metadata.learner_name, 'params': metadata.learner_params},
               'sample_stride': args.stride, 'dataset_fingerprint': metadata.dataset_fingerprint,
               'mean_rule_size': lists.mean_rule_size, 'rule_sizes': list(lists.rule_sizes),
               'depths': list(lists.depths), 'wall_s': wall}
    _emit(args, payload, [f'wrote {args.out}: {metadata.learner_name}, tau_plus '
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
        evaluation = evaluate_model(args.data, lists, tau_his, baselines=args.baselines,
                                    jobs=args.jobs, skip_unreadable=args.skip_unreadable,
                                    progress=not args.json, time_to_fall=metadata.time_to_fall,
                                    robot_mass_kg=metadata.robot_mass_kg)
    except (DatasetError, ModelFileError) as error:
        return _fail('evaluate', error)
    payload = {'model': str(args.model), 'data': str(args.data), **evaluation_json(evaluation),
               'trained_on_this_dataset': metadata.dataset_fingerprint == evaluation.dataset_fingerprint}
    r = evaluation.result
    lines = [f'{r.n_trajectories} trajectories ({r.n_fallen} fallen), tau_his {tau_his:.3f} s',
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


def cmd_sweep(args) -> int:
    import shlex

    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.learning.selection import pareto_mean_lead
    from fall_predictor.learning.sweep import SweepConfig, run_sweep

    settings = {'folds': args.folds, 'seed': args.seed, 'learner_name': args.learner,
                'learner_params': dict(args.param), 'sample_stride': args.stride,
                'capture_point': not args.no_capture_point}
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
        return _fail('sweep', error)
    try:
        result = run_sweep(args.data, args.out, config, jobs=args.jobs,
                           skip_unreadable=args.skip_unreadable, progress=not args.json,
                           command=command)
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
        return _fail('sweep', error)
    t = result.timing
    payload = {'out': str(args.out), 'files': list(result.files),
               'n_trajectories': result.n_trajectories, 'n_fallen': result.n_fallen,
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
    _emit(args, payload, lines)
    return 0


def cmd_import_bags(args) -> int:
    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.data.generation import import_recordings

    try:
        report = import_recordings(args.bags, args.out)
    except DatasetError as error:
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
                       description='Generate N push trajectories (SPEC §3, C_bal throughout) into DIR: one '
                                   'rosbag2 bag per trajectory plus an index. Deterministic per seed; '
                                   'rerunning finishes an interrupted run without redoing finished trajectories.')
    p.add_argument('--trajectories', type=argtypes.positive_int, required=True)
    p.add_argument('--seed', type=int, default=0)
    p.add_argument('--out', type=Path, required=True, help='dataset directory')
    p.add_argument('--jobs', type=argtypes.positive_int, default=1, help='parallel processes')
    p.add_argument('--horizon', type=argtypes.positive, default=4.0,
                   help='simulated seconds after the push ends before a trajectory counts as balanced')
    p.add_argument('--sensor-noise', type=float, default=None, metavar='SCALE', help='also record the sensor topics (noise x SCALE; 1 = default sensors)')
    p.add_argument('--fixed-gait', action='store_true',
                   help='every trajectory walks the default gait (faster: the walk is simulated once per '
                        'process) instead of drawing its gait (SPEC §3 amendment)')
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

    p = sub.add_parser('import-bags', help='make a dataset from live recordings (recorder_node bags)',
                       description='Copy recorded bags (one push each, C_bal throughout: record with '
                                   '`bringup --record DIR --no-fall-trigger`) into a new dataset directory '
                                   'with an index, so that train/evaluate/sweep can use them.')
    p.add_argument('bags', nargs='+', type=Path, help='bag directories')
    p.add_argument('--out', type=Path, required=True, help='new dataset directory')
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
                       description='Train one decision list per foot contact mode (SPEC §8) on every '
                                   'trajectory of a dataset and write the JSON model file. Falling states '
                                   'before t_height_drop + tau_plus are withheld; balanced states weigh 4, '
                                   'falling states 1 (per 1 kHz sample). Exit code 2 if the dataset or a '
                                   'setting cannot be used.')
    p.add_argument('--data', type=Path, required=True, help='dataset directory')
    p.add_argument('--tau-plus', type=argtypes.finite(float), required=True,
                   help='tau_plus [s]: falling states are trained on from t_height_drop + tau_plus '
                        '(may be < 0; write --tau-plus=-0.25)')
    p.add_argument('--out', type=Path, required=True, help='model file to write (JSON)')
    _add_learner_arguments(p)
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
                                   'decision lists, history window tau_his, CoM guard) and report SPEC §5\'s '
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
    p.add_argument('--jobs', type=argtypes.positive_int, default=1)
    p.add_argument('--skip-unreadable', action='store_true',
                   help='leave out unreadable bags instead of failing')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_evaluate)

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
    _add_learner_arguments(p)
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
