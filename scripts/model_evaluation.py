"""Write the shipped model's cross-validated evaluation (models/default_model.evaluation.json):
the sweep's point at the model's own (tau_plus, recommended tau_his), with the commands that made
the dataset, the sweep and the model.

    .venv/bin/python scripts/model_evaluation.py \
        --sweep docs/prediction/asimo_like/sweep_default_model/sweep.json \
        --model models/default_model.json --out models/default_model.evaluation.json
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from fall_predictor.monitor.model_file import load_model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sweep', type=Path, required=True)
    parser.add_argument('--model', type=Path, required=True)
    parser.add_argument('--out', type=Path, required=True)
    parser.add_argument('--dataset-command', default='fall-predictor generate --trajectories 1000 --seed 0 '
                                                    '--out data/d1000 --jobs 2')
    args = parser.parse_args()
    sweep = json.loads(args.sweep.read_text())
    _, metadata = load_model(args.model)
    tau_plus, tau_his = metadata.tau_plus_s, metadata.recommended_tau_his_s
    point = next((p for p in sweep['points']
                  if abs(p['tau_plus_s'] - tau_plus) < 1e-9 and abs(p['tau_his_s'] - tau_his) < 1e-9), None)
    if point is None:
        raise SystemExit(f'the sweep has no point at tau_plus {tau_plus}, tau_his {tau_his}')
    n = sweep['dataset']['n_trajectories']
    folds = sweep['settings']['folds']
    out = {
        'description': (f'Cross-validated evaluation ({folds}-fold by trajectory, {n} trajectories) of the '
                        f'settings of {args.model}: each fold trains on {round(point["n_train"])} trajectories '
                        f'with these settings and is evaluated on the other {n - round(point["n_train"])} at tau_his = {tau_his} s. '
                        f'The shipped model itself is then trained on all {n}.'),
        'model_command': f'fall-predictor train --data data/d1000s {"--mirror " if metadata.mirror else ""}'
                         f'--tau-plus={tau_plus} --tau-his-recommended {tau_his} --out {args.model} --jobs 2',
        'dataset_command': args.dataset_command,
        'evaluation_command': sweep['command'],
        'dataset_fingerprint': sweep['dataset']['fingerprint'],
        'tau_plus_s': tau_plus, 'tau_his_s': tau_his,
        'cross_validated': point,
    }
    args.out.write_text(json.dumps(out, indent=1, sort_keys=True) + '\n')
    print(args.out)


if __name__ == '__main__':
    main()
