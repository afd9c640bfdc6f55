"""The run-time fall predictor (method §5 and §8): decision lists + history window + CoM guard.

:class:`OnlinePredictor` is the one predictor used by the offline evaluator and by the ROS
predictor node. Per sample at time ``t`` it computes

* ``atomic``: the contact mode's decision list (or boosted trees, method §8a) says falling for
  the feature vector ``x``;
* ``guard``: the CoM height ``x[2]`` is below the guard height (0.48 m, method §5);
* ``falling``: ``atomic or guard`` held at every sample of ``[t - tau_his, t]``;
* ``latched``: falling has been output at least once since :meth:`OnlinePredictor.reset`.

**History window.** The samples since the last reset whose ``atomic or guard`` is true form
runs of consecutive samples. ``falling`` needs the current run to have lasted at least
``tau_his``: ``t - t_run_start >= tau_his``, where ``t_run_start`` is the time of the run's
first sample. With regular sampling and ``tau_his`` a multiple of the period this is exactly
"every sample in ``[t - tau_his, t]`` is falling"; samples before the reset (or before the
first sample) count as not falling, so a run starting at the first sample also has to last
``tau_his``. Times are used, not sample counts, so irregular spacing is handled; times are
compared with a tolerance of ``dt_s / 1000`` so that float round-off in sample times
(``0.003 - 0.001 < 0.002``) does not drop a sample. ``tau_his = 0`` passes every sample's
``atomic or guard`` through.

**Guard.** The CoM guard removes false negatives of states that are certainly falling (a CoM
below 0.48 m; standing height 0.59 m, fallen 0.33 m). It goes through the same window as the
decision lists: a single glitch sample reporting a low CoM must not latch the fall for good,
and the window's cost is small (the guard fires late in a fall anyway; the lead it costs on
the dataset is in docs/results.md).

:func:`predict_trajectory` is the vectorised offline twin of the streaming predictor and gives
exactly the same outputs as :meth:`OnlinePredictor.step` sample by sample.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.records import FALLING, GUARD_COM_HEIGHT_M, N_CONTACT_MODES

#: Index of the CoM height feature (``com_z``) in a feature vector.
COM_HEIGHT_FEATURE = 2
#: Time comparison tolerance as a fraction of the nominal sample period.
TIME_TOLERANCE_FRACTION = 1e-3


@dataclass(slots=True)
class PredictorOutput:
    """One decision of :class:`OnlinePredictor` at simulation/ROS time ``t`` [s]."""

    t: float
    atomic: bool        #: the contact mode's decision list says falling
    falling: bool       #: the prediction: atomic or guard throughout the history window
    guard: bool         #: the CoM guard fired (CoM height below the guard height)
    latched: bool       #: falling was output at least once since the last reset (one-way)


def _check_tau_his(tau_his_s: float) -> float:
    value = float(tau_his_s)
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f'tau_his_s must be a finite number >= 0 [s], got {tau_his_s!r}')
    return value


def _check_positive(name: str, value: float) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f'{name} must be a finite number > 0, got {value!r}')
    return value


class OnlinePredictor:
    """Streaming fall predictor; see the module documentation for the exact semantics.

    ``lists``: one decision list per contact mode; ``tau_his_s`` [s]: history window length
    (run-time parameter, settable at any time, effective from the next step); ``dt_s`` [s]:
    nominal sample period (sets the time tolerance only); ``guard_com_height_m`` [m]: the CoM
    guard height (method §5).
    """

    def __init__(self, lists: PerModeDecisionLists, tau_his_s: float, dt_s: float = 0.001,
                 guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> None:
        self.lists = lists
        self._tau_his_s = _check_tau_his(tau_his_s)
        self._dt_s = _check_positive('dt_s', dt_s)
        self._time_tolerance_s = self._dt_s * TIME_TOLERANCE_FRACTION
        self._guard_com_height_m = float(guard_com_height_m)
        self.reset()

    @property
    def lists(self) -> PerModeDecisionLists:
        """The classifiers; settable at any time (e.g. another decision threshold), effective from
        the next step, the history and latch kept."""
        return self._lists

    @lists.setter
    def lists(self, lists: PerModeDecisionLists) -> None:
        if not isinstance(lists, PerModeDecisionLists):
            raise TypeError(f'lists must be PerModeDecisionLists, got {type(lists).__name__}')
        self._lists = lists
        self._predict_by_mode = tuple(decision_list.predict_one for decision_list in lists.lists)

    @property
    def tau_his_s(self) -> float:
        """History window length [s]."""
        return self._tau_his_s

    @tau_his_s.setter
    def tau_his_s(self, value: float) -> None:
        self._tau_his_s = _check_tau_his(value)

    @property
    def dt_s(self) -> float:
        return self._dt_s

    @property
    def guard_com_height_m(self) -> float:
        return self._guard_com_height_m

    @property
    def latched(self) -> bool:
        """Falling was output at least once since the last reset."""
        return self._latched

    def reset(self) -> None:
        """Forget the history and the latch (a new trajectory, or the robot was reset)."""
        self._run_start_t: Optional[float] = None
        self._last_t = -math.inf
        self._latched = False

    def step(self, t: float, x: Sequence[float], mode: int) -> PredictorOutput:
        """Predict at time ``t`` [s] from features ``x`` (15, CoP frame) in contact mode ``mode``.

        Times must not decrease between resets (ValueError otherwise: call :meth:`reset`).
        NaN features satisfy no comparison and do not fire the guard.
        """
        t = float(t)
        if t < self._last_t:
            raise ValueError(f'time went backwards ({t} s after {self._last_t} s); call reset() first')
        if not 0 <= mode < N_CONTACT_MODES:
            raise ValueError(f'contact mode index {mode} outside [0, {N_CONTACT_MODES})')
        values = x.tolist() if isinstance(x, np.ndarray) else x
        atomic = self._predict_by_mode[mode](values) == FALLING
        guard = values[COM_HEIGHT_FEATURE] < self._guard_com_height_m
        if atomic or guard:
            if self._run_start_t is None:
                self._run_start_t = t
            falling = t - self._run_start_t >= self._tau_his_s - self._time_tolerance_s
        else:
            self._run_start_t = None
            falling = False
        if falling:
            self._latched = True
        self._last_t = t
        return PredictorOutput(t, atomic, falling, guard, self._latched)


@dataclass(frozen=True)
class TrajectoryPrediction:
    """Per-sample predictor outputs over one trajectory (arrays of shape (N,))."""

    t: np.ndarray           #: sample times [s]
    atomic: np.ndarray      #: bool, decision list says falling
    guard: np.ndarray       #: bool, CoM guard fired
    falling: np.ndarray     #: bool, predictor output after the history window

    @property
    def latched(self) -> np.ndarray:
        """Falling output at least once up to and including each sample."""
        return np.logical_or.accumulate(self.falling)

    def first_falling_time(self, t_from: float = -math.inf) -> Optional[float]:
        """Time [s] of the first falling output at or after ``t_from`` [s], or None."""
        return first_true_time(self.t, self.falling, t_from)


def first_true_time(t: np.ndarray, flags: np.ndarray, t_from: float = -math.inf) -> Optional[float]:
    """Time [s] of the first sample at or after ``t_from`` [s] whose flag is set, or None."""
    hits = np.flatnonzero(flags & (t >= t_from))
    return float(t[hits[0]]) if hits.size else None


def check_sample_times(t: np.ndarray) -> np.ndarray:
    """``t`` as a float64 array (N,), or ValueError if it is not 1-D, finite and non-decreasing."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or not np.isfinite(t).all() or (np.diff(t) < 0).any():
        raise ValueError('sample times must be a finite, non-decreasing 1-D array')
    return t


