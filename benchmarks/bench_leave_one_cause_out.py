"""Does a model catch the falls of a cause it never trained on? A leave-one-cause-out study
(method §5 "Per cause").

On the development data (``--data``: runs of several causes, ``generate --causes``), one model is
trained per variant, every variant with the same learner and run-time settings (``--model``: a
model file's learner, tau_plus, mirror, attitude, decision threshold and history window, so the
variants differ only in the runs they saw):

* ``all causes``: every development run (the shipped model's training set);
* ``without <cause>``: every development run but that cause's (trips, slips, steps, faults);
* ``pushes only``: the development pushes alone (a model made as models were before causes).

Each is evaluated held out (``--test``, another seed's runs of every cause) per cause with
:func:`~fall_predictor.learning.deployment.cause_figures` (falls caught, FPR with its Wilson
interval, alarms before the onset, lead and lead / onset-to-fall), the column a reader looks at
being the left-out cause. Writes JSON (``--out``):

    .venv/bin/python benchmarks/bench_leave_one_cause_out.py --data data/g1pol_mix_dev1000 \\
        --test data/g1pol_mix_test600 --model models/g1_unitree_rl_model.json \\
        --out docs/prediction/g1_unitree_rl/leave_one_cause_out.json
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, Mapping, Sequence

from fall_predictor.data.dataset import CAUSE_PUSH, read_index
from fall_predictor.learning.deployment import cause_figures, run_outcomes
from fall_predictor.learning.metrics import evaluate_atomic
from fall_predictor.learning.run_groups import RunDisturbance, disturbances
from fall_predictor.learning.training import (fit_strided, load_training_data, make_learner,
                                              model_inputs)
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import TrajectoryFeatures

sys.path.insert(0, str(Path(__file__).resolve().parent))
from portable_paths import portable_path as portable, write_json  # noqa: E402

LEARNERS = {'BoostedTreesLearner': 'boosting', 'DecisionTreeLearner': 'tree',
            'CoveringLearner': 'covering'}


def runs_of(data) -> dict[str, RunDisturbance]:
    """Each trajectory's disturbance, by the trajectory id the loaded data uses."""
    runs: dict[str, RunDisturbance] = {}
    for part in data.parts:
        runs.update(disturbances(read_index(part.data_dir), part.prefix))
    return runs


def cause_of(traj: TrajectoryFeatures, runs: Mapping[str, RunDisturbance]) -> str:
    run = runs.get(traj.trajectory_id)
    return run.cause if run is not None else CAUSE_PUSH


def per_cause(model, test: Sequence[TrajectoryFeatures], runs, threshold: float, tau_his_s: float,
              guard_m: float) -> dict[str, Any]:
    """The held-out figures of one model per cause and over every run."""
    atomic = [model.score(t.X, t.mode) > threshold for t in test]
    result = evaluate_atomic(test, atomic, (tau_his_s,), guard_com_height_m=guard_m,
                             keep_alarms=True)[tau_his_s]
    outcomes = run_outcomes(test, result.alarms, runs)
    causes = sorted({o.cause for o in outcomes})
    return {'all_runs': cause_figures(outcomes),
            **{cause: cause_figures([o for o in outcomes if o.cause == cause]) for cause in causes}}


def settings_of(model_path: Path) -> dict[str, Any]:
    """The learner and settings a model file was trained and runs with (its decision threshold
    the one it runs with, which ``train`` may have chosen by cross-validation)."""
    lists, metadata = load_model(model_path)
    doc = json.loads(model_path.read_text())
    threshold = lists.decision_threshold
    return {'learner': LEARNERS[metadata.learner_name], 'params': dict(metadata.learner_params),
            'decision_threshold': float(threshold if threshold is not None else 0.0),
            'tau_plus_s': float(metadata.tau_plus_s), 'mirror': bool(doc['training'].get('mirror')),
            'attitude': 'base_roll' in doc.get('input_names', ()),
            'tau_his_s': float(metadata.recommended_tau_his_s),
            'state': doc['training'].get('state', 'estimated')}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--data', type=Path, required=True, help='development data')
    parser.add_argument('--test', type=Path, required=True, help='held-out data (another seed)')
    parser.add_argument('--model', type=Path, required=True,
                        help='the model file whose learner and settings every variant takes')
    parser.add_argument('--jobs', type=int, default=1)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    settings = settings_of(args.model)   # load_model refuses a file that is not a model
    data = load_training_data(args.data, jobs=args.jobs, state=settings['state'])
    dev = model_inputs(data.report.trajectories, settings['attitude'])
    dev_runs = runs_of(data)
    test_data = load_training_data(args.test, jobs=args.jobs, state=settings['state'])
    test = model_inputs(test_data.report.trajectories, settings['attitude'])
    test_runs = runs_of(test_data)
    causes = sorted({cause_of(t, dev_runs) for t in dev})
    variants: dict[str, list[TrajectoryFeatures]] = {'all causes': dev}
    for cause in causes:
        if cause != CAUSE_PUSH:
            variants[f'without {cause}'] = [t for t in dev if cause_of(t, dev_runs) != cause]
    variants['pushes only'] = [t for t in dev if cause_of(t, dev_runs) == CAUSE_PUSH]
    out_variants: dict[str, Any] = {}
    for name, trajs in variants.items():
        learner = make_learner(settings['learner'], settings['params'])
        model = fit_strided(trajs, settings['tau_plus_s'], learner, mirror=settings['mirror'])
        figures = per_cause(model, test, test_runs, settings['decision_threshold'],
                            settings['tau_his_s'], test_data.guard_com_height_m)
        out_variants[name] = {'n_train': len(trajs),
                              'n_train_fallen': sum(bool(t.fallen) for t in trajs),
                              'held_out': figures}
        print(name, json.dumps({c: (f['falls_caught'], f['fpr']) for c, f in figures.items()}),
              flush=True)
    out = {'data': portable(args.data), 'test': portable(args.test),
           'model': portable(args.model), 'settings': settings,
           'n_dev': len(dev), 'n_test': len(test),
           'n_test_by_cause': {c: sum(cause_of(t, test_runs) == c for t in test)
                               for c in sorted({cause_of(t, test_runs) for t in test})},
           'variants': out_variants,
           'command': ' '.join(['benchmarks/bench_leave_one_cause_out.py', *(argv or sys.argv[1:])])}
    if args.out:
        write_json(args.out, out)       # every machine path made portable
    return out


if __name__ == '__main__':
    main()
