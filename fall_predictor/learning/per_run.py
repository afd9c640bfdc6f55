"""``evaluate --per-run``: one row per run (trajectory) of what the monitor's alarm did on it.

A team evaluating a model on its robot's recordings needs to see which runs alarmed and whether
an alarm came while the robot was only walking, not only the rates over all runs. Each row comes
from the very alarm records the summary is computed from
(:attr:`~fall_predictor.learning.metrics.EvaluationResult.alarms`: the ``tau_his``-windowed
prediction with the CoM guard, as ``evaluate`` runs it), with method §5's definitions
(:mod:`fall_predictor.learning.metrics`):

* ``first_alarm_s``: the first falling output anywhere; ``first_alarm_after_push_s`` the first
  at or after the push (``t_predict``);
* ``lead_s`` on a fallen run alarmed in time: ``t_fallen - t_predict``; ``missed`` when no alarm
  came in ``[t_push, t_fallen)`` (the summary counts its lead 0);
* ``false_alarm`` on a run that did not fall: any falling output (it counts in the FPR);
* ``pre_push_alarm_onsets``: how many times the alarm turned on before the push, on either
  outcome (a run with any is one of the summary's pre-push false alarms).

* ``cause``: what disturbed the run (the index's; a push in datasets made before causes
  existed), whose onset the push columns hold; ``alarm_onsets``: the alarm episodes anywhere
  on the run (on a long walk, its false alarms).

Times are the recording's own stamp times [s] (simulation time in generated datasets, ROS time on
a robot). A run whose push time is unknown (a robot's recording imported without one: its
``t_push`` is the recording's start) has an empty push time and no pre-push count: every alarm
on it counts from its start. ``refused_samples`` counts the samples left out of it as holes
(:mod:`fall_predictor.data.dataset`).

The file is CSV, or JSON when its name ends in ``.json`` (``{"format", ..., "runs": [...]}``).
"""
from __future__ import annotations

import csv
import json
import math
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

from fall_predictor.data.dataset import RefusedSamples
from fall_predictor.learning.metrics import TrajectoryAlarms
from fall_predictor.monitor.fileio import atomic_output
from fall_predictor.monitor.records import TrajectoryFeatures

FORMAT = 'fall_predictor/per-run/v1'


@dataclass(frozen=True)
class RunRecord:
    """One run of an evaluation (module docs; times [s], None where not applicable)."""

    trajectory_id: str
    fallen: bool
    push_source: str                            #: where t_push comes from; 'unknown' if nowhere
    t_push_s: Optional[float]                   #: None when the push time is unknown
    t_fallen_s: Optional[float]
    first_alarm_s: Optional[float]
    first_alarm_after_push_s: Optional[float]
    lead_s: Optional[float]                     #: fallen runs alarmed in time
    missed: Optional[bool]                      #: fallen runs: no alarm in [t_push, t_fallen)
    false_alarm: Optional[bool]                 #: runs that did not fall: any alarm
    pre_push_alarm_onsets: Optional[int]        #: None when the push time is unknown
    refused_samples: int
    #: what disturbed the run (push, trip, slip, step, fault, walk: the index's ``cause``)
    cause: str = 'push'
    alarm_onsets: int = 0                       #: alarm episodes anywhere on the run


def run_records(trajectories: Sequence[TrajectoryFeatures], alarms: Sequence[TrajectoryAlarms],
                push_sources: Mapping[str, str],
                refused: Mapping[str, RefusedSamples],
                causes: Optional[Mapping[str, str]] = None) -> list[RunRecord]:
    """The rows of ``trajectories`` from their ``alarms`` (the evaluation's, in the same order).

    ``push_sources``: per trajectory id where its push time comes from, ``'unknown'`` for none
    (:func:`~fall_predictor.data.dataset.push_time_known`); ``refused``: its refused samples;
    ``causes``: its cause (none given: a push). For every cause the index keeps the onset in
    ``t_push``, so the push columns are the onset's.
    """
    if len(alarms) != len(trajectories):
        raise ValueError(f'{len(trajectories)} trajectories but {len(alarms)} alarm records')
    rows = []
    for traj, alarm in zip(trajectories, alarms):
        source = push_sources.get(traj.trajectory_id, 'unknown')
        known = source != 'unknown'
        t_predict = alarm.first_alarm_after_push_t
        lead = missed = false_alarm = None
        if traj.fallen:
            hit = t_predict is not None and traj.t_fallen is not None and t_predict < traj.t_fallen
            lead, missed = (traj.t_fallen - t_predict if hit else None), not hit
        else:
            false_alarm = alarm.first_alarm_t is not None
        holes = refused.get(traj.trajectory_id)
        rows.append(RunRecord(
            trajectory_id=traj.trajectory_id, fallen=bool(traj.fallen), push_source=source,
            t_push_s=float(traj.t_push) if known else None, t_fallen_s=traj.t_fallen,
            first_alarm_s=alarm.first_alarm_t, first_alarm_after_push_s=t_predict if known else None,
            lead_s=lead, missed=missed, false_alarm=false_alarm,
            pre_push_alarm_onsets=alarm.pre_push_onsets if known else None,
            refused_samples=0 if holes is None else holes.total,
            cause=(causes or {}).get(traj.trajectory_id, 'push'), alarm_onsets=alarm.alarm_onsets))
    return rows


def _json_value(value: Any) -> Any:
    """None for NaN and infinity; times to the microsecond, as in the CSV."""
    if isinstance(value, float):
        return round(value, 6) if math.isfinite(value) else None
    return value


def write_per_run(path: str | os.PathLike, records: Sequence[RunRecord],
                  context: Optional[Mapping[str, Any]] = None) -> Path:
    """Write ``records`` to ``path`` (atomically): CSV, or JSON with ``context`` (the model, the
    dataset, the window) when the name ends in ``.json``. Returns the path."""
    path = Path(path)
    names = [f.name for f in fields(RunRecord)]
    with atomic_output(path) as tmp:
        if path.suffix.lower() == '.json':
            document = {'format': FORMAT, **dict(context or {}),
                        'runs': [{k: _json_value(v) for k, v in asdict(r).items()} for r in records]}
            Path(tmp).write_text(json.dumps(document, indent=1, allow_nan=False) + '\n')
        else:
            with open(tmp, 'w', newline='') as f:
                writer = csv.DictWriter(f, fieldnames=names)
                writer.writeheader()
                for record in records:
                    writer.writerow({k: _csv_value(v) for k, v in asdict(record).items()})
    return path


def _csv_value(value: Any) -> Any:
    """Empty for None (not applicable), booleans as 0/1, times with microseconds."""
    if value is None:
        return ''
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, float):
        return '' if not math.isfinite(value) else f'{value:.6f}'
    return value

