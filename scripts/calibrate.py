#!/usr/bin/env python3
"""Calibration of C_bal against method §3 (issue: simulated humanoid, §5).

Runs N random pushes drawn per method §3 (C_bal throughout, no predictor) and writes JSON:
the fall fraction, the fall fraction by force band, and the time from the end of the push
to the fall (which justifies the dataset horizon). Usage:

    .venv/bin/python scripts/calibrate.py --trajectories 200 --seed 1 --jobs 2 --out docs/calibration.json
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
from joblib import Parallel, delayed
from tqdm import tqdm

from fall_predictor.sim.pushes import PushDistribution, trajectory_seed
from fall_predictor.sim.trajectory import run_trajectory

HORIZON_AFTER_PUSH_S = 6.0   # generous here: this run measures how long falls take


def one(seed: int, index: int) -> dict:
    push = PushDistribution().sample(trajectory_seed(seed, index))
    result = run_trajectory(push, push.t_force_end + HORIZON_AFTER_PUSH_S)
    last = result.measurements[-1]
    return {'index': index, 'force_n': push.force_n, 'angle_deg': push.angle_deg, 'height_m': push.height_m,
            't_push': push.t_push, 'fallen': result.fallen, 't_fallen': result.t_fallen,
            't_reflex': result.t_reflex,
            'final_horizontal_momentum': float(np.hypot(*last.lin_mom[:2])) if not result.fallen else None}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--trajectories', type=int, default=200)
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', default='docs/calibration.json')
    args = parser.parse_args()
    start = time.time()
    rows = Parallel(n_jobs=args.jobs)(delayed(one)(args.seed, i)
                                      for i in tqdm(range(args.trajectories), desc='pushes'))
    fallen = [r for r in rows if r['fallen']]
    bands = {}
    for lo in range(0, 500, 50):
        band = [r for r in rows if lo <= r['force_n'] < lo + 50]
        bands[f'{lo}-{lo + 50} N'] = {'n': len(band), 'fall_fraction': (sum(r['fallen'] for r in band) / len(band)) if band else None}
    delays = np.array([r['t_fallen'] - r['t_push'] - 0.1 for r in fallen])
    under_200 = [r for r in rows if r['force_n'] < 200]
    summary = {
        'command': f'scripts/calibrate.py --trajectories {args.trajectories} --seed {args.seed}',
        'trajectories': len(rows),
        'fall_fraction': len(fallen) / len(rows),
        'survival_fraction_under_200N': 1 - sum(r['fallen'] for r in under_200) / max(1, len(under_200)),
        'fall_fraction_by_force': bands,
        'fall_after_force_end_s': {'min': float(delays.min()), 'median': float(np.median(delays)),
                                   'p95': float(np.percentile(delays, 95)), 'max': float(delays.max())} if len(delays) else None,
        'max_final_horizontal_momentum_balanced': max((r['final_horizontal_momentum'] for r in rows if not r['fallen']), default=None),
        'wall_s': time.time() - start,
        'rows': rows,
    }
    with open(args.out, 'w') as f:
        json.dump(summary, f, indent=1)
    print(json.dumps({k: v for k, v in summary.items() if k != 'rows'}, indent=1))


if __name__ == '__main__':
    main()
