"""Samples the onboard state estimator refuses (and flags) on a dataset's sensor topics.

For every bag of a dataset generated with ``--sensor-noise`` the estimator runs over the sensor
messages as the live node does (:func:`fall_predictor.data.estimation.run_pipeline`); each sample
it gives no estimate for is a refused one (onboard: a DEGRADED state). Counted apart:

* runs the robot survived (any refused sample there is a false DEGRADED of a robot that was fine);
* runs that fell: before the push, and from the push to the fall (the seconds the monitor is for);
* the first samples before any sole is loaded (the world frame is not placed yet: not a bound);
* samples flagged (beyond a joint's limit or speed, kept: method §10's plausibility tiers).

The reasons are tallied by their first words. Writes one JSON object (also printed).

Usage::

    python benchmarks/bench_refused_samples.py --data data/g1pol40 \
        --out docs/estimation/refused_samples_g1_12dof.json
"""
from __future__ import annotations

import argparse
import collections
import json
import re
from pathlib import Path

from fall_predictor.data.dataset import dataset_robot, read_index
from fall_predictor.data.estimation import run_pipeline

#: The fault of a sample before the world frame is placed (not a plausibility bound).
NO_FIX = 'no loaded sole yet'


def _reason(fault: str) -> str:
    """A fault's kind: its words with the numbers and joint names taken out."""
    words = re.sub(r'-?\d+(\.\d+)?(e-?\d+)?', 'N', fault)
    words = re.sub(r'joint \S+', 'joint J', words)
    return words[:110]


def measure(data: Path, limit: int = 0) -> dict:
    robot = dataset_robot(data)
    rows = read_index(data)[:limit or None]
    totals = collections.Counter()
    reasons = collections.Counter()
    flag_reasons = collections.Counter()
    for row in rows:
        estimates = run_pipeline(data / row.bag, robot=robot)
        where = 'fell' if row.fallen else 'survived'
        totals[f'{where}_runs'] += 1
        refused_here = 0
        for e in estimates:
            t = e.stamp_ns / 1e9
            totals[f'{where}_samples'] += 1
            flags = getattr(e, 'flags', '')
            if flags:
                totals[f'{where}_flagged'] += 1
                flag_reasons[_reason(flags)] += 1
            if e.measurement is not None:
                continue
            if NO_FIX in e.fault:
                totals['before_first_fix'] += 1
                continue
            refused_here += 1
            reasons[_reason(e.fault)] += 1
            if not row.fallen:
                totals['survived_refused'] += 1
            elif t < row.t_push:
                totals['fell_refused_before_push'] += 1
            elif row.t_fallen is None or t <= row.t_fallen:
                totals['fell_refused_push_to_fall'] += 1
            else:
                totals['fell_refused_after_fall'] += 1
        if refused_here:
            totals[f'{where}_runs_with_refused'] += 1
    return {'data': str(data), 'robot': robot, 'counts': dict(sorted(totals.items())),
            'refused_reasons': dict(reasons.most_common(12)),
            'flagged_reasons': dict(flag_reasons.most_common(12))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--data', type=Path, required=True)
    parser.add_argument('--limit', type=int, default=0, help='only the first N runs')
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args()
    result = measure(args.data, args.limit)
    text = json.dumps(result, indent=2)
    print(text)
    if args.out:
        args.out.write_text(text + '\n')


if __name__ == '__main__':
    main()
