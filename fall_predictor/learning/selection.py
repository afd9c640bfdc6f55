"""Choosing among predictors on the FPR / tau_lead trade-off (method §9): the paper's Table 2
predictors (FP-L1..3), the rule that picks their analogues on a sweep's Pareto front, and
:func:`pareto_mean_lead`, one number for a family of predictors (the area under its front).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

from fall_predictor.learning.baselines import pareto_front
from fall_predictor.learning.crossval import SweepPoint


@dataclass(frozen=True)
class PaperPredictor:
    """A predictor of the paper's Table 2 (method §9); times [s]."""

    name: str
    tau_plus_s: float
    tau_his_s: float
    fpr: float
    tau_lead_s: float
    mean_rule_size: float


PAPER_PREDICTORS = (PaperPredictor('FP-L1', -0.30, 0.016, 0.46, 0.90, 61.6),
                    PaperPredictor('FP-L2', -0.25, 0.060, 0.06, 0.76, 51.4),
                    PaperPredictor('FP-L3', 0.30, 0.044, 0.005, 0.43, 5.3))

#: How the analogues of the paper's predictors are picked (written into table.md).
SELECTION_RULE = ('the Pareto-front predictor with the longest tau_lead among those whose '
                  'fold-mean FPR does not exceed the paper\'s FPR for that predictor (if none '
                  'does, the front\'s lowest-FPR predictor)')


#: FPR budgets over which :func:`pareto_mean_lead` averages: the paper's predictors lie within.
PARETO_MAX_FPR = 0.5


def pareto_mean_lead(points: Sequence[Any], max_fpr: float = PARETO_MAX_FPR) -> float:
    """One number for a family of predictors: the best tau_lead [s] reachable within an FPR
    budget, averaged over budgets uniform in ``[0, max_fpr]`` (a budget no predictor meets
    counts 0). The area under the Pareto front, divided by ``max_fpr``; higher is better.

    ``points``: anything with ``fpr`` and ``tau_lead_s`` (NaN points are ignored).
    """
    if not 0.0 < max_fpr <= 1.0:
        raise ValueError(f'max_fpr must be in (0, 1], got {max_fpr!r}')
    area, best_lead = 0.0, 0.0
    front = [p for p in pareto_front(points) if p.fpr < max_fpr]
    for point, next_fpr in zip(front, [p.fpr for p in front[1:]] + [max_fpr]):
        best_lead = max(best_lead, point.tau_lead_s)
        area += best_lead * (next_fpr - point.fpr)
    return area / max_fpr


def select_paper_analogues(points: Sequence[SweepPoint]) -> list[tuple[PaperPredictor, SweepPoint]]:
    """For each of :data:`PAPER_PREDICTORS`, the sweep point chosen by :data:`SELECTION_RULE`."""
    front = pareto_front(points)
    if not front:
        return []
    chosen = []
    for paper in PAPER_PREDICTORS:
        within = [p for p in front if p.fpr <= paper.fpr + 1e-12]
        chosen.append((paper, max(within, key=lambda p: p.tau_lead_s) if within else front[0]))
    return chosen
