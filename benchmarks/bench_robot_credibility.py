"""Robot credibility of the previous and the current robot on the method §3 push protocol.

'previous': PyBullet position motors, stabilizer off; 'current': PD torque servos and the
closed-loop stabilizer (the defaults). Both use today's walking plan and reflex.
For N pushes of dataset seed 0 (the same pushes for both robots) simulates each trajectory
with C_bal and reports, through the statistics `fall-predictor stats` uses: the CoM rise after
the push (p50/p95/p99), the fraction of samples airborne while upright, the touchdown force
peaks of the unpushed walk, the fall fraction and the CPU time.

    .venv/bin/python benchmarks/bench_robot_credibility.py --trajectories 60 \
        --out docs/robots/asimo_like/robot_credibility.json
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from fall_predictor.data.stats import robot_credibility
from fall_predictor.monitor.records import N_FEATURES, TrajectoryFeatures
from fall_predictor.sim.pushes import PushDistribution, trajectory_seed
from fall_predictor.sim.pybullet_world import PybulletWorld, PybulletConfig
from fall_predictor.robot.stabilizer import StabilizerConfig
from fall_predictor.sim.trajectory import ROBOT_TOTAL_MASS_KG, WalkPrefix, run_trajectory
from fall_predictor.profiles.profile import C_BAL
from fall_predictor.robot.control import make_controller

ROBOTS = {'previous': ('position', StabilizerConfig().open_loop()), 'current': ('pd_torque', StabilizerConfig())}


def measure(robot: str, n: int, horizon_s: float) -> dict:
    actuation, stabilizer = ROBOTS[robot]
    dist = PushDistribution()
    sim = PybulletWorld(config=PybulletConfig(actuation=actuation))
    prefix = WalkPrefix(sim, until_s=dist.settle_s + dist.walk_cycle_s() + 0.01, walk_duration_s=60.0,
                        controller=make_controller(sim.profile, C_BAL, walk_duration_s=60.0,
                                                   stabilizer=stabilizer))
    trajectories, fallen = [], 0
    start = time.process_time()
    for i in range(n):
        push = dist.sample(trajectory_seed(0, i))
        result = run_trajectory(push, push.t_force_end + horizon_s, prefix=prefix)
        ms = result.measurements[int(round((push.t_push - 1.0) / sim.config.dt_s)):]
        X = np.zeros((len(ms), N_FEATURES))
        X[:, 2] = [m.com[2] for m in ms]
        force = np.array([[m.left_contacts[:, 2].sum(), m.right_contacts[:, 2].sum()] for m in ms])
        trajectories.append(TrajectoryFeatures(f'{i}', np.array([m.t for m in ms]), X,
                                               np.zeros(len(ms), dtype=int), result.fallen, push.t_push,
                                               push.t_force_end, result.t_fallen, None, force))
        fallen += result.fallen
    cpu = time.process_time() - start
    sim.close()
    return {'robot': robot, 'actuation': actuation, 'stabilizer': stabilizer.dcm_gain > 0, 'trajectories': n, 'fall_fraction': fallen / n, 'cpu_s': cpu,
            **robot_credibility(trajectories, ROBOT_TOTAL_MASS_KG)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--trajectories', type=int, default=60)
    parser.add_argument('--horizon', type=float, default=2.5, help='s simulated after the push ends')
    parser.add_argument('--out', type=Path, default=Path('docs/robots/asimo_like/robot_credibility.json'))
    args = parser.parse_args()
    results = [measure(robot, args.trajectories, args.horizon) for robot in ROBOTS]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2) + '\n')
    print(json.dumps(results, indent=2))


if __name__ == '__main__':
    main()
