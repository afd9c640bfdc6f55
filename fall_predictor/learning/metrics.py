"""Evaluation of fall predictors (method §5): FPR, lead time, misses, pre-push alarms.

Definitions (per trajectory, from the predictor's falling output run over the whole
trajectory from a reset state):

* **FPR**: fraction of the balanced (never fallen) trajectories with at least one falling
  output anywhere, before the push included. Fallen trajectories never count in FPR.
* **tau_lead**: mean over fallen trajectories of ``t_fallen - t_predict``, where ``t_predict``
  is the first falling output at or after ``t_push``; no falling output in
  ``[t_push, t_fallen)`` counts 0 and is a **miss**.
* **pre-push false alarms**: trajectories (balanced or fallen) with a falling output before
  ``t_push``, counted separately for the two outcomes. On a fallen trajectory such an alarm
  does not change ``t_predict`` (still the first output at or after the push) and does not
  count in FPR; on a balanced trajectory it is also a false positive. Per trajectory, its
  alarm onsets before the push (the falling output turning on) are counted too
  (:class:`TrajectoryAlarms`, kept per trajectory in :attr:`EvaluationResult.alarms`).
* **oracle lead**: mean over fallen trajectories of ``t_fallen - t_push``.
* **lists alone / guard alone** (method §11): the same lead and misses computed from the decision
  lists' windowed output with the CoM guard off (``tau_lead_lists_only_s``,
  ``n_missed_lists_only``) and from the CoM guard alone (``tau_lead_guard_only_s``), so that
  "no misses" is not credited to the guard.
* **intervals** (method §11): ``fpr_ci95`` is the Wilson 95 % interval of the FPR;
  ``tau_lead_ci95`` and ``tau_lead_lists_only_ci95`` are bootstrap 95 % intervals over the
  fallen trajectories (:mod:`fall_predictor.learning.intervals`).

**Holes** (samples the estimator or the feature extractor refused, left out of a trajectory's
arrays: :mod:`fall_predictor.data.dataset`) are handled as the onboard monitor handles them
(:class:`~fall_predictor.monitor.fall_monitor.FallMonitor`): the history window spans a hole of
at most :data:`MAX_GAP_S`, and restarts after a longer one (:func:`run_durations`).

Rates and means over an empty set are NaN (:func:`mean_or_nan`, :func:`std_or_nan`; also used
to average over cross-validation folds). Cross-validation itself is in
:mod:`fall_predictor.learning.crossval`.
"""
from __future__ import annotations

import inspect
import math
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from fall_predictor.learning.intervals import bootstrap_mean_interval, wilson_interval
from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.fall_monitor import FallMonitor
from fall_predictor.monitor.predictor import (check_sample_times, falling_run_durations,
                                              first_true_time, guard_predictions, windowed_falling)
from fall_predictor.monitor.records import FALLING, GUARD_COM_HEIGHT_M, TrajectoryFeatures


#: The longest hole [s] the onboard monitor's history window spans (its ``max_gap_s``: the window
#: restarts after a longer one); read from :class:`FallMonitor`, so that there is one value.
MAX_GAP_S: float = float(inspect.signature(FallMonitor).parameters['max_gap_s'].default)


def run_durations(t: np.ndarray, flags: np.ndarray, max_gap_s: float = MAX_GAP_S) -> np.ndarray:
    """:func:`~fall_predictor.monitor.predictor.falling_run_durations` of ``flags`` at the
    sample times ``t`` [s], with a run broken where consecutive samples are more than
    ``max_gap_s`` [s] apart (a hole after which the onboard window restarts): the run then
    starts again at the sample after the hole."""
    t = np.asarray(t, dtype=float)
    flags = np.asarray(flags, dtype=bool)
    starts = np.flatnonzero(np.diff(t) > max_gap_s) + 1
    if not starts.size:
        return falling_run_durations(t, flags)
    bounds = [0, *starts.tolist(), t.size]
    return np.concatenate([falling_run_durations(t[a:b], flags[a:b])
                           for a, b in zip(bounds[:-1], bounds[1:])])


