#!/usr/bin/env python3
"""Speed of the 1 kHz simulation loop on one core, against bare physics of the same motion.

Prints JSON: steps per second (and multiples of real time) of the full loop (physics, servos,
C_bal and the measurements, walking with the robot's own gait) and of bare PyBullet stepping of
the same motion (the loop's joint torques replayed into a fresh world, :mod:`bare_physics`; the
replay must end in the loop's final pose), and their ratio, by wall clock and by process CPU
time (less sensitive to other load). For comparison, ``collapsing_robot_physics``: the robot
stepped from its first posture with no torques, which lets it fall and lie on the ground (what
this benchmark measured as bare physics before: about twice the cost of the walking robot's).

    .venv/bin/python benchmarks/bench_sim_speed.py --seconds 10
    .venv/bin/python benchmarks/bench_sim_speed.py --seconds 10 --robot g1
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time

import pybullet as pb

from bare_physics import MAX_POSE_ERROR_M, record_calls, replay
from fall_predictor.profiles.profile import DEFAULT_ROBOT, load_profile
from fall_predictor.robot.control import BalanceControl, ControllerSwitch
from fall_predictor.robot.balance_controller import BalanceController, controller_configs
from fall_predictor.sim.pybullet_world import PybulletWorld, PybulletConfig


def _rates(steps: int, wall: float, cpu: float) -> dict:
    return {'steps_per_s_wall': steps / wall, 'steps_per_s_cpu': steps / cpu,
            'real_time_factor_wall': steps / wall / 1000.0, 'real_time_factor_cpu': steps / cpu / 1000.0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=10.0, help='simulated seconds per measurement')
    parser.add_argument('--solver-iterations', type=int, default=PybulletConfig().solver_iterations)
    parser.add_argument('--robot', default=DEFAULT_ROBOT, help='robot profile (name or path)')
    parser.add_argument('--out', help='write the JSON here too')
    args = parser.parse_args()
    steps = int(args.seconds * 1000)
    config = PybulletConfig(solver_iterations=args.solver_iterations)
    profile = load_profile(args.robot)
    sim = PybulletWorld(profile, config=config)
    gait, reflex, stabilizer = controller_configs(profile)

    def walk() -> PybulletWorld:
        """The full loop from the first posture, every step; the simulator it ran."""
        switch = ControllerSwitch(BalanceControl(BalanceController(
            gait, reflex, walk_duration_s=args.seconds + 5, stabilizer=stabilizer, profile=profile)))
        m = sim.reset(*switch.balance.initial_posture())
        for _ in range(steps):
            sim.set_joint_targets(switch.update(m))
            m = sim.step()
        return sim

    walk()                                          # warm up: caches, first allocations
    wall0, cpu0 = time.perf_counter(), time.process_time()
    walk()
    full = _rates(steps, time.perf_counter() - wall0, time.process_time() - cpu0)
    fell = bool(sim.measure().com[2] < profile.fallen_com_height_m)

    calls, pose = record_calls(walk)
    posture = BalanceController(gait, reflex, walk_duration_s=args.seconds + 5,
                                stabilizer=stabilizer, profile=profile).initial_posture()
    wall0 = time.perf_counter()
    bare_cpu, bare_steps, replayed = replay(sim, *posture, calls)
    bare = _rates(bare_steps, time.perf_counter() - wall0, bare_cpu)
    pose_error = float(abs(replayed - pose).max())
    if bare_steps != steps or pose_error > MAX_POSE_ERROR_M:
        raise SystemExit(f'the bare replay did not reproduce the walk ({bare_steps} steps, pose '
                         f'error {pose_error:.3g})')

    sim.reset(*posture)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        pb.stepSimulation(physicsClientId=sim.client)
    collapsing = _rates(steps, time.perf_counter() - wall0, time.process_time() - cpu0)
    collapsing['final_base_height_m'] = float(
        pb.getBasePositionAndOrientation(sim.robot, physicsClientId=sim.client)[0][2])
    sim.close()
    result = {
        'robot': profile.name, 'simulated_s': args.seconds, 'solver_iterations': args.solver_iterations,
        'full_loop': full, 'bare_physics': bare,
        'full_over_bare_cpu': full['steps_per_s_cpu'] / bare['steps_per_s_cpu'],
        'replay_pose_error_m': pose_error, 'full_loop_fell': fell,
        'collapsing_robot_physics': collapsing,
        'load_average_1min': os.getloadavg()[0], 'cpus': os.cpu_count(), 'python': platform.python_version(),
    }
    output = json.dumps(result, indent=1)
    print(output)
    if args.out:
        with open(args.out, 'w', encoding='utf-8') as f:
            f.write(output + '\n')


if __name__ == '__main__':
    main()
