"""Credibility of a simulated robot from one of its datasets (true state), in its own size: the
CoM rise after the push (launches), the samples with no foot on the ground while upright (in
survived and in fallen runs), and the ground-force peaks of the touchdowns of the walk before the
push and of the steps after a survived push, in body weights: per 1 ms sample (PyBullet's rigid
contact lands a foot in one impulse) and averaged over 10 ms (as a rubber sole spreads it). Heights are the robot's:
"upright" is a CoM above 0.76 of its standing CoM height (the ASIMO-like robot's 0.45 m of
0.589 m, the threshold `fall-predictor stats` uses for it).

    .venv/bin/python benchmarks/bench_robot_profile_credibility.py --data data/g1_dev1000 \\
        --out docs/robots/g1_c_bal/credibility.json
"""
from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from fall_predictor.data.dataset import read_manifest, robot_total_mass_kg
from fall_predictor.data.stats import (UPRIGHT_COM_FRACTION, com_rise_m, standing_com_height_m,
                                       touchdown_force_peaks_n)
from fall_predictor.learning.training import load_dataset
from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2

def _percentiles(values) -> dict:
    v = np.asarray(list(values), dtype=float)
    return {'n': int(v.size), 'p50': float(np.percentile(v, 50)), 'p95': float(np.percentile(v, 95)),
            'p99': float(np.percentile(v, 99)), 'max': float(v.max())} if v.size else {'n': 0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--data', type=Path, required=True)
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, required=True)
    args = parser.parse_args()
    trajectories = load_dataset(args.data, jobs=args.jobs, state='true').trajectories
    weight_n = robot_total_mass_kg(args.data) * STANDARD_GRAVITY_M_S2
    standing = standing_com_height_m(trajectories)
    upright = UPRIGHT_COM_FRACTION * standing
    airborne = {False: 0, True: 0}
    samples = {False: 0, True: 0}
    peaks = {'walk': [], 'recovery': [], 'walk_10ms': [], 'recovery_10ms': []}
    for traj in trajectories:
        samples[traj.fallen] += len(traj.t)
        no_foot = traj.foot_force_n.sum(axis=1) <= 0.0
        airborne[traj.fallen] += int((no_foot & (traj.com_height > upright)).sum())
        smoothed = replace(traj, foot_force_n=np.column_stack([
            np.convolve(f, np.ones(10) / 10, mode='same') for f in traj.foot_force_n.T]))
        peaks['walk'] += touchdown_force_peaks_n(traj)
        peaks['walk_10ms'] += touchdown_force_peaks_n(smoothed)
        # Touchdowns of the survived pushes (a falling robot's last steps are part of its fall).
        if not traj.fallen:
            peaks['recovery'] += touchdown_force_peaks_n(traj, after_push=True)
            peaks['recovery_10ms'] += touchdown_force_peaks_n(smoothed, after_push=True)
    result = {
        'data': str(args.data), 'robot': read_manifest(args.data).get('robot', {}).get('name'),
        'trajectories': len(trajectories), 'fall_fraction': float(np.mean([t.fallen for t in trajectories])),
        'standing_com_height_m': standing, 'upright_com_m': upright,
        'com_rise_m': _percentiles(com_rise_m(t) for t in trajectories),
        'airborne_upright_fraction': sum(airborne.values()) / sum(samples.values()),
        'airborne_upright_fraction_survived': airborne[False] / max(samples[False], 1),
        'airborne_upright_fraction_fallen': airborne[True] / max(samples[True], 1),
        'walk_touchdown_peak_bw': _percentiles(p / weight_n for p in peaks['walk']),
        'walk_touchdown_peak_bw_10ms_mean': _percentiles(p / weight_n for p in peaks['walk_10ms']),
        'recovery_touchdown_peak_bw': _percentiles(p / weight_n for p in peaks['recovery']),
        'recovery_touchdown_peak_bw_10ms_mean': _percentiles(p / weight_n for p in peaks['recovery_10ms']),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + '\n')
    print(json.dumps(result, indent=1))


if __name__ == '__main__':
    main()