@dataclass(frozen=True, slots=True)
class TrajectoryAlarms:
    """When a predictor said falling on one trajectory (times [s], None if never)."""

    first_alarm_t: Optional[float]              #: first falling output anywhere
    first_alarm_after_push_t: Optional[float]   #: first falling output at or after t_push
    pre_push_alarm: bool                        #: a falling output before t_push
    #: times the falling output turned on before t_push (a count beside the alarm times, which
    #: identify the alarms: not compared)
    pre_push_onsets: int = field(default=0, compare=False)
    #: times the falling output turned on anywhere on the trajectory: its alarm episodes (the
    #: false alarms per hour of an undisturbed walk count them); a count, not compared
    alarm_onsets: int = field(default=0, compare=False)


def trajectory_alarms(t: np.ndarray, falling: np.ndarray, t_push: float) -> TrajectoryAlarms:
    """Alarm times of one trajectory from its per-sample falling outputs."""
    first = first_true_time(t, falling)
    falling = np.asarray(falling, dtype=bool)
    onsets = falling & ~np.concatenate(([False], falling[:-1]))
    return TrajectoryAlarms(first_alarm_t=first,
                            first_alarm_after_push_t=first_true_time(t, falling, t_push),
                            pre_push_alarm=first is not None and first < t_push,
                            pre_push_onsets=int(np.count_nonzero(onsets & (np.asarray(t) < t_push))),
                            alarm_onsets=int(np.count_nonzero(onsets)))


@dataclass(frozen=True)
class EvaluationResult:
    """method §5 metrics of one predictor over a set of trajectories (times in seconds)."""

    n_trajectories: int
    n_balanced: int                   #: trajectories that never fall
    n_fallen: int
    n_false_positives: int            #: balanced trajectories with any falling output
    fpr: float                        #: n_false_positives / n_balanced
    tau_lead_s: float                 #: mean lead over fallen trajectories (misses count 0)
    n_missed: int                     #: fallen trajectories without a falling output in [t_push, t_fallen)
    n_pre_push_alarms_balanced: int   #: balanced trajectories with a falling output before t_push
    n_pre_push_alarms_fallen: int     #: fallen trajectories with a falling output before t_push
    oracle_lead_s: float              #: mean t_fallen - t_push over fallen trajectories
    lead_fraction: float              #: tau_lead_s / oracle_lead_s
    mean_rule_size: Optional[float] = None   #: of the decision lists, if the predictor has any
    fpr_ci95: tuple[float, float] = (math.nan, math.nan)        #: Wilson 95 % interval of fpr
    tau_lead_ci95: tuple[float, float] = (math.nan, math.nan)   #: bootstrap over trajectories
    n_missed_lists_only: Optional[int] = None       #: misses with the CoM guard off
    tau_lead_lists_only_s: float = math.nan         #: lead with the CoM guard off
    tau_lead_lists_only_ci95: tuple[float, float] = (math.nan, math.nan)
    tau_lead_guard_only_s: float = math.nan         #: lead of the CoM guard by itself
    #: per fallen trajectory, its lead [s] (0 for a miss): for pooled intervals; not in JSON
    leads_s: tuple[float, ...] = ()
    #: per trajectory, in the order evaluated, its alarms, when asked for (``keep_alarms``: the
    #: per-run report); not in JSON
    alarms: tuple[TrajectoryAlarms, ...] = ()

    @property
    def n_pre_push_alarms(self) -> int:
        """Trajectories of either outcome with a falling output before the push."""
        return self.n_pre_push_alarms_balanced + self.n_pre_push_alarms_fallen


def _not_nan(values: Sequence[float]) -> list[float]:
    return [v for v in values if not math.isnan(v)]


def mean_or_nan(values: Sequence[float]) -> float:
    """Mean of the non-NaN values; NaN if there are none (an empty or all-NaN sequence)."""
    kept = _not_nan(values)
    return float(np.mean(kept)) if kept else math.nan


def std_or_nan(values: Sequence[float]) -> float:
    """Population standard deviation of the non-NaN values; NaN if there are none."""
    kept = _not_nan(values)
    return float(np.std(kept)) if kept else math.nan