def guard_predictions(X: np.ndarray, guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> np.ndarray:
    """Bool (N,): the CoM guard fires (``X[:, 2]`` below ``guard_com_height_m`` [m])."""
    return np.asarray(X)[:, COM_HEIGHT_FEATURE] < guard_com_height_m


def falling_run_durations(t: np.ndarray, atomic: np.ndarray) -> np.ndarray:
    """Per sample: ``t - t_run_start`` [s] of its run of consecutive flagged samples.

    ``atomic`` is the per-sample candidate (``atomic | guard`` for the predictor). NaN where it
    is not set. Computed once per trajectory, it gives the
    windowed output for any ``tau_his`` (:func:`windowed_falling`).
    """
    t = np.asarray(t, dtype=float)
    atomic = np.asarray(atomic, dtype=bool)
    index = np.arange(atomic.size)
    run_starts = atomic & ~np.concatenate(([False], atomic[:-1]))
    start_index = np.maximum.accumulate(np.where(run_starts, index, 0))
    return np.where(atomic, t - t[start_index], np.nan)


def windowed_falling(run_durations: np.ndarray, tau_his_s: float,
                     dt_s: float = 0.001) -> np.ndarray:
    """Bool (N,): the predictor output for history window ``tau_his_s`` [s].

    ``run_durations`` from :func:`falling_run_durations` of ``atomic | guard``; same
    arithmetic as :meth:`OnlinePredictor.step`.
    """
    tau_his_s = _check_tau_his(tau_his_s)
    time_tolerance_s = _check_positive('dt_s', dt_s) * TIME_TOLERANCE_FRACTION
    with np.errstate(invalid='ignore'):
        return run_durations >= tau_his_s - time_tolerance_s


def predict_trajectory(lists: PerModeDecisionLists, X: np.ndarray, mode: np.ndarray,
                       t: np.ndarray, tau_his_s: float, dt_s: float = 0.001,
                       guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> TrajectoryPrediction:
    """Vectorised :class:`OnlinePredictor` over a whole trajectory, from a reset state.

    ``X`` (N, 15) features, ``mode`` (N,) contact mode indices, ``t`` (N,) non-decreasing
    sample times [s]. Outputs equal those of ``OnlinePredictor.step`` called sample by sample.
    """
    t = check_sample_times(t)
    atomic = lists.predict(X, mode) == FALLING
    guard = guard_predictions(X, guard_com_height_m)
    falling = windowed_falling(falling_run_durations(t, atomic | guard), tau_his_s, dt_s)
    return TrajectoryPrediction(t=t, atomic=atomic, guard=guard, falling=falling)
