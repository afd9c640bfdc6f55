"""CPU time per sample of the state estimator (the state_estimator_node's core) at 1 kHz.

Simulates a walk with a push (sensor truths recorded), applies the default sensor model, then
times :meth:`StateEstimator.update` on every sample in this one process (``time.thread_time``
around each call, so time the scheduler gives to other processes is not counted; wall time too).
Prints one JSON object and writes it to ``benchmarks/results/estimator_cpu.json``:
``cpu_us`` and ``wall_us`` (median, p90, p99), the sample count and the load average.

Usage: ``python benchmarks/bench_estimator.py [--duration 4.0] [--repeats 3]``; the aim
is a median of at most 150 us.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from fall_predictor.monitor.estimator import StateEstimator
from fall_predictor.monitor.records import PushSpec
from fall_predictor.sim.sensors import SensorParams, apply_sensors, robot_description
from fall_predictor.sim.trajectory import run_trajectory


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=4.0, help='simulated seconds')
    parser.add_argument('--repeats', type=int, default=3, help='passes over the recording')
    parser.add_argument('--out', type=Path, default=Path(__file__).parent / 'results' / 'estimator_cpu.json')
    args = parser.parse_args()
    run = run_trajectory(PushSpec(60.0, 30.0, 0.1, 2.0), args.duration, record_sensors=True)
    readings = apply_sensors(run.sensor_truths, SensorParams(), seed=0)
    urdf = robot_description()
    cpu, wall = [], []
    for _ in range(args.repeats):
        est = StateEstimator(urdf)
        for r in readings:
            c0, w0 = time.thread_time_ns(), time.perf_counter_ns()
            est.update(r)
            cpu.append(time.thread_time_ns() - c0)
            wall.append(time.perf_counter_ns() - w0)

    def stats(ns):
        us = np.array(ns) / 1e3
        return {'median': float(np.median(us)), 'p90': float(np.percentile(us, 90)),
                'p99': float(np.percentile(us, 99))}
    result = {'samples': len(cpu), 'cpu_us': stats(cpu), 'wall_us': stats(wall),
              'aim_median_us': 150.0, 'aim_met': bool(np.median(cpu) / 1e3 <= 150.0),
              'load_average': os.getloadavg(), 'python': platform.python_version(),
              'machine': platform.machine(), 'cores': os.cpu_count()}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + '\n')
    print(json.dumps(result))


if __name__ == '__main__':
    main()