def _leads(trajectories: Sequence[TrajectoryFeatures],
           alarms: Sequence[TrajectoryAlarms]) -> tuple[list[float], int]:
    """Per fallen trajectory its lead [s] (0 for a miss), and the number of misses."""
    leads: list[float] = []
    missed = 0
    for traj, alarm in zip(trajectories, alarms):
        if not traj.fallen:
            continue
        if traj.t_fallen is None:
            raise ValueError(f'trajectory {traj.trajectory_id} fell but has no t_fallen')
        t_predict = alarm.first_alarm_after_push_t
        hit = t_predict is not None and t_predict < traj.t_fallen
        leads.append(traj.t_fallen - t_predict if hit else 0.0)
        missed += not hit
    return leads, missed


def evaluate(trajectories: Sequence[TrajectoryFeatures], alarms: Sequence[TrajectoryAlarms],
             mean_rule_size: Optional[float] = None,
             lists_only_alarms: Optional[Sequence[TrajectoryAlarms]] = None,
             guard_only_alarms: Optional[Sequence[TrajectoryAlarms]] = None,
             keep_alarms: bool = False) -> EvaluationResult:
    """method §5 metrics from each trajectory's alarm times (``alarms[i]`` for ``trajectories[i]``).

    ``lists_only_alarms`` (the predictor with the CoM guard off) and ``guard_only_alarms`` (the
    CoM guard by itself), when given, fill the lists-alone and guard-alone fields. With
    ``keep_alarms`` the result keeps ``alarms`` (:attr:`EvaluationResult.alarms`; off by default:
    sweeps make thousands of results).
    """
    for name, records in (('alarm', alarms), ('lists-only alarm', lists_only_alarms),
                          ('guard-only alarm', guard_only_alarms)):
        if records is not None and len(records) != len(trajectories):
            raise ValueError(f'{len(trajectories)} trajectories but {len(records)} {name} records')
    false_positives = pre_push_balanced = pre_push_fallen = 0
    oracle_leads: list[float] = []
    leads, missed = _leads(trajectories, alarms)
    for traj, alarm in zip(trajectories, alarms):
        if traj.fallen:
            oracle_leads.append(traj.t_fallen - traj.t_push)
            pre_push_fallen += alarm.pre_push_alarm
        else:
            false_positives += alarm.first_alarm_t is not None
            pre_push_balanced += alarm.pre_push_alarm
    n_fallen = len(leads)
    n_balanced = len(trajectories) - n_fallen
    tau_lead_s = mean_or_nan(leads)
    oracle_lead_s = mean_or_nan(oracle_leads)
    extra: dict = {}
    if lists_only_alarms is not None:
        lists_leads, lists_missed = _leads(trajectories, lists_only_alarms)
        extra.update(n_missed_lists_only=lists_missed,
                     tau_lead_lists_only_s=mean_or_nan(lists_leads),
                     tau_lead_lists_only_ci95=bootstrap_mean_interval(lists_leads))
    if guard_only_alarms is not None:
        extra['tau_lead_guard_only_s'] = mean_or_nan(_leads(trajectories, guard_only_alarms)[0])
    return EvaluationResult(
        n_trajectories=len(trajectories), n_balanced=n_balanced, n_fallen=n_fallen,
        n_false_positives=false_positives,
        fpr=false_positives / n_balanced if n_balanced else math.nan,
        tau_lead_s=tau_lead_s, n_missed=missed,
        n_pre_push_alarms_balanced=pre_push_balanced, n_pre_push_alarms_fallen=pre_push_fallen,
        oracle_lead_s=oracle_lead_s,
        lead_fraction=tau_lead_s / oracle_lead_s if oracle_lead_s > 0 else math.nan,
        mean_rule_size=mean_rule_size,
        fpr_ci95=wilson_interval(false_positives, n_balanced),
        tau_lead_ci95=bootstrap_mean_interval(leads), leads_s=tuple(leads),
        alarms=tuple(alarms) if keep_alarms else (), **extra)


