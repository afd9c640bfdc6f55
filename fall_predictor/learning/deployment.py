"""The figures a team reads before it lets the monitor switch its robot into a fall mode
(method §5 "Per cause"): per cause, per push impulse band, and per hour of undisturbed walking.

From the very alarm records ``evaluate`` computes its summary from
(:class:`~fall_predictor.learning.metrics.TrajectoryAlarms`: the windowed prediction with the
CoM guard) and each run's :class:`~fall_predictor.learning.run_groups.RunDisturbance`:

* **per cause**: falls caught (an alarm in ``[onset, t_fallen)``), FPR over the survived runs
  with its Wilson 95 % interval, runs alarmed before the onset, the lead (``t_fallen`` minus the
  first alarm at or after the onset; a miss counts 0) as a median with a bootstrap 95 % interval
  and as a mean, the time from the onset to the fall (median), and the lead as a fraction of it
  (median over the falls, a miss 0). Every run's alarms count from its onset, which the index
  keeps in ``t_push`` for every cause (:class:`~fall_predictor.data.dataset.IndexRow`).
* **false alarms per hour of undisturbed walking**: over the long walks that did not fall, the
  alarm episodes (the falling output turning on) over the hours the walks covered (each walk's
  recorded span), with the exact Poisson (Garwood) 95 % interval. A walk that fell is a fall
  like any other (caught or missed), not walking time.
* **pushes per impulse band**: FPR over the survived pushes per band of ``band_width_ns``
  [N s], and the ambiguous band (20-80 % of pushes fell, found from the data:
  :func:`~fall_predictor.learning.run_groups.ambiguous_band`) on its own line: the FPR of a
  budget moves with the share of such pushes in whatever sampler measures it.

A dataset without the cause columns reads as all pushes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Optional, Sequence

import numpy as np

from fall_predictor.data.dataset import CAUSE_PUSH, CAUSES
from fall_predictor.learning.intervals import (bootstrap_quantile_interval, garwood_interval,
                                               wilson_interval)
from fall_predictor.learning.metrics import TrajectoryAlarms
from fall_predictor.learning.run_groups import (UNKNOWN_PUSH, AmbiguousBand, RunDisturbance,
                                                ambiguous_band, is_walk)
from fall_predictor.monitor.records import TrajectoryFeatures

#: Impulse band width [N s] of the per-band FPR (``evaluate --band-width``).
DEFAULT_BAND_WIDTH_NS = 10.0
SECONDS_PER_HOUR = 3600.0


@dataclass(frozen=True)
class RunOutcome:
    """One run as the deployer's figures count it (times [s]; None where not applicable)."""

    trajectory_id: str
    disturbance: RunDisturbance
    fallen: bool
    caught: Optional[bool]              #: fallen runs: an alarm in [onset, t_fallen)
    lead_s: Optional[float]             #: fallen runs: t_fallen - first alarm at or after onset; 0 if missed
    onset_to_fall_s: Optional[float]    #: fallen runs with an onset
    false_alarm: Optional[bool]         #: survived runs: any alarm
    alarm_before_onset: Optional[bool]  #: runs with an onset (disturbed runs)
    alarm_episodes: int                 #: the falling output turning on, anywhere
    duration_s: float                   #: the recorded span

    @property
    def cause(self) -> str:
        return self.disturbance.cause


def run_outcomes(trajectories: Sequence[TrajectoryFeatures], alarms: Sequence[TrajectoryAlarms],
                 runs: Mapping[str, RunDisturbance]) -> list[RunOutcome]:
    """The outcome of each trajectory from its alarms (the evaluation's, same order) and its
    disturbance (``runs`` by trajectory id; a trajectory missing there is a push)."""
    if len(trajectories) != len(alarms):
        raise ValueError(f'{len(trajectories)} trajectories but {len(alarms)} alarm records')
    out = []
    for traj, alarm in zip(trajectories, alarms):
        run = runs.get(traj.trajectory_id, UNKNOWN_PUSH)
        walk = is_walk(run)
        onset = None if walk else (run.onset_s if run.onset_s is not None else float(traj.t_push))
        caught = lead = onset_to_fall = false_alarm = None
        if traj.fallen:
            t_predict = alarm.first_alarm_after_push_t
            caught = t_predict is not None and t_predict < traj.t_fallen
            lead = traj.t_fallen - t_predict if caught else 0.0
            start = onset if onset is not None else float(traj.t[0])
            onset_to_fall = traj.t_fallen - start
        else:
            false_alarm = alarm.first_alarm_t is not None
        out.append(RunOutcome(
            traj.trajectory_id, run, bool(traj.fallen), caught, lead, onset_to_fall, false_alarm,
            None if walk else bool(alarm.pre_push_alarm), int(alarm.alarm_onsets),
            float(traj.t[-1] - traj.t[0]) if traj.t.size else 0.0))
    return out


