"""The hand-coded baselines on a held-out dataset, their thresholds and tau_his chosen on the
development dataset as the learned lists' settings are (method §11): for each FPR budget, the
(threshold, tau_his) with the longest lead at development FPR <= budget (else the lowest FPR),
then reported once on the test dataset with Wilson / bootstrap intervals (budgets 0, 0.01, 0.06).
As ``train`` does (method §11 "A budget that holds"), the budget is checked on the one-sided
Wilson upper bound of the development FPR (``--fpr-rule ucb``, ``--fpr-level``); ``point``
checks the development FPR itself, as the results made before this rule were.
Beside them, model files evaluated on the same test set (``--model FILE`` at its recommended
tau_his, ``--model FILE@TAU_HIS`` at another). The baselines run with the CoM guard of each
dataset's robot, a model with the guard it records (as ``fall-predictor evaluate``).

    .venv/bin/python benchmarks/bench_heldout_baselines.py --dev data/g1_dev1000 \\
        --test data/g1_test1000_5050 --model models/g1_attitude_model.json \\
        --out docs/prediction/g1_c_bal/heldout/baselines.json
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from fall_predictor.data.dataset import dataset_guard_com_height_m
from fall_predictor.learning.evaluation import (BaselineGrids, capture_point_distances_cached,
                                                evaluation_result_json)
from fall_predictor.learning.intervals import wilson_upper_bound
from fall_predictor.learning.metrics import evaluate_atomic, evaluate_lists
from fall_predictor.learning.tilt_detector import imu_signals_cached, threshold_grid, tilt_alarms
from fall_predictor.learning.training import load_dataset, model_inputs
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import FEATURE_NAMES

TAU_HIS_S = (0.0, 0.016, 0.044, 0.06, 0.1)
BUDGETS = (0.0, 0.01, 0.06)
COM_Z, PX, PY = (FEATURE_NAMES.index(n) for n in ('com_z', 'lin_mom_x', 'lin_mom_y'))


def baselines(trajs, capture, imu, grids: BaselineGrids) -> dict:
    """name -> (thresholds, atomic(i, threshold))."""
    return {
        'com_height': ([float(h) for h in grids.com_height_m], lambda i, h: trajs[i].X[:, COM_Z] < h),
        'momentum': ([(float(a), float(b)) for a in grids.momentum_sagittal for b in grids.momentum_frontal],
                     lambda i, ab: (np.abs(trajs[i].X[:, PX]) > ab[0]) | (np.abs(trajs[i].X[:, PY]) > ab[1])),
        'capture_point': ([float(m) for m in grids.capture_point_margin_m],
                          lambda i, m: np.asarray(capture[i]) > -m),
        'imu_tilt': (threshold_grid(), lambda i, th: tilt_alarms(imu[i], *th)),
    }


def grid(trajs, thresholds, atomic_for, guard_m: float) -> list:
    """(threshold, tau_his, result) for every point of the grid, CoM guard at ``guard_m``."""
    out = []
    for th in thresholds:
        atomic = [atomic_for(i, th) for i in range(len(trajs))]
        for tau_his, result in evaluate_atomic(trajs, atomic, TAU_HIS_S, 0.001, guard_m).items():
            out.append((th, tau_his, result))
    return out


def choose(points, budget: float, rule: str = 'ucb', level: float = 0.95):
    """The longest development lead whose FPR (by ``rule``: the FPR or its upper bound) is within
    ``budget``; else the lowest such FPR (:func:`~fall_predictor.learning.nested.choose_setting`)."""
    def fpr(p) -> float:
        return p[2].fpr if rule == 'point' else wilson_upper_bound(p[2].n_false_positives,
                                                                    p[2].n_balanced, level)
    ok = [p for p in points if fpr(p) <= budget + 1e-12]
    return (max(ok, key=lambda p: p[2].tau_lead_s) if ok
            else min(points, key=lambda p: (fpr(p), -p[2].tau_lead_s)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--dev', type=Path, required=True)
    parser.add_argument('--test', type=Path, required=True)
    parser.add_argument('--model', action='append', default=[],
                        help='model file, or FILE@TAU_HIS (repeatable)')
    parser.add_argument('--budgets', type=lambda s: tuple(float(v) for v in s.split(',')),
                        default=BUDGETS, help=f'FPR budgets (default {BUDGETS})')
    parser.add_argument('--fpr-rule', choices=('ucb', 'point'), default='ucb',
                        help='the budget checked on the development FPR\'s one-sided Wilson upper '
                             'bound (ucb) or on the FPR itself (point)')
    parser.add_argument('--fpr-level', type=float, default=0.95, help='level of the ucb rule\'s bound')
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, required=True)
    args = parser.parse_args()
    sets, guards = {}, {}
    for name, folder in (('dev', args.dev), ('test', args.test)):
        trajs = load_dataset(folder, jobs=args.jobs, state='estimated').trajectories
        capture = capture_point_distances_cached(folder, trajs, jobs=args.jobs, state='estimated')
        imu = imu_signals_cached(folder, trajs, jobs=args.jobs)
        sets[name] = baselines(trajs, capture, imu, BaselineGrids.coarse()), trajs
        guards[name] = dataset_guard_com_height_m(folder)
    results = {'dev': str(args.dev), 'test': str(args.test), 'tau_his_grid_s': TAU_HIS_S,
               'fpr_rule': args.fpr_rule, 'fpr_level': args.fpr_level,
               'guard_com_height_m': guards, 'baselines': [], 'models': []}
    for name in sets['dev'][0]:
        dev_points = grid(sets['dev'][1], *sets['dev'][0][name], guards['dev'])
        test_thresholds, test_atomic = sets['test'][0][name]
        for budget in args.budgets:
            th, tau_his, dev_result = choose(dev_points, budget, args.fpr_rule, args.fpr_level)
            atomic = [test_atomic(i, th) for i in range(len(sets['test'][1]))]
            test_result = evaluate_atomic(sets['test'][1], atomic, (tau_his,), 0.001,
                                          guards['test'])[tau_his]
            row = {'baseline': name, 'fpr_budget': budget, 'threshold': th, 'tau_his_s': tau_his,
                   'dev': {'fpr': dev_result.fpr, 'tau_lead_s': dev_result.tau_lead_s},
                   'test': evaluation_result_json(test_result)}
            results['baselines'].append(row)
            print(name, budget, th, tau_his, round(test_result.fpr, 3), round(test_result.tau_lead_s, 3), flush=True)
    for spec in args.model:
        # PATH, or PATH@TAU_HIS for a history window other than the model's recommended one.
        path, _, window = str(spec).partition('@')
        lists, metadata = load_model(path)
        tau_his = float(window) if window else (metadata.recommended_tau_his_s or 0.06)
        guard = metadata.feature_settings.guard_com_height_m
        result = evaluate_lists(model_inputs(sets['test'][1], lists.reads_attitude), lists, (tau_his,),
                                guard_com_height_m=guard)[tau_his]     # (a model's inputs)
        results['models'].append({'model': path, 'tau_his_s': tau_his, 'guard_com_height_m': guard,
                                  'test': evaluation_result_json(result)})
        print(spec, round(result.fpr, 3), round(result.tau_lead_s, 3), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1, default=str) + '\n')


if __name__ == '__main__':
    main()
