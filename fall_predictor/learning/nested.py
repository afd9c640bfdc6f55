"""Nested selection of operating points (SPEC §11).

An operating point that is *chosen* ("the longest lead at FPR <= 0.06", the analogues of the
paper's Table 2) must not be reported on the data it was chosen on. With the cross-validated
grid of :func:`~fall_predictor.learning.crossval.cross_validate_grid` (per fold, per
``(tau_plus, tau_his)``, the held-out fold's result), :func:`nested_operating_point` does, for
every outer fold k: pool the results of the *other* folds per setting, choose the setting there,
and take fold k's result at that setting. The reported figure pools the outer folds' results
(false positives over balanced trajectories, leads over fallen trajectories), with a Wilson
interval on the FPR and a bootstrap interval over trajectories on the lead.

Caveat, stated in the docs: the inner folds' results come from models whose training data
included fold k (one training per fold, as in the issue's "re-select on 9 folds, report the
10th"); only the choice of setting is nested, not the training. The settings chosen per outer
fold are returned, so their stability can be reported.
"""
from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Sequence

from fall_predictor.learning.crossval import FoldFit
from fall_predictor.learning.intervals import bootstrap_mean_interval, wilson_interval
from fall_predictor.learning.metrics import EvaluationResult, mean_or_nan

Setting = tuple[float, float]   #: (tau_plus_s, tau_his_s)


@dataclass(frozen=True)
class PooledFigures:
    """FPR and tau_lead pooled over several results (one per fold)."""

    n_balanced: int
    n_false_positives: int
    fpr: float
    fpr_ci95: tuple[float, float]
    n_fallen: int
    tau_lead_s: float
    tau_lead_ci95: tuple[float, float]
    n_missed: int


def pool_results(results: Sequence[EvaluationResult]) -> PooledFigures:
    """Pool fold results: FPR = all false positives / all balanced trajectories, tau_lead = mean
    over all fallen trajectories' leads (each result must carry its ``leads_s``)."""
    n_balanced = sum(r.n_balanced for r in results)
    n_fp = sum(r.n_false_positives for r in results)
    leads = [lead for r in results for lead in r.leads_s]
    if sum(r.n_fallen for r in results) != len(leads):
        raise ValueError('results without per-trajectory leads (leads_s) cannot be pooled')
    return PooledFigures(n_balanced, n_fp, n_fp / n_balanced if n_balanced else math.nan,
                         wilson_interval(n_fp, n_balanced), len(leads), mean_or_nan(leads),
                         bootstrap_mean_interval(leads), sum(r.n_missed for r in results))


def _per_fold_grid(fits: Sequence[FoldFit]) -> dict[int, dict[Setting, EvaluationResult]]:
    grid: dict[int, dict[Setting, EvaluationResult]] = defaultdict(dict)
    for fit in fits:
        if fit.train_size is not None:
            continue                      # learning-curve trainings are not part of the grid
        for tau_his_s, result in fit.results.items():
            setting = (float(fit.tau_plus_s), float(tau_his_s))
            if setting in grid[fit.fold]:
                raise ValueError(f'fold {fit.fold}: setting {setting} appears twice')
            grid[fit.fold][setting] = result
    settings = {frozenset(g) for g in grid.values()}
    if len(settings) != 1:
        raise ValueError('every fold must hold the same (tau_plus, tau_his) settings')
    if len(grid) < 2:
        raise ValueError('nested selection needs at least 2 folds')
    return dict(grid)


def choose_setting(pooled: dict[Setting, PooledFigures], max_fpr: float) -> Setting:
    """The setting with the longest pooled lead whose pooled FPR is ``<= max_fpr``; if none
    qualifies, the lowest FPR (ties: longest lead). Remaining ties: the smaller setting."""
    within = [s for s, p in pooled.items() if p.fpr <= max_fpr + 1e-12]
    if within:
        return max(sorted(within), key=lambda s: pooled[s].tau_lead_s)
    return min(sorted(pooled), key=lambda s: (pooled[s].fpr, -pooled[s].tau_lead_s))


@dataclass(frozen=True)
class NestedOperatingPoint:
    """An operating point chosen on inner folds and reported on the outer folds."""

    max_fpr: float                       #: the FPR budget of the choice
    chosen: tuple[Setting, ...]          #: per outer fold, the (tau_plus, tau_his) chosen
    outer: PooledFigures                 #: the outer folds' results at their chosen settings
    selected_in_hindsight: Setting       #: what choosing on all folds would have picked
    hindsight: PooledFigures             #: its figures on all folds (optimistic)


def nested_operating_point(fits: Sequence[FoldFit], max_fpr: float) -> NestedOperatingPoint:
    """Choose "the longest lead at FPR <= ``max_fpr``" on the other folds, report each fold."""
    grid = _per_fold_grid(fits)
    folds = sorted(grid)
    settings = sorted(grid[folds[0]])
    chosen: list[Setting] = []
    outer: list[EvaluationResult] = []
    for k in folds:
        inner = {s: pool_results([grid[j][s] for j in folds if j != k]) for s in settings}
        setting = choose_setting(inner, max_fpr)
        chosen.append(setting)
        outer.append(grid[k][setting])
    everything = {s: pool_results([grid[j][s] for j in folds]) for s in settings}
    hindsight = choose_setting(everything, max_fpr)
    return NestedOperatingPoint(max_fpr, tuple(chosen), pool_results(outer), hindsight,
                                everything[hindsight])


def fixed_setting(fits: Sequence[FoldFit], setting: Setting) -> PooledFigures:
    """Figures at settings fixed in advance (e.g. the paper's own): no selection, no nesting."""
    grid = _per_fold_grid(fits)
    key = (float(setting[0]), float(setting[1]))
    if key not in grid[min(grid)]:
        raise ValueError(f'setting {setting} is not in the cross-validated grid')
    return pool_results([grid[k][key] for k in sorted(grid)])