def _rate(k: int, n: int) -> dict[str, Any]:
    return {'k': k, 'n': n, 'rate': k / n if n else None,
            'ci95': list(wilson_interval(k, n)) if n else None}


def _median(values: Sequence[float]) -> Optional[float]:
    return float(np.median(values)) if len(values) else None


def _interval(values: Sequence[float]) -> Optional[list[float]]:
    return list(bootstrap_quantile_interval(values, 0.5)) if len(values) else None


def cause_figures(outcomes: Sequence[RunOutcome]) -> dict[str, Any]:
    """The figures of one set of runs (module docs: falls caught, FPR, alarms before the onset,
    lead, onset to fall, lead fraction)."""
    falls = [o for o in outcomes if o.fallen]
    survived = [o for o in outcomes if not o.fallen]
    leads = [o.lead_s for o in falls]
    fractions = [o.lead_s / o.onset_to_fall_s for o in falls
                 if o.onset_to_fall_s is not None and o.onset_to_fall_s > 0.0]
    disturbed = [o for o in outcomes if o.alarm_before_onset is not None]
    return {
        'n_runs': len(outcomes), 'n_fallen': len(falls), 'n_survived': len(survived),
        'falls_caught': _rate(sum(bool(o.caught) for o in falls), len(falls)),
        'fpr': _rate(sum(bool(o.false_alarm) for o in survived), len(survived)),
        'alarms_before_onset': {'k': sum(bool(o.alarm_before_onset) for o in disturbed),
                                'n': len(disturbed)},
        'lead_median_s': _median(leads), 'lead_median_ci95': _interval(leads),
        'lead_mean_s': float(np.mean(leads)) if leads else None,
        'onset_to_fall_median_s': _median([o.onset_to_fall_s for o in falls
                                           if o.onset_to_fall_s is not None]),
        'lead_fraction_median': _median(fractions),
        'lead_fraction_median_ci95': _interval(fractions)}


def walking_false_alarms(outcomes: Sequence[RunOutcome]) -> Optional[dict[str, Any]]:
    """False alarm episodes per hour over the long walks that did not fall, with the Garwood
    95 % interval; None when there are no such walks."""
    walks = [o for o in outcomes if is_walk(o.disturbance) and not o.fallen]
    if not walks:
        return None
    episodes = sum(o.alarm_episodes for o in walks)
    hours = sum(o.duration_s for o in walks) / SECONDS_PER_HOUR
    low, high = garwood_interval(episodes, hours)
    return {'n_walks': len(walks), 'hours': hours, 'alarm_episodes': episodes,
            'walks_alarmed': sum(bool(o.false_alarm) for o in walks),
            'per_hour': episodes / hours if hours > 0 else None,
            'per_hour_ci95': None if math.isnan(high) else [low, high], 'interval': 'Garwood'}