def evaluate_atomic(trajectories: Sequence[TrajectoryFeatures], atomic: Sequence[np.ndarray],
                    tau_his_values: Sequence[float] = (0.0,), dt_s: float = 0.001,
                    guard_com_height_m: float = GUARD_COM_HEIGHT_M,
                    mean_rule_size: Optional[float] = None,
                    keep_alarms: bool = False) -> dict[float, EvaluationResult]:
    """Evaluate per-sample atomic predictions (bool (N,) per trajectory) for several windows.

    The CoM guard and the history window are applied as by
    :class:`~fall_predictor.monitor.predictor.OnlinePredictor`, the window restarting after a
    hole longer than :data:`MAX_GAP_S` as in the onboard monitor (:func:`run_durations`);
    returns ``{tau_his_s: result}`` (each with its per-trajectory alarms with ``keep_alarms``).
    """
    if len(trajectories) != len(atomic):
        raise ValueError(f'{len(trajectories)} trajectories but {len(atomic)} atomic arrays')
    alarms: dict[float, list[TrajectoryAlarms]] = {float(tau): [] for tau in tau_his_values}
    lists_only: dict[float, list[TrajectoryAlarms]] = {float(tau): [] for tau in tau_his_values}
    guard_only: dict[float, list[TrajectoryAlarms]] = {float(tau): [] for tau in tau_his_values}
    for traj, atomic_falling in zip(trajectories, atomic):
        t = check_sample_times(traj.t)
        if np.shape(atomic_falling) != t.shape:
            raise ValueError(f'trajectory {traj.trajectory_id}: atomic predictions do not match its samples')
        guard = guard_predictions(traj.X, guard_com_height_m)
        durations = run_durations(t, atomic_falling | guard)
        lists_durations = run_durations(t, atomic_falling)
        guard_durations = run_durations(t, guard)
        for tau_his_s, records in alarms.items():
            falling = windowed_falling(durations, tau_his_s, dt_s)
            records.append(trajectory_alarms(t, falling, traj.t_push))
            lists_falling = windowed_falling(lists_durations, tau_his_s, dt_s)
            lists_only[tau_his_s].append(trajectory_alarms(t, lists_falling, traj.t_push))
            guard_falling = windowed_falling(guard_durations, tau_his_s, dt_s)
            guard_only[tau_his_s].append(trajectory_alarms(t, guard_falling, traj.t_push))
    return {tau_his_s: evaluate(trajectories, records, mean_rule_size,
                                lists_only_alarms=lists_only[tau_his_s],
                                guard_only_alarms=guard_only[tau_his_s], keep_alarms=keep_alarms)
            for tau_his_s, records in alarms.items()}


def windowed_prediction(lists: PerModeDecisionLists, traj: TrajectoryFeatures, tau_his_s: float,
                        guard_com_height_m: float = GUARD_COM_HEIGHT_M, dt_s: float = 0.001
                        ) -> np.ndarray:
    """Bool (N,): the falling output of ``lists`` on one trajectory with the CoM guard and the
    history window ``tau_his_s`` [s], as :func:`evaluate_atomic` computes it (holes included)."""
    t = check_sample_times(traj.t)
    candidate = (lists.predict(traj.X, traj.mode) == FALLING) | guard_predictions(traj.X, guard_com_height_m)
    return windowed_falling(run_durations(t, candidate), tau_his_s, dt_s)


def evaluate_lists(trajectories: Sequence[TrajectoryFeatures], lists: PerModeDecisionLists,
                   tau_his_values: Sequence[float], dt_s: float = 0.001,
                   guard_com_height_m: float = GUARD_COM_HEIGHT_M,
                   keep_alarms: bool = False) -> dict[float, EvaluationResult]:
    """Evaluate a learned predictor for several ``tau_his`` [s] at once: ``{tau_his_s: result}``.

    The decision lists run once per trajectory; the window is applied per ``tau_his``.
    """
    atomic = [lists.predict(traj.X, traj.mode) == FALLING for traj in trajectories]
    return evaluate_atomic(trajectories, atomic, tau_his_values, dt_s, guard_com_height_m,
                           lists.mean_rule_size, keep_alarms)
