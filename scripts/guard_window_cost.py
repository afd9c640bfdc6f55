"""What putting the CoM guard through the tau_his window costs, on a dataset.

Until the fault-injection work the CoM guard bypassed the history window: one sample with a low
CoM (a glitch) latched a fall. Now the guard needs the same confirmation as the decision lists.
This evaluates a model on a dataset both ways, at the model's recommended window and at a few
others, and writes the lead time, misses and FPR of each (in-sample for the shipped model,
trained on the same dataset: the point is the difference between the two rules, not the
absolute figures, which docs/results.md reports cross-validated).

    .venv/bin/python scripts/guard_window_cost.py --data data/d1000 \
        --model docs/prediction/asimo_like/plain_lists/plain_model.json --out docs/monitor/guard_window_cost.json
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from fall_predictor.data.dataset import load_features
from fall_predictor.learning.metrics import evaluate, trajectory_alarms
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.predictor import (falling_run_durations, guard_predictions,
                                              windowed_falling)
from fall_predictor.monitor.records import FALLING


def _summary(result) -> dict:
    return {'tau_lead_s': round(result.tau_lead_s, 4), 'n_missed': result.n_missed,
            'fpr': round(result.fpr, 4), 'n_false_positives': result.n_false_positives,
            'n_fallen': result.n_fallen, 'n_balanced': result.n_balanced}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--data', type=Path, required=True)
    parser.add_argument('--model', type=Path, required=True)
    parser.add_argument('--out', type=Path, required=True)
    parser.add_argument('--jobs', type=int, default=2)
    args = parser.parse_args()
    lists, metadata = load_model(args.model)
    report = load_features(args.data, jobs=args.jobs)
    trajectories = report.trajectories
    tau_values = sorted({0.0, 0.02, metadata.recommended_tau_his_s or 0.0, 0.1})
    rows = []
    prepared = []
    for traj in trajectories:
        atomic = lists.predict(traj.X, traj.mode) == FALLING
        guard = guard_predictions(traj.X, metadata.feature_settings.guard_com_height_m)  # the model's
        prepared.append((traj, falling_run_durations(traj.t, atomic),
                         falling_run_durations(traj.t, atomic | guard), guard))
    for tau in tau_values:
        bypass = [trajectory_alarms(tr.t, windowed_falling(lists_d, tau) | guard, tr.t_push)
                  for tr, lists_d, _, guard in prepared]
        windowed = [trajectory_alarms(tr.t, windowed_falling(both_d, tau), tr.t_push)
                    for tr, _, both_d, _ in prepared]
        old, new = evaluate(trajectories, bypass), evaluate(trajectories, windowed)
        rows.append({'tau_his_s': tau, 'guard_bypasses_window': _summary(old),
                     'guard_through_window': _summary(new),
                     'lead_cost_s': round(old.tau_lead_s - new.tau_lead_s, 4)
                     if math.isfinite(old.tau_lead_s) and math.isfinite(new.tau_lead_s) else None})
    out = {'command': f'scripts/guard_window_cost.py --data {args.data} --model {args.model}',
           'dataset_fingerprint': report.fingerprint, 'n_trajectories': len(trajectories),
           'model_tau_his_s': metadata.recommended_tau_his_s, 'rows': rows}
    args.out.write_text(json.dumps(out, indent=1) + '\n')
    print(json.dumps(out, indent=1))


if __name__ == '__main__':
    main()