def impulse_band_figures(pushes: Sequence[RunOutcome], band_width_ns: float
                         ) -> list[dict[str, Any]]:
    """Per impulse band of ``band_width_ns`` [N s] from 0 (those holding pushes): the pushes,
    their fall fraction, and the FPR over the survived ones with its Wilson interval."""
    if not (math.isfinite(band_width_ns) and band_width_ns > 0.0):
        raise ValueError(f'band_width_ns must be finite and > 0, got {band_width_ns!r}')
    by_band: dict[int, list[RunOutcome]] = {}
    for o in pushes:
        if o.disturbance.impulse_ns is not None:
            by_band.setdefault(int(o.disturbance.impulse_ns // band_width_ns), []).append(o)
    out = []
    for k in sorted(by_band):
        runs = by_band[k]
        survived = [o for o in runs if not o.fallen]
        out.append({'low_ns': k * band_width_ns, 'high_ns': (k + 1) * band_width_ns,
                    'n_pushes': len(runs), 'fall_fraction': sum(o.fallen for o in runs) / len(runs),
                    'fpr': _rate(sum(bool(o.false_alarm) for o in survived), len(survived))})
    return out


def ambiguous_band_figures(pushes: Sequence[RunOutcome]) -> Optional[dict[str, Any]]:
    """The ambiguous band found from these pushes and the figures of the pushes in it."""
    sized = [o for o in pushes if o.disturbance.impulse_ns is not None]
    band: Optional[AmbiguousBand] = ambiguous_band([o.disturbance.impulse_ns for o in sized],
                                                   [o.fallen for o in sized])
    if band is None:
        return None
    inside = [o for o in sized if band.contains(o.disturbance.impulse_ns)]
    return {**band.to_json(), **cause_figures(inside)}


def deployment_figures(outcomes: Sequence[RunOutcome],
                       band_width_ns: float = DEFAULT_BAND_WIDTH_NS) -> dict[str, Any]:
    """Everything of the module docs, as JSON-ready data."""
    present = [c for c in CAUSES if any(o.cause == c for o in outcomes)]
    pushes = [o for o in outcomes if o.cause == CAUSE_PUSH]
    return {'by_cause': {c: cause_figures([o for o in outcomes if o.cause == c]) for c in present},
            'walking': walking_false_alarms(outcomes),
            'push_band_width_ns': band_width_ns,
            'push_bands': impulse_band_figures(pushes, band_width_ns),
            'ambiguous_push_band': ambiguous_band_figures(pushes)}


# -- the table ------------------------------------------------------------------------------------
def _ratio(rate: Mapping[str, Any]) -> str:
    return f"{rate['k']}/{rate['n']}"


def _fpr(rate: Mapping[str, Any]) -> str:
    if not rate['n']:
        return '—'
    low, high = rate['ci95']
    return f"{rate['rate']:.3f} [{low:.3f}, {high:.3f}] ({_ratio(rate)})"


def _s(value: Optional[float], interval: Optional[Sequence[float]] = None) -> str:
    if value is None:
        return '—'
    return f'{value:.2f}' + ('' if interval is None else f' [{interval[0]:.2f}, {interval[1]:.2f}]')


def cause_row(name: str, f: Mapping[str, Any]) -> str:
    """One row of the per-cause table (:func:`deployment_lines`; the results page's tables)."""
    return (f"| {name} | {_ratio(f['falls_caught'])} | {_fpr(f['fpr'])} | "
            f"{f['alarms_before_onset']['k']}/{f['alarms_before_onset']['n']} | "
            f"{_s(f['lead_median_s'], f['lead_median_ci95'])} | {_s(f['onset_to_fall_median_s'])} | "
            f"{_s(f['lead_fraction_median'])} |")


def walking_line(walking: Optional[Mapping[str, Any]]) -> str:
    """The false alarms over the hours of undisturbed walking, in words ('' without walks)."""
    if walking is None or walking['per_hour_ci95'] is None:
        return ''
    interval = walking['per_hour_ci95']
    return (f"undisturbed walking: {walking['alarm_episodes']} false alarm episodes in "
            f"{walking['hours']:.2f} h ({walking['n_walks']} walk{'' if walking['n_walks'] == 1 else 's'}): "
            f"{walking['per_hour']:.2f} per hour, Garwood 95 % "
            f"[{interval[0]:.2f}, {interval[1]:.2f}]")


def deployment_lines(figures: Mapping[str, Any]) -> list[str]:
    """The figures as a readable table (markdown), then the walking hours and the push bands."""
    lines = ['', '| cause | falls caught | FPR [Wilson 95 %] (false alarms / survived) | alarms '
             'before onset | median lead [s] [95 %] | onset to fall [s] (median) | lead / onset '
             'to fall (median) |', '|---|---|---|---|---|---|---|']
    lines += [cause_row(cause, f) for cause, f in figures['by_cause'].items()]
    band = figures['ambiguous_push_band']
    if band is not None:
        lines.append(cause_row(f"push, ambiguous {band['low_ns']:.0f}–{band['high_ns']:.0f} N s", band))
    if walking_line(figures['walking']):
        lines.append(walking_line(figures['walking']))
    if figures['push_bands']:
        lines.append('survived pushes per impulse band: ' + '; '.join(
            f"{b['low_ns']:.0f}–{b['high_ns']:.0f} N s {_fpr(b['fpr'])}, "
            f"{b['fall_fraction']:.0%} fell" for b in figures['push_bands']))
    return lines
