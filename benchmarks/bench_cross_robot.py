"""Across robots: does a model learned on one humanoid predict the falls of another, with the
features as they are (metres, kilograms) and made dimensionless by each robot's size and mass?

For each (train, test) pair of datasets (estimated state), the decision lists are trained at one
operating point (tau_plus, tau_his) and evaluated on the test dataset, with

- ``raw`` features, the CoM guard of the test dataset's robot (its profile's: 0.48 m for the
  ASIMO-like robot, 0.55 m for the G1), the robot the lists are asked to watch;
- ``dimensionless`` features: lengths over the robot's standing CoM height L (the median CoM
  height over each dataset's first 0.5 s), linear momentum over M sqrt(g L), angular momentum
  over M L sqrt(g L), their rates over M g and M g L (M: the robot's mass), the guard at
  0.48 / 0.589 of L (the ASIMO-like robot's ratio). Contact modes are dimensionless already.

    .venv/bin/python benchmarks/bench_cross_robot.py \\
        --dataset asimo=data/asimo_test100 --dataset g1=data/g1_dev1000 --dataset g1_test=data/g1_test400 \\
        --pair asimo:g1_test --pair g1:asimo --pair g1:g1_test --pair asimo+g1:g1_test \\
        --out docs/prediction/g1_c_bal/cross_robot.json
"""
from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from fall_predictor.data.dataset import dataset_guard_com_height_m, robot_total_mass_kg
from fall_predictor.learning.metrics import evaluate_lists
from fall_predictor.learning.training import fit_strided, load_dataset, make_learner
from fall_predictor.monitor.records import GUARD_COM_HEIGHT_M

G = 9.81
#: The guard as a fraction of the standing CoM height (the ASIMO-like robot's 0.48 m of 0.589 m).
GUARD_FRACTION = GUARD_COM_HEIGHT_M / 0.589


def standing_com_height_m(trajectories) -> float:
    return float(np.median(np.concatenate([t.X[t.t <= t.t[0] + 0.5, 2] for t in trajectories])))


def dimensionless(trajectories, length_m: float, mass_kg: float):
    v = math.sqrt(G * length_m)
    scale = np.array([length_m] * 3 + [mass_kg * v] * 3 + [mass_kg * length_m * v] * 3
                     + [mass_kg * G] * 3 + [mass_kg * G * length_m] * 3)
    return [replace(t, X=t.X / scale) for t in trajectories]


def summary(result) -> dict:
    return {'fpr': result.fpr, 'fpr_ci95': list(result.fpr_ci95), 'tau_lead_s': result.tau_lead_s,
            'tau_lead_ci95': list(result.tau_lead_ci95), 'lead_fraction': result.lead_fraction,
            'misses': result.n_missed, 'misses_lists_only': result.n_missed_lists_only,
            'n_balanced': result.n_balanced, 'n_fallen': result.n_fallen}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--dataset', action='append', required=True, metavar='NAME=DIR')
    parser.add_argument('--pair', action='append', required=True, metavar='TRAIN[+TRAIN]:TEST')
    parser.add_argument('--tau-plus', type=float, default=-0.25)
    parser.add_argument('--tau-his', type=float, default=0.06)
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, required=True)
    args = parser.parse_args()
    data = {}
    for item in args.dataset:
        name, folder = item.split('=', 1)
        trajs = load_dataset(folder, jobs=args.jobs, state='estimated').trajectories
        length = standing_com_height_m(trajs)
        mass = robot_total_mass_kg(folder)
        data[name] = {'raw': trajs, 'dimensionless': dimensionless(trajs, length, mass),
                      'length_m': length, 'mass_kg': mass, 'dir': folder,
                      'guard_m': dataset_guard_com_height_m(folder)}
    results = []
    for pair in args.pair:
        train_names, test_name = pair.split(':')
        test = data[test_name]
        row = {'train': train_names, 'test': test_name}
        for kind in ('raw', 'dimensionless'):
            train = [t for name in train_names.split('+') for t in data[name][kind]]
            lists = fit_strided(train, args.tau_plus, make_learner('tree'))
            guard = test['guard_m'] if kind == 'raw' else GUARD_FRACTION
            result = evaluate_lists(test[kind], lists, (args.tau_his,), guard_com_height_m=guard)[args.tau_his]
            row[kind] = summary(result)
        results.append(row)
        print(json.dumps(row), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({
        'tau_plus_s': args.tau_plus, 'tau_his_s': args.tau_his,
        'datasets': {n: {'dir': d['dir'], 'standing_com_height_m': d['length_m'], 'mass_kg': d['mass_kg'],
                         'guard_com_height_m': d['guard_m'], 'trajectories': len(d['raw'])}
                     for n, d in data.items()},
        'results': results}, indent=1) + '\n')


if __name__ == '__main__':
    main()
