#!/usr/bin/env python3
"""The held-out test set: the shipped model and the baselines, every operating point chosen on
the development data, evaluated once on a large dataset of a seed used for nothing else.

Operating points, all read from the development dataset's sweep (``--sweep``: the sweep.json of
``fall-predictor sweep`` on the data the shipped model was trained on):

* **learned**: the shipped model's lists (trained on all the development data at its tau_plus)
  at its recommended tau_his (FP-L2's settings), and, for each FPR budget, at the tau_his with the
  longest cross-validated lead among the sweep's points at the model's tau_plus whose
  cross-validated FPR is within the budget (else the lowest FPR);
* **baselines** (CoM height, momentum, capture point, IMU tilt): for each budget, the threshold and
  tau_his the sweep's nested baselines selected on all the development folds.

Each is evaluated once on ``--test`` (estimated state): FPR with its Wilson interval, lead with its
bootstrap interval, misses, oracle lead and lead fraction. Writes JSON (``--out``) and prints a
Markdown table.

    python benchmarks/bench_test_set.py --test data/t1000s_2026 --sweep docs/sweep/sweep.json \\
        --model models/default_model.json --out docs/test_set_t1000.json
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from fall_predictor.learning.evaluation import capture_point_distances_cached, evaluation_result_json
from fall_predictor.learning.metrics import evaluate_atomic, evaluate_lists
from fall_predictor.learning.tilt_detector import imu_signals_cached, tilt_alarms
from fall_predictor.learning.training import load_dataset
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import FEATURE_NAMES

BUDGETS = (0.0, 0.005, 0.01, 0.06)
COM_Z, PX, PY = (FEATURE_NAMES.index(n) for n in ('com_z', 'lin_mom_x', 'lin_mom_y'))
KEEP = ('n_balanced', 'n_fallen', 'n_false_positives', 'fpr', 'fpr_ci95', 'tau_lead_s',
        'tau_lead_ci95', 'n_missed', 'oracle_lead_s', 'lead_fraction', 'n_pre_push_alarms_balanced')


def _number(value) -> float:
    return math.inf if value is None else float(value)       # JSON wrote inf as null


def baseline_atomic(name: str, threshold, trajs, capture, imu):
    """Per trajectory, the baseline's per-sample alarm (before tau_his and the guard)."""
    if name == 'com_height':
        return [t.X[:, COM_Z] < float(threshold) for t in trajs]
    if name == 'momentum':
        a, b = (_number(v) for v in threshold)
        return [(np.abs(t.X[:, PX]) > a) | (np.abs(t.X[:, PY]) > b) for t in trajs]
    if name == 'capture_point':
        return [np.asarray(d) > -float(threshold) for d in capture]
    if name == 'imu_tilt':
        return [tilt_alarms(s, *threshold) for s in imu]
    raise ValueError(f'unknown baseline {name!r}')


def chosen_tau_his(points: list, tau_plus_s: float, budget: float) -> dict:
    """The sweep's point at ``tau_plus_s`` with the longest CV lead within the FPR budget (else the
    lowest CV FPR)."""
    row = [p for p in points if abs(p['tau_plus_s'] - tau_plus_s) < 1e-9]
    ok = [p for p in row if p['fpr'] <= budget + 1e-12]
    return max(ok, key=lambda p: p['tau_lead_s']) if ok else min(row, key=lambda p: p['fpr'])


def short(result) -> dict:
    payload = evaluation_result_json(result)
    return {k: payload[k] for k in KEEP if k in payload}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--test', type=Path, required=True)
    parser.add_argument('--sweep', type=Path, required=True, help="the development data's sweep.json")
    parser.add_argument('--model', type=Path, required=True)
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    sweep = json.loads(args.sweep.read_text())
    lists, metadata = load_model(args.model)
    guard = metadata.feature_settings.guard_com_height_m
    trajs = load_dataset(args.test, jobs=args.jobs, state='estimated').trajectories
    rows = []

    def add(kind: str, name: str, budget, settings: dict, result, dev: dict) -> None:
        rows.append({'kind': kind, 'name': name, 'fpr_budget': budget, 'settings': settings,
                     'development': dev, 'test': short(result)})
        print(kind, name, budget, settings, round(result.fpr, 4), round(result.tau_lead_s, 3), flush=True)

    tau_his = metadata.recommended_tau_his_s or 0.0
    fixed = next(p for p in sweep['points'] if abs(p['tau_plus_s'] - metadata.tau_plus_s) < 1e-9
                 and abs(p['tau_his_s'] - tau_his) < 1e-9)
    add('learned', 'shipped model, FP-L2 settings', None,
        {'tau_plus_s': metadata.tau_plus_s, 'tau_his_s': tau_his},
        evaluate_lists(trajs, lists, (tau_his,), guard_com_height_m=guard)[tau_his],
        {'cv_fpr': fixed['fpr'], 'cv_tau_lead_s': fixed['tau_lead_s']})
    for budget in BUDGETS:
        point = chosen_tau_his(sweep['points'], metadata.tau_plus_s, budget)
        h = point['tau_his_s']
        add('learned', 'shipped model, tau_his chosen on the development CV', budget,
            {'tau_plus_s': metadata.tau_plus_s, 'tau_his_s': h},
            evaluate_lists(trajs, lists, (h,), guard_com_height_m=guard)[h],
            {'cv_fpr': point['fpr'], 'cv_tau_lead_s': point['tau_lead_s']})
    capture = capture_point_distances_cached(args.test, trajs, jobs=args.jobs, state='estimated')
    imu = imu_signals_cached(args.test, trajs, jobs=args.jobs)
    for name, choices in sweep['baselines_nested'].items():
        for choice in choices:
            selected = choice['selected_in_hindsight']
            atomic = baseline_atomic(name, selected['threshold'], trajs, capture, imu)
            h = float(selected['tau_his_s'])
            result = evaluate_atomic(trajs, atomic, (h,), 0.001, guard)[h]
            add('baseline', name, choice['max_fpr'], selected, result,
                {'fpr': choice['hindsight']['fpr'], 'tau_lead_s': choice['hindsight']['tau_lead_s']})
    out = {'test': str(args.test), 'sweep': str(args.sweep), 'model': str(args.model),
           'guard_com_height_m': guard, 'n_trajectories': len(trajs), 'rows': rows}
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(out, indent=1, default=float) + '\n')
    print('| predictor | FPR budget (dev) | settings | dev FPR / lead | test FPR [Wilson 95 %] | '
          'test lead [s] [95 %] | misses | lead fraction |')
    print('|---|---|---|---|---|---|---|---|')
    for r in rows:
        t, d = r['test'], r['development']
        dev = (d.get('cv_fpr', d.get('fpr')), d.get('cv_tau_lead_s', d.get('tau_lead_s')))
        print(f"| {r['name']} | {r['fpr_budget']} | {r['settings']} | {dev[0]:.3f} / {dev[1]:.2f} | "
              f"{t['n_false_positives']}/{t['n_balanced']} = {t['fpr']:.3f} "
              f"[{t['fpr_ci95'][0]:.3f}, {t['fpr_ci95'][1]:.3f}] | {t['tau_lead_s']:.2f} "
              f"[{t['tau_lead_ci95'][0]:.2f}, {t['tau_lead_ci95'][1]:.2f}] | {t['n_missed']} | "
              f"{t['lead_fraction']:.2f} |")
    return out


if __name__ == '__main__':
    main()
