"""Hand-coded fall predictors (the paper's Sec. 4 baselines), evaluated like learned ones.

Each baseline says falling (atomically) when one physical quantity crosses a threshold; the
CoM guard of method §5 is added like for every predictor, and an optional history window
``tau_his_s`` is applied exactly as by :class:`~fall_predictor.monitor.predictor.OnlinePredictor`
(the paper's baselines use none: default 0). Sweeping the threshold gives a curve of
:class:`CurvePoint` (threshold, FPR, tau_lead):

* :func:`com_height_curve`: CoM height below ``h`` [m]. With the guard on, every ``h`` below
  the guard height predicts exactly as the guard alone.
* :func:`momentum_curve`: ``|p_x| > a or |p_y| > b`` [kg m/s], horizontal linear momentum in
  the heading frame (features ``lin_mom_x``, ``lin_mom_y``), over a grid of ``(a, b)``.
* :func:`capture_point_curve`: the instantaneous capture point ``xi = c + v / omega``
  (``omega = sqrt(g / z_com)``, ``v = p / m``) leaves the support polygon shrunk by a margin.
  It needs the support polygon, which the CoP-frame features do not hold, so it takes a
  per-sample signed distance of the capture point to the polygon computed from the raw
  :class:`~fall_predictor.monitor.records.Measurement` stream by :func:`~fall_predictor.monitor.capture_point.capture_point_distances`.

:func:`pareto_front` picks the non-dominated points of any such curve or set of results.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Protocol, Sequence, TypeVar, Union

import numpy as np

from fall_predictor.learning.metrics import EvaluationResult, evaluate_atomic
from fall_predictor.monitor.records import FEATURE_NAMES, GUARD_COM_HEIGHT_M, TrajectoryFeatures

COM_Z = FEATURE_NAMES.index('com_z')
LIN_MOM_X = FEATURE_NAMES.index('lin_mom_x')
LIN_MOM_Y = FEATURE_NAMES.index('lin_mom_y')


@dataclass(frozen=True)
class CurvePoint:
    """One baseline setting and its metrics (FPR, lead time [s]) over the trajectories."""

    threshold: Union[float, tuple[float, float]]   #: the baseline's threshold(s), in its units
    fpr: float
    tau_lead_s: float
    evaluation: EvaluationResult


Threshold = TypeVar('Threshold', float, tuple[float, float])


def _curve(trajectories: Sequence[TrajectoryFeatures], thresholds: Sequence[Threshold],
           atomic_for: Callable[[int, Threshold], np.ndarray], tau_his_s: float, dt_s: float,
           guard_com_height_m: float) -> list[CurvePoint]:
    """Evaluate ``atomic_for(trajectory index, threshold) -> bool (N,)`` for every threshold."""
    points = []
    for threshold in thresholds:
        atomic = [atomic_for(i, threshold) for i in range(len(trajectories))]
        result = evaluate_atomic(trajectories, atomic, (tau_his_s,), dt_s, guard_com_height_m)
        evaluation = result[float(tau_his_s)]
        points.append(CurvePoint(threshold, evaluation.fpr, evaluation.tau_lead_s, evaluation))
    return points


def com_height_curve(trajectories: Sequence[TrajectoryFeatures], heights_m: Sequence[float],
                     tau_his_s: float = 0.0, dt_s: float = 0.001,
                     guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> list[CurvePoint]:
    """Baseline "CoM height below h": one point per ``h`` in ``heights_m`` [m]."""
    return _curve(trajectories, [float(h) for h in heights_m],
                  lambda i, h: trajectories[i].X[:, COM_Z] < h, tau_his_s, dt_s, guard_com_height_m)


def momentum_curve(trajectories: Sequence[TrajectoryFeatures],
                   sagittal_thresholds: Sequence[float], frontal_thresholds: Sequence[float],
                   tau_his_s: float = 0.0, dt_s: float = 0.001,
                   guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> list[CurvePoint]:
    """Baseline ``|p_x| > a or |p_y| > b`` over the grid ``a`` x ``b`` [kg m/s].

    Thresholds are ``(a, b)`` tuples; pass ``math.inf`` to leave one axis out.
    """
    grid = [(float(a), float(b)) for a in sagittal_thresholds for b in frontal_thresholds]
    return _curve(trajectories, grid,
                  lambda i, ab: (np.abs(trajectories[i].X[:, LIN_MOM_X]) > ab[0])
                  | (np.abs(trajectories[i].X[:, LIN_MOM_Y]) > ab[1]),
                  tau_his_s, dt_s, guard_com_height_m)


def capture_point_curve(trajectories: Sequence[TrajectoryFeatures],
                        distances: Sequence[np.ndarray], margins_m: Sequence[float],
                        tau_his_s: float = 0.0, dt_s: float = 0.001,
                        guard_com_height_m: float = GUARD_COM_HEIGHT_M) -> list[CurvePoint]:
    """Baseline "capture point outside the support polygon shrunk by ``margin``" [m].

    ``distances[i]`` holds, for every sample of ``trajectories[i]`` (same length and order as
    its ``t``), the capture point's signed distance to the support polygon
    (:func:`~fall_predictor.monitor.capture_point.capture_point_distances`). Falling where ``distance > -margin``: a positive margin
    shrinks the polygon (earlier alarms), a negative one grows it.
    """
    if len(distances) != len(trajectories):
        raise ValueError(f'{len(trajectories)} trajectories but {len(distances)} distance arrays')
    distances = [np.asarray(d, dtype=float) for d in distances]
    return _curve(trajectories, [float(m) for m in margins_m],
                  lambda i, margin: distances[i] > -margin,
                  tau_his_s, dt_s, guard_com_height_m)


class _TradeOff(Protocol):
    fpr: float
    tau_lead_s: float


P = TypeVar('P', bound=_TradeOff)


def pareto_front(points: Sequence[P]) -> list[P]:
    """The points no other point beats (lower or equal FPR and higher or equal tau_lead, one
    strictly), sorted by increasing FPR. Points with a NaN metric are left out; of identical
    (FPR, tau_lead) pairs the first is kept. Works on :class:`CurvePoint`,
    :class:`~fall_predictor.learning.metrics.EvaluationResult` or anything with ``fpr``/``tau_lead_s``.
    """
    candidates = [(p.fpr, -p.tau_lead_s, i) for i, p in enumerate(points)
                  if not (math.isnan(p.fpr) or math.isnan(p.tau_lead_s))]
    front = []
    best_lead = -math.inf
    for fpr, negative_lead, i in sorted(candidates):
        if -negative_lead > best_lead:
            front.append(points[i])
            best_lead = -negative_lead
    return front
