"""``fall-predictor simulate`` and ``bringup``: the simulated robot, alone or as the ROS 2 system."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from fall_predictor.cli import args as argtypes
from fall_predictor.cli.args import emit as _emit, fail as _fail


def cmd_simulate(args) -> int:
    from fall_predictor.monitor.records import PushSpec
    from fall_predictor.profiles.profile import ProfileError
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.policy_runs import commanded_pushes, physics_dt_s
    from fall_predictor.sim.pushes import PushDistribution, robot_gait
    from fall_predictor.sim.trajectory import run_trajectory
    from fall_predictor.sim.world import make_world

    try:
        controller_name, simulator = argtypes.controller_of(args)
        profile = argtypes.checked_profile(args.robot, controller_name)
        policy = profile.controller_profile(controller_name)
    except ProfileError as error:
        return _fail('simulate', error)
    rng = np.random.default_rng(args.seed)
    push = None
    if args.push_force > 0:
        if args.push_time is not None:
            onset = args.push_time
        elif policy is None:
            onset = PushDistribution().onset(rng, robot_gait(args.robot))
        else:
            pushes = commanded_pushes(policy)
            onset = round(policy.settle_s + rng.uniform(0.0, pushes.cycle_s), 3)
        push = PushSpec(args.push_force, args.push_angle, args.push_height, onset)
        if push.t_force_end > args.duration:
            print(f'error: the push ends at {push.t_force_end:.3f} s, after --duration {args.duration} s',
                  file=sys.stderr)
            return 2
    options = {'gui': True} if args.gui and simulator == 'pybullet' else {}
    world = make_world(profile, simulator, physics_dt_s(policy), **options)
    controller = make_controller(profile, controller_name, args.command,
                                 dt_s=world.dt_s, walk_duration_s=args.duration + 5.0)
    start = time.perf_counter()
    try:
        result = run_trajectory(push, args.duration, world=world, controller=controller)
    finally:
        world.close()
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
        # How far the CoM went over the ground, and its heading change: a walk's speed and turn.
        'com_travel_m': float(np.linalg.norm(result.com[-1, :2] - result.com[0, :2])),
        'heading_change_deg': float(np.degrees(np.unwrap([m.heading for m in result.measurements])[-1]
                                               - result.measurements[0].heading)),
        'wall_s': wall,
        'real_time_factor': simulated / wall if wall > 0 else None,
        'seed': args.seed,
        'robot': profile.name, 'controller': controller.name, 'simulator': simulator,
        'command': None if policy is None else list(controller.velocity_command),
    }
    lines = [f'{profile.name} under {controller.name} in {simulator}: simulated {simulated:.3f} s in '
             f'{wall:.1f} s ({payload["real_time_factor"]:.2f}x real time)']
    if push is not None:
        lines.append(f'push: {push.force_n:.0f} N for {push.duration_s:.1f} s at {push.t_push:.3f} s, '
                     f'{push.angle_deg:.0f} deg from the heading, {push.height_m:+.2f} m above the CoM')
    lines.append('reflex: ' + ('none' if result.t_reflex is None else f'fired at {result.t_reflex:.3f} s'))
    lines.append(f'outcome: FALLEN at {result.t_fallen:.3f} s' if result.fallen else 'outcome: balanced')
    _emit(args, payload, lines)
    if result.fallen and (push is None or result.t_fallen < push.t_push):
        # No push fells a working robot: its files are wrong (check says which), or the
        # commanded walk is beyond it.
        print(f'warning: {profile.name} fell at {result.t_fallen:.2f} s under {controller.name} with '
              f'no push{"" if push is None else " (before its push)"}: run `fall-predictor check --robot {args.robot}` (likely: '
              + argtypes.unpushed_fall_causes(profile, controller_name)
              + (f'; or the command {list(controller.velocity_command)} is beyond the policy'
                 if policy is not None else '') + ')', file=sys.stderr)
    elif policy is not None:
        _warn_if_off_command(args, profile, controller, result, push)
    return 0


#: simulate says when a learned policy does not walk as commanded, over at least this much walk
#: before any push [s] (from its first second on: sim/checks.py).
TRACKING_WINDOW_S = 3.0


def _warn_if_off_command(args, profile, controller, result, push) -> None:
    """One warning line when the walk before any push is not the commanded one (sim/checks.py's
    measure): a policy that walks, but not as told, is a mistake in its files as often as a fall."""
    from fall_predictor.sim.checks import MEASURE_FROM_S, command_problems

    until = result.measurements[-1].t if push is None else push.t_push
    if until - MEASURE_FROM_S < TRACKING_WINDOW_S:
        return
    found, problems = command_problems(result.measurements, controller.velocity_command, until)
    if problems:
        print(f'warning: {profile.name} under {controller.name} at the command '
              f'{list(controller.velocity_command)}: {found}: {", ".join(problems)}: run '
              f'`fall-predictor check --robot {args.robot}` (likely: '
              f'{argtypes.unpushed_fall_causes(profile, controller.name)}; or the command is '
              'beyond the policy)', file=sys.stderr)


def cmd_render(args) -> int:
    """A pushed run of the robot under its controller as a strip of frames (headless renders of
    the run's own world: PyBullet's TinyRenderer, MuJoCo's offscreen renderer)."""
    import math

    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    from fall_predictor.monitor.records import PushSpec
    from fall_predictor.profiles.profile import ProfileError
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.policy_runs import physics_dt_s
    from fall_predictor.sim.trajectory import run_trajectory
    from fall_predictor.sim.world import make_world

    try:
        controller_name, simulator = argtypes.controller_of(args)
        if simulator == 'mujoco':           # before MuJoCo is imported (the checks load it)
            from fall_predictor.sim.gl_backend import choose_mujoco_gl
            choose_mujoco_gl()
        profile = argtypes.checked_profile(args.robot, controller_name)
        policy = profile.controller_profile(controller_name)
    except ProfileError as error:
        return _fail('render', error)
    world = make_world(profile, simulator, physics_dt_s(policy))
    disturbance = None
    if args.cause != 'push':
        # Another cause (sim/disturbances.py), drawn from --seed: a first run measures its onset.
        disturbance, args.onset, controller, what = _disturbance_to_render(args, profile, controller_name, world)
        args.force, args.angle = 0.0, 0.0           # the camera at right angles to the walk (+x)
    else:
        controller = make_controller(profile, controller_name, args.command, dt_s=world.dt_s,
                                     walk_duration_s=args.onset + args.after + 5.0)
    push = PushSpec(args.force, args.angle, args.height, args.onset) if disturbance is None else None
    times = list(np.linspace(args.onset - args.before, args.onset + args.after, args.frames))
    images, labels, heading, frame_times = [], [], [], []
    height_m = 0.42 * profile.guard_com_height_m / 0.48     # the ASIMO-like robot's view, scaled

    def on_step(w, m) -> None:
        if not heading and m.t >= args.onset - 1e-9:
            heading.append(math.degrees(m.heading))
        if times and m.t >= times[0] - 1e-9:
            # The camera follows the CoM, at right angles to the push: its motion in the image plane.
            yaw = (heading[0] if heading else math.degrees(m.heading)) + args.angle
            images.append(w.render(320, 400, (m.com[0], m.com[1], height_m), yaw))
            frame_times.append(m.t)
            contact = ('both feet' if len(m.left_contacts) and len(m.right_contacts) else
                       'left foot' if len(m.left_contacts) else
                       'right foot' if len(m.right_contacts) else 'no foot')
            labels.append(f't = {m.t - args.onset:+.2f} s\nCoM {m.com[2]:.2f} m, {contact}'
                          + (', fallen' if m.com[2] < profile.fallen_com_height_m else ''))
            times.pop(0)
    try:
        # With a model, the robot's sensors are simulated (a policy's are anyway) for the monitor.
        result = run_trajectory(push, args.onset + args.after + 0.01, stop_when_fallen=False,
                                world=world, controller=controller, on_step=on_step,
                                record_sensors=args.model is not None and policy is None,
                                disturbance=disturbance)
    finally:
        world.close()
    alarm = _monitor_alarm(profile, args.model, result) if args.model is not None else None
    fig, axes = plt.subplots(1, len(images), figsize=(2.0 * len(images), 3.3))
    for ax, image, label, t in zip(np.atleast_1d(axes), images, labels, frame_times):
        ax.imshow(image)
        alarmed = alarm is not None and t >= alarm.stamp_s - 1e-9
        ax.set_title(label + ('\nmonitor: FALLING' if alarmed else '\n'), fontsize=7,
                     color='tab:red' if alarmed else 'black')
        ax.axis('off')
    who = controller.name
    if policy is not None:
        who += ' at (' + ', '.join(f'{c:g}' for c in controller.velocity_command) + ')'
    if disturbance is None:
        what = (f'{push.impulse_ns:.0f} N s push, {args.angle:.0f}° from the heading, {args.height:.2f} m '
                'above the CoM (t = 0: onset)') if args.force else 'no push (t = 0: the given onset)'
    fig.suptitle(f'{profile.name}, {who}, {simulator}: {what}' + ('' if args.model is None else
                                     f'\nmonitor ({Path(args.model).name}): ' + (
                                         'no alarm' if alarm is None else
                                         f'FALLING at {alarm.stamp_s - args.onset:+.3f} s' + (
                                             f', fallen at {result.t_fallen - args.onset:+.3f} s'
                                             if result.fallen else ''))), fontsize=9)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.86 if args.model is not None else 0.92))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    plt.close(fig)
    payload = {'out': str(args.out), 'fallen': result.fallen, 't_fallen': result.t_fallen,
               'cause': args.cause, 't_onset': args.onset if disturbance is not None else push.t_push,
               'cause_params': None if disturbance is None else disturbance.params,
               'frames': len(images), 'robot': profile.name, 'controller': controller.name,
               'simulator': simulator, 'model': None if args.model is None else str(args.model),
               't_alarm': None if alarm is None else alarm.stamp_s,
               'lead_s': (result.t_fallen - alarm.stamp_s) if alarm is not None and result.fallen
               else None}
    lines = [f'{args.out}: {len(images)} frames, ' + (
        f'fallen at {result.t_fallen:.3f} s' if result.fallen else 'standing at the end')]
    if args.model is not None:
        lines.append(f'monitor ({args.model}): ' + ('no alarm' if alarm is None else
                                                    f'FALLING at {alarm.stamp_s:.3f} s'))
    _emit(args, payload, lines)
    return 0


