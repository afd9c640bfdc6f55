#!/usr/bin/env python3
"""Speed of the 1 kHz simulation loop on one core (issue: simulated humanoid, §6).

Prints JSON: steps per second (and multiples of real time) of the full loop (physics +
C_bal + measurements) and of bare PyBullet stepping of the same robot in the same posture,
and their ratio; both by wall clock and by process CPU time (less sensitive to other load).

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

from fall_predictor.profiles import DEFAULT_ROBOT, load_profile
from fall_predictor.robot.controllers import BalanceController, ControllerSwitch, controller_configs
from fall_predictor.sim.simulator import Simulator, SimulatorConfig


def _rates(steps: int, wall: float, cpu: float) -> dict:
    return {'steps_per_s_wall': steps / wall, 'steps_per_s_cpu': steps / cpu,
            'real_time_factor_wall': steps / wall / 1000.0, 'real_time_factor_cpu': steps / cpu / 1000.0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=10.0, help='simulated seconds per measurement')
    parser.add_argument('--solver-iterations', type=int, default=SimulatorConfig().solver_iterations)
    parser.add_argument('--robot', default=DEFAULT_ROBOT, help='robot profile (name or path)')
    args = parser.parse_args()
    steps = int(args.seconds * 1000)
    config = SimulatorConfig(solver_iterations=args.solver_iterations)
    profile = load_profile(args.robot)

    sim = Simulator(config, profile)
    gait, reflex, stabilizer = controller_configs(profile)
    switch = ControllerSwitch(BalanceController(gait, reflex, walk_duration_s=args.seconds + 5,
                                                stabilizer=stabilizer, profile=profile))
    q0, torso = switch.balance.initial_posture()
    m = sim.reset(q0, torso)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        sim.set_joint_targets(switch.update(m))
        m = sim.step()
    full = _rates(steps, time.perf_counter() - wall0, time.process_time() - cpu0)
    fell = bool(m.com[2] < profile.fallen_com_height_m)

    m = sim.reset(q0, torso)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        pb.stepSimulation(physicsClientId=sim.client)
    bare = _rates(steps, time.perf_counter() - wall0, time.process_time() - cpu0)
    sim.close()
    print(json.dumps({
        'robot': profile.name, 'simulated_s': args.seconds, 'solver_iterations': args.solver_iterations,
        'full_loop': full, 'bare_physics': bare,
        'full_over_bare_cpu': full['steps_per_s_cpu'] / bare['steps_per_s_cpu'],
        'full_loop_fell': fell,
        'load_average_1min': os.getloadavg()[0], 'cpus': os.cpu_count(), 'python': platform.python_version(),
    }, indent=1))


if __name__ == '__main__':
    main()
