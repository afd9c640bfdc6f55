#!/usr/bin/env python3
"""Dataset generation against bare physics on one core, side by side in one run.

For trajectories 0..N-1 of a dataset seed (the method §3 pushes and gaits) this measures, by
process CPU time per simulated second:

* ``generation``: what ``fall-predictor generate`` does per trajectory (simulate with C_bal,
  build the measurements, record the bag, the labels, the index row and the cost record);
* ``simulation``: the simulation alone (``run_trajectory``: physics, servos, C_bal,
  measurements, and with ``--sensor-noise`` the sensor truth), without recording;
* ``bare_physics``: the same robot making the same motion with PyBullet calls only: the joint
  torques and push forces that the simulation sent to PyBullet, replayed step by step into a
  fresh world, then ``stepSimulation``. The replay must end where the simulation ended (checked:
  the base pose matches to 1e-9 m), so both step the same contacts, not a collapsed robot.

The ratio ``generation / bare_physics`` is the aim (<= 1.3). With ``--profile`` it also
writes the top of a cProfile of the generation pass (``--profile-out``).

    .venv/bin/python benchmarks/bench_generation_speed.py --trajectories 10 \
        --sensor-noise 1 --out docs/scale_out/generation_speed.json
"""
from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import platform
import pstats
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import pybullet

from bare_physics import MAX_POSE_ERROR_M, record_calls, replay
from fall_predictor.data import generation
from fall_predictor.data.generation import GenerationConfig, generate_one
from fall_predictor.robot.balance_controller import BalanceController, ReflexConfig
from fall_predictor.sim.pushes import trajectory_seed
from fall_predictor.sim.trajectory import gait_run, run_trajectory

def _trajectory(config: GenerationConfig, index: int):
    gait, push = config.push_distribution.sample_with_gait(trajectory_seed(config.seed, index))
    return gait, push, push.t_force_end + config.horizon_after_push_s


def _record(config: GenerationConfig, index: int):
    """The PyBullet calls of trajectory ``index`` and the base pose it ends in."""
    gait, push, duration = _trajectory(config, index)

    def run():
        sim = generation._worker_simulator()
        run_trajectory(push, duration, **gait_run(sim, gait, duration))
        return sim
    return record_calls(run)


def _replay(config: GenerationConfig, index: int, calls) -> tuple[float, int, np.ndarray]:
    """Bare physics: a fresh world in the trajectory's first posture, the recorded calls only.
    Returns CPU seconds of the stepping loop, steps, and the final base pose."""
    gait, _, duration = _trajectory(config, index)
    posture = BalanceController(gait, ReflexConfig(), generation._worker_simulator().config.dt_s,
                                walk_duration_s=duration + 5.0).initial_posture()
    return replay(generation._worker_simulator(), *posture, calls)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--trajectories', type=int, default=10)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--horizon', type=float, default=4.0, help='as generate --horizon')
    parser.add_argument('--sensor-noise', type=float, default=None, metavar='SCALE',
                        help='as generate --sensor-noise: record the robot\'s sensor topics (the '
                             'datasets of docs/results.md use 1)')
    parser.add_argument('--out', type=Path, help='write the JSON here too')
    parser.add_argument('--profile', action='store_true', help='cProfile the generation pass')
    parser.add_argument('--profile-out', type=Path, help='where to write the profile table (text)')
    args = parser.parse_args()
    config = GenerationConfig(seed=args.seed, horizon_after_push_s=args.horizon,
                              sensor_noise_scale=args.sensor_noise)
    indices = range(args.trajectories)
    folder = Path(tempfile.mkdtemp(prefix='bench_generation_'))
    try:
        generation._open_dataset(folder, config)
        generate_one(folder, config, 0)                  # warm up: imports, simulator, caches
        shutil.rmtree(folder)
        generation._open_dataset(folder, config)

        profiler = cProfile.Profile() if args.profile else None
        cpu0, wall0 = time.process_time(), time.perf_counter()
        if profiler:
            profiler.enable()
        rows = [generate_one(folder, config, i) for i in indices]
        if profiler:
            profiler.disable()
        generation_cpu, generation_wall = time.process_time() - cpu0, time.perf_counter() - wall0
        simulated_s = sum(json.loads((folder / 'costs' / f'{r.trajectory_id}.json').read_text())['simulated_s']
                          for r in rows)

        cpu0 = time.process_time()
        for i in indices:
            gait, push, duration = _trajectory(config, i)
            run_trajectory(push, duration, **gait_run(generation._worker_simulator(), gait, duration),
                           record_sensors=args.sensor_noise is not None)
        simulation_cpu = time.process_time() - cpu0

        bare_cpu, steps, pose_error = 0.0, 0, 0.0
        for i in indices:
            calls, pose = _record(config, i)
            cpu, n, replayed = _replay(config, i, calls)
            bare_cpu += cpu
            steps += n
            pose_error = max(pose_error, float(np.abs(replayed - pose).max()))
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    if pose_error > MAX_POSE_ERROR_M:
        raise SystemExit(f'the bare replay did not reproduce the motion (pose error {pose_error:.3g})')

    def per_s(cpu: float) -> float:
        return cpu / simulated_s
    result = {
        'trajectories': args.trajectories, 'seed': args.seed, 'horizon_after_push_s': args.horizon,
        'sensor_noise_scale': args.sensor_noise,
        'simulated_s': round(simulated_s, 3), 'physics_steps': steps,
        'recorded_fraction_of_simulated': round(sum(r.samples for r in rows) / steps, 4),
        'cpu_s': {'generation': generation_cpu, 'simulation': simulation_cpu, 'bare_physics': bare_cpu},
        'cpu_per_simulated_s': {'generation': per_s(generation_cpu), 'simulation': per_s(simulation_cpu),
                                'bare_physics': per_s(bare_cpu)},
        'generation_over_bare_physics': generation_cpu / bare_cpu,
        'simulation_over_bare_physics': simulation_cpu / bare_cpu,
        'recording_share_of_generation': (generation_cpu - simulation_cpu) / generation_cpu,
        'aim_generation_over_bare_physics': 1.3,
        'replay_pose_error_m': pose_error,
        'generation_wall_s': generation_wall, 'profiled': bool(args.profile),
        'load_average_1min': os.getloadavg()[0], 'cpus': os.cpu_count(),
        'python': platform.python_version(), 'pybullet_api': pybullet.getAPIVersion(),
    }
    if profiler:
        text = io.StringIO()
        pstats.Stats(profiler, stream=text).sort_stats('tottime').print_stats(30)
        if args.profile_out:
            args.profile_out.parent.mkdir(parents=True, exist_ok=True)
            args.profile_out.write_text(text.getvalue())
    output = json.dumps(result, indent=1)
    print(output)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(output + '\n')


if __name__ == '__main__':
    main()