def _disturbance_to_render(args, profile, controller_name, world):
    """``render --cause``: (the disturbance drawn from ``--seed`` as a dataset draws it, its onset
    measured by a first run [s], a fresh controller for the rendered run, the title's words)."""
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.disturbance_runs import (cause_ranges, fault_joints, run_length_s,
                                                     sample_disturbance, walker_for)
    from fall_predictor.sim.trajectory import WALK_MARGIN_S, run_trajectory

    disturbance, gait, expected_s = sample_disturbance(
        args.cause, np.random.default_rng(args.seed), walker_for(profile, controller_name),
        cause_ranges(profile, controller_name, args.cause), fault_joints(profile), walk_s=args.after)

    def controller():
        command = disturbance.command or args.command
        if disturbance.schedule is not None:
            command = disturbance.schedule.at(0.0)
        return make_controller(profile, controller_name, command, dt_s=world.dt_s,
                               walk_duration_s=expected_s + args.after + WALK_MARGIN_S + 5.0, gait=gait)
    first = run_trajectory(None, run_length_s(args.cause, expected_s, args.after), world=world,
                           controller=controller(), disturbance=disturbance)
    onset = first.extras['t_onset']
    if onset is None:
        onset = expected_s if args.cause != 'walk' else 2.0
    words = ', '.join(f'{k} {v:.3g}' if isinstance(v, float) else f'{k} {v}'
                      for k, v in disturbance.params.items() if k not in ('times_s', 'commands'))
    return disturbance, onset, controller(), f'{args.cause} ({words}; t = 0: onset)'


