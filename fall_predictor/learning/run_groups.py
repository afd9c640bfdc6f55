"""What disturbed each run, and how hard: its cause, a push's impulse, the impulse bands, the
ambiguous band, and the groups cross-validation folds keep whole (method §5 "Per cause", §11
"A budget that holds").

* :class:`RunDisturbance`: a run's cause (``push`` for every dataset made before causes
  existed), its onset [s] (None for a long walk) and, for a push, its impulse [N s] = force x
  duration.
* :func:`ambiguous_band`: the impulse band in which 20-80 % of pushes fell the robot, found from
  the data: a logistic fit of the fall probability on the impulse (two parameters, by iteratively
  reweighted least squares), the band between the impulses where it crosses 0.2 and 0.8. None
  when the data do not show falls rising with the impulse (too few falls or survivals, or no
  rising trend).
* :func:`fold_groups`: the group of each run that a fold keeps whole: a push's impulse band
  (``bands`` bands of equal counts), a run of any other cause its cause. A fold tested on a
  band (or a cause) then comes from a model that never trained on it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Optional, Sequence

import numpy as np

from fall_predictor.data.dataset import CAUSE_PUSH, CAUSE_WALK, IndexRow

#: The fall probabilities that bound the ambiguous band.
AMBIGUOUS_FALL_PROBABILITY = (0.2, 0.8)
#: Fewest falls and fewest survivals among pushes for the ambiguous band to be fitted.
MIN_OUTCOMES_FOR_BAND = 3


@dataclass(frozen=True)
class RunDisturbance:
    """What disturbed one run (times [s], impulse [N s]; None where not applicable)."""

    cause: str
    onset_s: Optional[float]        #: when the disturbance first acted; None for a long walk
    #: A push's force x duration; None for other causes, and for a push of unknown force (a
    #: robot's own recordings: its force is not measured).
    impulse_ns: Optional[float]

    @classmethod
    def of_row(cls, row: IndexRow) -> 'RunDisturbance':
        impulse = (abs(row.force_n) * max(row.t_force_end - row.t_push, 0.0)
                   if row.cause == CAUSE_PUSH else None)
        return cls(row.cause, row.onset_s,
                   impulse if impulse is not None and math.isfinite(impulse) else None)


#: A run without an index row (e.g. a trajectory built in a test) reads as a push of unknown size.
UNKNOWN_PUSH = RunDisturbance(CAUSE_PUSH, None, None)


def disturbances(rows: Sequence[IndexRow], prefix: str = '') -> dict[str, RunDisturbance]:
    """Per trajectory id (``prefix/id`` when ``prefix``: a merged training set's ids) its
    disturbance."""
    return {(f'{prefix}/{row.trajectory_id}' if prefix else row.trajectory_id):
            RunDisturbance.of_row(row) for row in rows}


def _logistic_fit(x: np.ndarray, y: np.ndarray, ridge: float = 1e-3,
                  iterations: int = 100) -> tuple[float, float]:
    """Intercept and slope of P(y = 1) = 1 / (1 + exp(-(a + b x))), by Newton steps on the
    log-likelihood with a small ridge on the slope of the standardised ``x`` (so that data a
    threshold separates perfectly give a steep, finite slope)."""
    mean, scale = float(np.mean(x)), float(np.std(x)) or 1.0
    design = np.column_stack([np.ones_like(x), (x - mean) / scale])
    beta = np.zeros(2)
    penalty = np.diag([0.0, ridge])
    for _ in range(iterations):
        p = 1.0 / (1.0 + np.exp(-np.clip(design @ beta, -50.0, 50.0)))
        gradient = design.T @ (y - p) - penalty @ beta
        hessian = design.T @ (design * (p * (1.0 - p))[:, None]) + penalty
        step = np.linalg.solve(hessian + 1e-12 * np.eye(2), gradient)
        beta += step
        if np.max(np.abs(step)) < 1e-10:
            break
    slope = beta[1] / scale
    return float(beta[0] - slope * mean), float(slope)


@dataclass(frozen=True)
class AmbiguousBand:
    """The impulse band [N s] in which the fitted fall probability goes from 0.2 to 0.8."""

    low_ns: float
    high_ns: float
    intercept: float                #: the logistic fit: P(fall) = 1 / (1 + exp(-(a + b I)))
    slope_per_ns: float
    n_pushes: int

    def contains(self, impulse_ns: Optional[float]) -> bool:
        return impulse_ns is not None and self.low_ns <= impulse_ns <= self.high_ns

    def to_json(self) -> dict:
        return {'low_ns': self.low_ns, 'high_ns': self.high_ns,
                'fall_probability': list(AMBIGUOUS_FALL_PROBABILITY),
                'fit': {'intercept': self.intercept, 'slope_per_ns': self.slope_per_ns},
                'n_pushes': self.n_pushes}


def ambiguous_band(impulses_ns: Sequence[float], fallen: Sequence[bool]) -> Optional[AmbiguousBand]:
    """The ambiguous band of pushes of these impulses [N s] and outcomes (module docs)."""
    x = np.asarray(impulses_ns, dtype=float)
    y = np.asarray(fallen, dtype=float)
    if x.shape != y.shape:
        raise ValueError(f'{x.size} impulses but {y.size} outcomes')
    n_fallen = int(y.sum())
    if n_fallen < MIN_OUTCOMES_FOR_BAND or x.size - n_fallen < MIN_OUTCOMES_FOR_BAND:
        return None
    intercept, slope = _logistic_fit(x, y)
    if not slope > 0.0:
        return None                 # falls do not rise with the impulse: no band of it
    low, high = ((math.log(p / (1.0 - p)) - intercept) / slope for p in AMBIGUOUS_FALL_PROBABILITY)
    return AmbiguousBand(float(low), float(high), intercept, slope, int(x.size))


def fold_groups(trajectory_ids: Sequence[str], runs: Mapping[str, RunDisturbance],
                bands: int) -> list[tuple]:
    """Per trajectory (in order) the group a cross-validation fold keeps whole: ``('push', k)``
    for a push in impulse band ``k`` of ``bands`` bands of (nearly) equal counts over the pushes
    (ranked by impulse, ties by order), ``(cause,)`` for a run of another cause. A push of
    unknown impulse (no index row) joins the bands by its rank among them as if of impulse 0."""
    if isinstance(bands, bool) or not isinstance(bands, int) or bands < 1:
        raise ValueError(f'bands must be an int >= 1, got {bands!r}')
    found = [runs.get(tid, UNKNOWN_PUSH) for tid in trajectory_ids]
    pushes = [i for i, run in enumerate(found) if run.cause == CAUSE_PUSH]
    impulses = np.array([found[i].impulse_ns or 0.0 for i in pushes])
    rank = np.empty(len(pushes), dtype=int)
    rank[np.argsort(impulses, kind='stable')] = np.arange(len(pushes))
    band_of = {i: int(r * bands // max(len(pushes), 1)) for i, r in zip(pushes, rank)}
    return [(CAUSE_PUSH, band_of[i]) if i in band_of else (found[i].cause,)
            for i in range(len(found))]


def is_walk(run: RunDisturbance) -> bool:
    """A long walk: no disturbance acted (every alarm on it is false unless it fell)."""
    return run.cause == CAUSE_WALK
