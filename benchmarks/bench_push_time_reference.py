#!/usr/bin/env python3
"""A privileged reference for the low false-alarm end: classifiers told when the push came.

The monitor does not know that a push happened, nor when; it judges every sample. This reference
does know: for each delay ``delta`` after the push's onset (``--deltas``: 0.10 s to ``--max-delta``
in 0.05 s steps) it trains a classifier on one row per trajectory, the estimated state at
``t_push + delta``: the 15 features and the base's attitude at that sample, each feature's
largest and smallest value over the last ``--window`` seconds, and the contact mode (``--push``
adds the push itself: force components in the heading frame, height, the gait's parameters and
its phase at the onset). Scikit-learn's histogram gradient boosting, 5-fold CV by trajectory
(the sweep's folds), then trained on all the development data and evaluated once on ``--test``.

Per delay, the threshold that lets ``k`` development false alarms through (out-of-fold scores) is
chosen; the schedule of all delays raises an alarm at the first delay whose classifier is above
its threshold (a trajectory already fallen by that delay cannot be alarmed at it). Reported for
k = 0, 1, 2, on the development folds and held out: FPR [Wilson 95 %], falls detected, mean lead
(t_fallen - t_push - delta at the first alarm) [bootstrap 95 %] and the share of the oracle lead.

What it answers: whether the aim of FPR <= 0.01 at a lead >= 0.76 s with every fall detected is
within reach of the information in the estimated state, given an advantage the monitor never has
(the push's time, one classifier per delay). It is not a bound in the strict sense (another
learner, more data or other inputs could do better), and it has no cost constraint; it is a
reference beside the shipped models' held-out figures. Writes JSON (``--out``).

    .venv/bin/python benchmarks/bench_push_time_reference.py --data data/d1000s \\
        --test data/t1000s_2026 --out docs/prediction/asimo_like/levers/push_time_reference.json
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import time
from pathlib import Path

import numpy as np
from sklearn.ensemble import HistGradientBoostingClassifier

from fall_predictor.learning.crossval import stratified_trajectory_folds
from fall_predictor.learning.intervals import bootstrap_mean_interval, wilson_interval
from fall_predictor.learning.training import load_dataset
from fall_predictor.monitor.records import TrajectoryFeatures


def push_inputs(row: dict) -> list[float]:
    """The push and the gait it met, from a dataset index row: force components in the heading
    frame [N], height [m], gait speed, single-support time, step width, standing, and the phase
    of the push in the stride (cos, sin; zero when standing)."""
    force, angle = float(row['force_n']), math.radians(float(row['angle_deg']))
    single_support_s = float(row['gait_single_support_s'])
    standing = row['gait_standing'] == 'True'
    # The walk starts after half a second of standing; a stride is two steps of double support
    # (0.2 s, the generator's) and single support.
    stride_s = 2.0 * (0.2 + single_support_s)
    phase = 2.0 * math.pi * (((float(row['t_push']) - 0.5) % stride_s) / stride_s)
    return [force * math.cos(angle), force * math.sin(angle), float(row['height_m']),
            float(row['gait_speed_m_s']), single_support_s, float(row['gait_step_width_m']),
            float(standing), 0.0 if standing else math.cos(phase), 0.0 if standing else math.sin(phase)]


def snapshot(traj: TrajectoryFeatures, delta_s: float, window_s: float,
             push: list[float] | None) -> tuple[list[float], bool]:
    """One trajectory's inputs at ``t_push + delta_s`` and whether it had fallen by then (its
    recording ends at the fall: the last sample stands in)."""
    t_query = traj.t_push + delta_s
    i = min(int(np.searchsorted(traj.t, t_query - 1e-9)), len(traj.t) - 1)
    j = min(int(np.searchsorted(traj.t, t_query - window_s - 1e-9)), i)
    recent = traj.X[j:i + 1]
    inputs = [*traj.X[i], *traj.attitude[i], *np.nanmax(recent, axis=0), *np.nanmin(recent, axis=0),
              float(traj.mode[i])]
    gone = bool(traj.fallen and traj.t_fallen <= t_query)
    return inputs + (push or []), gone


def classifier() -> HistGradientBoostingClassifier:
    return HistGradientBoostingClassifier(max_iter=300, learning_rate=0.05, min_samples_leaf=5,
                                          random_state=0)


def scores_at(dev, test, delta_s: float, window_s: float, push_rows, folds) -> dict:
    """Out-of-fold development scores and held-out scores of the classifier at one delay."""
    def table(trajs, rows):
        pairs = [snapshot(tr, delta_s, window_s, push_inputs(rows[tr.trajectory_id]) if rows else None)
                 for tr in trajs]
        return np.array([p[0] for p in pairs], float), np.array([p[1] for p in pairs])
    x_dev, gone_dev = table(dev, push_rows and push_rows[0])
    x_test, gone_test = table(test, push_rows and push_rows[1])
    y_dev = np.array([tr.fallen for tr in dev])
    oof = np.zeros(len(dev))
    for held in folds:
        train = np.setdiff1d(np.arange(len(dev)), held)
        oof[held] = classifier().fit(x_dev[train], y_dev[train]).predict_proba(x_dev[held])[:, 1]
    held_out = classifier().fit(x_dev, y_dev).predict_proba(x_test)[:, 1]
    return {'delta_s': delta_s, 'dev': oof, 'test': held_out, 'gone_dev': gone_dev,
            'gone_test': gone_test}


def schedule(per_delta: list[dict], fallen_dev: np.ndarray, k: int) -> dict[str, np.ndarray]:
    """Per set, each trajectory's first alarm delay (inf: none), the per-delay threshold letting
    ``k`` development false alarms through."""
    first = {part: np.full(len(per_delta[0][part]), np.inf) for part in ('dev', 'test')}
    for row in per_delta:
        negatives = np.sort(row['dev'][~fallen_dev])
        threshold = negatives[-1 - k] + 1e-9 if k < len(negatives) else 0.0
        for part in first:
            alarm = (row[part] >= threshold) & ~row[f'gone_{part}']
            first[part] = np.where(alarm & np.isinf(first[part]), row['delta_s'], first[part])
    return first


def figures(first: np.ndarray, trajs) -> dict:
    fallen = np.array([tr.fallen for tr in trajs])
    to_fall = np.array([tr.t_fallen - tr.t_push if tr.fallen else np.nan for tr in trajs])
    fp, n = int((np.isfinite(first) & ~fallen).sum()), int((~fallen).sum())
    detected = np.isfinite(first) & fallen
    leads = to_fall[detected] - first[detected]
    oracle = float(np.nanmean(to_fall))
    low, high = wilson_interval(fp, n)
    lead_low, lead_high = bootstrap_mean_interval(leads)
    return {'false_alarms': fp, 'balanced': n, 'fpr': round(fp / n, 4),
            'fpr_wilson_95': [round(low, 4), round(high, 4)], 'falls': int(fallen.sum()),
            'detected': int(detected.sum()), 'missed': int(fallen.sum() - detected.sum()),
            'lead_s': round(float(leads.mean()), 3),
            'lead_bootstrap_95': [round(lead_low, 3), round(lead_high, 3)],
            'oracle_lead_s': round(oracle, 3), 'lead_over_oracle': round(float(leads.mean()) / oracle, 3)}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--data', type=Path, required=True, help='development dataset')
    parser.add_argument('--test', type=Path, required=True, help='held-out dataset')
    parser.add_argument('--folds', type=int, default=5)
    parser.add_argument('--max-delta', type=float, default=1.0, help='last delay after the onset [s]')
    parser.add_argument('--window', type=float, default=0.2, help='recent past summarised [s]')
    parser.add_argument('--push', action='store_true', help='the push itself among the inputs')
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    started = time.time()
    dev = load_dataset(args.data, state='estimated').trajectories
    test = load_dataset(args.test, state='estimated').trajectories
    push_rows = None
    if args.push:
        push_rows = [{r['trajectory_id']: r for r in csv.DictReader(open(d / 'index.csv'))}
                     for d in (args.data, args.test)]
    folds = stratified_trajectory_folds(dev, args.folds, seed=0)
    deltas = [round(0.1 + 0.05 * k, 2) for k in range(int(round((args.max_delta - 0.1) / 0.05)) + 1)]
    per_delta = []
    for delta_s in deltas:
        per_delta.append(scores_at(dev, test, delta_s, args.window, push_rows, folds))
        print(f'delay {delta_s:.2f} s done', flush=True)
    fallen_dev = np.array([tr.fallen for tr in dev])
    result = {'data': str(args.data), 'test': str(args.test), 'folds': args.folds,
              'deltas_s': deltas, 'window_s': args.window, 'push_inputs': args.push,
              'per_delay': [], 'schedules': {}}
    for row in per_delta:
        entry = {'delta_s': row['delta_s']}
        for k in (0, 1, 2):
            first = schedule([row], fallen_dev, k)
            entry[f'k{k}'] = {part: figures(first[part], trajs)
                              for part, trajs in (('dev', dev), ('test', test))}
        result['per_delay'].append(entry)
    for k in (0, 1, 2):
        first = schedule(per_delta, fallen_dev, k)
        result['schedules'][f'k{k}'] = {part: figures(first[part], trajs)
                                        for part, trajs in (('dev', dev), ('test', test))}
    result['seconds'] = round(time.time() - started, 1)
    text = json.dumps(result, indent=1)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')
    print(json.dumps(result['schedules'], indent=1))
    return result


if __name__ == '__main__':
    main()