def _monitor_alarm(profile, model: Path, result):
    """The first alarm of the onboard monitor (``model``) on a run's simulated sensor topics,
    as the robot's drivers publish them (data/onboard_replay)."""
    from fall_predictor.data.onboard_replay import first_alarm, onboard_chain
    from fall_predictor.sim.drivers import driver_messages
    from fall_predictor.sim.sensors import SensorParams, apply_sensors

    samples = result.sensor_readings or apply_sensors(result.sensor_truths, SensorParams(), seed=0,
                                                      profile=profile)
    return first_alarm(onboard_chain(profile, model), driver_messages(samples))


def cmd_bringup(args) -> int:
    try:
        from fall_predictor.ros.bringup import cmd_bringup as run
    except ImportError as error:
        return _fail('bringup', f'bringup needs ROS 2 (rclpy and common_interfaces): {error}')
    return run(args)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser('simulate', help='walk, optionally push once, and report the outcome',
                       description='Simulate a humanoid walking under its controller (C_bal, or a learned '
                                   'policy at --command); optionally push it once (a constant force for '
                                   '0.1 s on the torso) and report whether it fell.')
    p.add_argument('--duration', type=argtypes.positive, default=6.0, help='simulated seconds (default 6)')
    p.add_argument('--push-force', type=argtypes.finite(float), default=0.0, help='push force [N]; 0 = no push')
    p.add_argument('--push-angle', type=argtypes.finite(float), default=0.0,
                   help='push direction [deg] from the heading, counter-clockwise (90 = to the left)')
    p.add_argument('--push-height', type=argtypes.finite(float), default=0.1, help='height above the CoM [m]')
    p.add_argument('--push-time', type=argtypes.finite(float), default=None,
                   help='push onset [s]; default: a random instant of the walk cycle drawn from --seed')
    p.add_argument('--seed', type=int, default=0, help='random seed (push onset)')
    argtypes.add_robot_argument(p)
    argtypes.add_controller_arguments(p)
    p.add_argument('--command', type=argtypes.finite(float), nargs=3, default=None,
                   metavar=('VX', 'VY', 'YAW_RATE'),
                   help='a learned policy\'s velocity command [m/s, m/s, rad/s] (default: its deploy '
                        'config\'s cmd_init)')
    p.add_argument('--gui', action='store_true', help='open the PyBullet GUI')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser('render', help='a pushed run as a strip of frames (PNG)',
                       description='Render a pushed run of the robot under its controller as a strip '
                                   'of frames, the camera following the robot at right angles to the '
                                   'push (headless: PyBullet\'s TinyRenderer, MuJoCo\'s offscreen '
                                   'renderer with MUJOCO_GL=egl or osmesa).')
    p.add_argument('--cause', choices=('push', 'trip', 'slip', 'step', 'fault', 'walk'), default='push',
                   help='what disturbs the run (default push); another cause is drawn from --seed as '
                        'a dataset draws it, the frames around its measured onset')
    p.add_argument('--seed', type=int, default=0, help='with --cause: the draw of the disturbance')
    p.add_argument('--force', type=argtypes.finite(float), default=250.0, help='push force [N] for 0.1 s')
    p.add_argument('--angle', type=argtypes.finite(float), default=90.0,
                   help='push direction from the heading [deg]')
    p.add_argument('--height', type=argtypes.finite(float), default=0.1, help='above the CoM [m]')
    p.add_argument('--onset', type=argtypes.positive, default=2.5, help='push onset [s]')
    p.add_argument('--after', type=argtypes.positive, default=1.6, help='seconds shown after the onset')
    p.add_argument('--before', type=argtypes.nonnegative, default=0.1,
                   help='seconds shown before the onset')
    p.add_argument('--model', type=Path, default=None,
                   help='also run the onboard monitor with this model on the run\'s simulated sensor '
                        'topics and mark the frames from its first alarm (FALLING)')
    p.add_argument('--frames', type=argtypes.positive_int, default=8)
    argtypes.add_robot_argument(p)
    argtypes.add_controller_arguments(p)
    p.add_argument('--command', type=argtypes.finite(float), nargs=3, default=None,
                   metavar=('VX', 'VY', 'YAW_RATE'), help='a learned policy\'s velocity command')
    p.add_argument('--out', type=Path, required=True, help='the PNG to write')
    p.add_argument('--json', action='store_true')
    p.set_defaults(func=cmd_render)

    p = sub.add_parser('bringup', help='start the ROS 2 nodes and push the robot N times',
                       description='Start simulator, feature, predictor and controller nodes (and '
                                   'optionally the recorder) as separate processes with the shipped '
                                   'config and model, push the robot N times (under a learned policy, '
                                   'each push with the velocity command of its dataset trajectory) and '
                                   'print one JSON line per push.')
    argtypes.add_bringup_arguments(p)
    p.set_defaults(func=cmd_bringup)
