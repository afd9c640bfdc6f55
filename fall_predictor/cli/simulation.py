"""``fall-predictor simulate`` and ``bringup``: the simulated robot, alone or as the ROS 2 system."""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from fall_predictor.cli import args as argtypes
from fall_predictor.cli.args import emit as _emit, fail as _fail


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


def cmd_bringup(args) -> int:
    try:
        from fall_predictor.ros.bringup import cmd_bringup as run
    except ImportError as error:
        return _fail('bringup', f'bringup needs ROS 2 (rclpy and common_interfaces): {error}')
    return run(args)


def register(sub: argparse._SubParsersAction) -> None:
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

    p = sub.add_parser('bringup', help='start the ROS 2 nodes and push the robot N times',
                       description='Start simulator, feature, predictor and controller nodes (and '
                                   'optionally the recorder) as separate processes with the shipped '
                                   'config and model, push the robot N times and print one JSON '
                                   'line per push.')
    argtypes.add_bringup_arguments(p)
    p.set_defaults(func=cmd_bringup)
