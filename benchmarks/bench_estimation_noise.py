"""State estimation error against ground truth as the sensor noise grows (0x, 1x, 2x, 4x).

Simulates ``--trajectories`` pushed walks of the default gait (pushes from the method §3
distribution, seeded), records their exact sensor quantities once, and for each noise scale
applies the sensor model (same seeds) and runs the estimator (aligned at the first sample like
``estimation-error``). Prints one JSON object and writes ``benchmarks/results/estimation_noise.json``:
per scale the ``estimation-error`` summary (CoM, momenta, CoP, contact-mode agreement).

Usage: ``python benchmarks/bench_estimation_noise.py [--trajectories 6] [--seed 10]``. The
prediction side of the noise sweep (FPR, tau_lead) needs the training path on estimated state,
not done yet.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fall_predictor.data.estimation import BagEstimate, aligned_config, error_samples, summarise
from fall_predictor.monitor.estimator import StateEstimator
from fall_predictor.sim.pushes import PushDistribution, trajectory_seed
from fall_predictor.sim.sensors import SensorParams, apply_sensors, robot_description
from fall_predictor.sim.trajectory import run_trajectory

SCALES = (0.0, 1.0, 2.0, 4.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--trajectories', type=int, default=6)
    parser.add_argument('--seed', type=int, default=10)
    parser.add_argument('--pre-push-s', type=float, default=1.0, help='walk evaluated before the push')
    parser.add_argument('--after-s', type=float, default=2.0, help='simulated after the push ends')
    parser.add_argument('--out', type=Path, default=Path(__file__).parent / 'results' / 'estimation_noise.json')
    args = parser.parse_args()
    urdf = robot_description()
    per_scale: dict[float, list] = {s: [] for s in SCALES}
    for i in range(args.trajectories):
        push = PushDistribution().sample(trajectory_seed(args.seed, i))
        run = run_trajectory(push, push.t_force_end + args.after_s, record_sensors=True)
        first = next(k for k, m in enumerate(run.measurements) if m.t >= push.t_push - args.pre_push_s - 1e-9)
        truth = {round(m.t * 1000): m for m in run.measurements}
        for scale in SCALES:
            readings = apply_sensors(run.sensor_truths, SensorParams(noise_scale=scale), seed=1000 + i)[first:]
            est = StateEstimator(urdf, aligned_config(urdf, readings, truth))
            out = est.run(readings)
            b = BagEstimate(np.array([r.t for r in readings]), out,
                            [truth[round(r.t * 1000)] for r in readings])
            per_scale[scale].append(error_samples(b, push.t_push))
        print(f'trajectory {i}: {push.force_n:.0f} N at {push.angle_deg:.0f} deg, fallen {run.fallen}', flush=True)
    result = {'trajectories': args.trajectories, 'seed': args.seed,
              'noise_scales': {str(s): summarise(per_scale[s]) for s in SCALES}}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + '\n')
    print(json.dumps(result))


if __name__ == '__main__':
    main()
