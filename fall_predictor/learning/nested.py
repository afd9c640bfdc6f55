"""Nested selection of operating points (method §11).

An operating point that is *chosen* ("the longest lead at FPR <= 0.06", the analogues of the
paper's Table 2) must not be reported on the data it was chosen on. With the cross-validated
grid of :func:`~fall_predictor.learning.crossval.cross_validate_grid` (per fold, per
``(tau_plus, tau_his)``, the held-out fold's result), :func:`nested_operating_point` does, for
every outer fold k: pool the results of the *other* folds per setting, choose the setting there,
and take fold k's result at that setting. The reported figure pools the outer folds' results
(false positives over balanced trajectories, leads over fallen trajectories), with a Wilson
interval on the FPR and a bootstrap interval over trajectories on the lead.
:func:`nested_over_grid` does the same over any per-fold grid of settings, e.g. the boosted
trees' (tau_plus, decision threshold, tau_his) (method §8a).

Caveat, stated in the docs: the inner folds' results come from models whose training data
included fold k (one training per fold: "re-select on 9 folds, report the 10th", method §11);
only the choice of setting is nested, not the training. The settings chosen per outer fold are
returned, so their stability can be reported.
"""
from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Mapping, Optional, Sequence

from fall_predictor.learning.crossval import FoldFit
from fall_predictor.learning.intervals import (bootstrap_mean_interval, wilson_interval,
                                               wilson_upper_bound)
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


#: How a budget is checked (method §11 "A budget that holds"): ``'point'``, on the pooled
#: held-out FPR; ``'ucb'``, on its one-sided Wilson upper confidence bound at a stated level.
FPR_RULES = ('point', 'ucb')
#: The default level of the ``'ucb'`` rule's bound (one-sided).
DEFAULT_FPR_LEVEL = 0.95


def check_fpr_rule(rule: str, level: float) -> None:
    if rule not in FPR_RULES:
        raise ValueError(f'the FPR rule is one of {", ".join(FPR_RULES)}, got {rule!r}')
    if not 0.5 <= level < 1.0:
        raise ValueError(f'the FPR bound\'s level must be in [0.5, 1), got {level!r}')


def fpr_bound(pooled: PooledFigures, rule: str = 'point', level: float = DEFAULT_FPR_LEVEL) -> float:
    """The FPR a budget is checked on: the pooled FPR (``'point'``) or its one-sided Wilson
    upper bound at ``level`` (``'ucb'``: 1.0 with no balanced trajectory)."""
    check_fpr_rule(rule, level)
    if rule == 'point':
        return pooled.fpr
    return wilson_upper_bound(pooled.n_false_positives, pooled.n_balanced, level)


def fpr_rule_text(rule: str, level: float = DEFAULT_FPR_LEVEL) -> str:
    """The FPR a rule checks, in words."""
    return ('the cross-validated FPR' if rule == 'point' else
            f'the one-sided {100 * level:g} % Wilson upper bound of the cross-validated FPR')


def choose_setting(pooled: dict[Setting, PooledFigures], max_fpr: float, rule: str = 'point',
                   level: float = DEFAULT_FPR_LEVEL) -> Setting:
    """The setting with the longest pooled lead whose FPR (:func:`fpr_bound`: the pooled FPR,
    or with ``rule='ucb'`` its upper confidence bound at ``level``) is ``<= max_fpr``; if none
    qualifies, the lowest such FPR (ties: longest lead). Remaining ties: the smaller setting."""
    bound = {s: fpr_bound(p, rule, level) for s, p in pooled.items()}
    within = [s for s in pooled if bound[s] <= max_fpr + 1e-12]
    if within:
        return max(sorted(within), key=lambda s: pooled[s].tau_lead_s)
    return min(sorted(pooled), key=lambda s: (bound[s], -pooled[s].tau_lead_s))


@dataclass(frozen=True)
class NestedOperatingPoint:
    """An operating point chosen on inner folds and reported on the outer folds."""

    max_fpr: float                       #: the FPR budget of the choice
    chosen: tuple[tuple, ...]            #: per outer fold, the setting chosen (a grid's tuple)
    outer: PooledFigures                 #: the outer folds' results at their chosen settings
    selected_in_hindsight: tuple         #: what choosing on all folds would have picked
    hindsight: PooledFigures             #: its figures on all folds (optimistic)
    rule: str = 'point'                  #: how the budget was checked (:data:`FPR_RULES`)
    level: float = DEFAULT_FPR_LEVEL     #: the ``'ucb'`` rule's level


def nested_operating_point(fits: Sequence[FoldFit], max_fpr: float, rule: str = 'point',
                           level: float = DEFAULT_FPR_LEVEL) -> NestedOperatingPoint:
    """Choose "the longest lead at FPR <= ``max_fpr``" on the other folds, report each fold
    (the FPR checked by ``rule``: :func:`choose_setting`)."""
    return nested_over_grid(_per_fold_grid(fits), max_fpr, rule, level)


def nested_over_grid(grid: Mapping[int, Mapping[tuple, EvaluationResult]],
                     max_fpr: float, rule: str = 'point',
                     level: float = DEFAULT_FPR_LEVEL) -> NestedOperatingPoint:
    """:func:`nested_operating_point` over a grid given per fold: ``{fold: {setting: result}}``
    where a setting is any tuple of numbers (e.g. ``(tau_plus, decision_threshold, tau_his)``,
    a grid with a training setting and two run-time ones); every fold holds the same settings."""
    check_fpr_rule(rule, level)
    folds = sorted(grid)
    if len(folds) < 2:
        raise ValueError('nested selection needs at least 2 folds')
    settings = sorted(grid[folds[0]])
    if any(set(grid[k]) != set(settings) for k in folds):
        raise ValueError('every fold must hold the same settings')
    chosen: list[tuple] = []
    outer: list[EvaluationResult] = []
    for k in folds:
        inner = {s: pool_results([grid[j][s] for j in folds if j != k]) for s in settings}
        setting = choose_setting(inner, max_fpr, rule, level)
        chosen.append(setting)
        outer.append(grid[k][setting])
    everything = {s: pool_results([grid[j][s] for j in folds]) for s in settings}
    hindsight = choose_setting(everything, max_fpr, rule, level)
    return NestedOperatingPoint(max_fpr, tuple(chosen), pool_results(outer), hindsight,
                                everything[hindsight], rule, level)


def fixed_setting(fits: Sequence[FoldFit], setting: Setting) -> PooledFigures:
    """Figures at settings fixed in advance (e.g. the paper's own): no selection, no nesting."""
    grid = _per_fold_grid(fits)
    key = (float(setting[0]), float(setting[1]))
    if key not in grid[min(grid)]:
        raise ValueError(f'setting {setting} is not in the cross-validated grid')
    return pool_results([grid[k][key] for k in sorted(grid)])


#: FPR budgets of the nested "best lead at FPR <= x" points of the sweep report (0: the longest
#: lead without a false alarm on the other folds)
NESTED_FPR_BUDGETS = (0.0, 0.005, 0.01, 0.06, 0.46)


def _json_float(value: float):
    return float(value) if math.isfinite(value) else None


def pooled_json(pooled: PooledFigures) -> dict:
    """``pooled`` as JSON (NaN -> null; intervals as ``[low, high]``)."""
    return {'n_balanced': pooled.n_balanced, 'n_false_positives': pooled.n_false_positives,
            'fpr': _json_float(pooled.fpr), 'fpr_ci95': [_json_float(v) for v in pooled.fpr_ci95],
            'n_fallen': pooled.n_fallen, 'tau_lead_s': _json_float(pooled.tau_lead_s),
            'tau_lead_ci95': [_json_float(v) for v in pooled.tau_lead_ci95],
            'n_missed': pooled.n_missed}


def nested_report_json(fits: Sequence[FoldFit], paper_settings: dict[str, Setting],
                       budgets: Sequence[float] = NESTED_FPR_BUDGETS) -> Optional[dict]:
    """The sweep's method §11 section: nested points per FPR budget, and the paper's own settings
    (those in the grid) at fixed settings; None when there are no fold results."""
    if not fits:
        return None
    grid_settings = set(next(iter(_per_fold_grid(fits).values())))
    nested = []
    for budget in budgets:
        point = nested_operating_point(fits, budget)
        nested.append({'max_fpr': budget, 'outer': pooled_json(point.outer),
                       'chosen_per_fold': [list(s) for s in point.chosen],
                       'selected_in_hindsight': list(point.selected_in_hindsight),
                       'hindsight': pooled_json(point.hindsight)})
    fixed = {name: ({'setting': list(setting), **pooled_json(fixed_setting(fits, setting))}
                    if (float(setting[0]), float(setting[1])) in grid_settings else
                    {'setting': list(setting), 'in_grid': False})
             for name, setting in paper_settings.items()}
    return {'rule': 'per outer fold, the longest pooled lead among settings whose pooled FPR '
                    'over the other folds is <= max_fpr (else the lowest FPR); reported pooled '
                    'over the outer folds (Wilson / bootstrap 95 % intervals)',
            'nested': nested, 'paper_settings_fixed': fixed}


def nested_table_lines(document: Optional[dict]) -> list[str]:
    """Markdown lines for ``table.md`` from :func:`nested_report_json`'s document."""
    if document is None:
        return []

    def fig(pooled: dict) -> str:
        if pooled.get('fpr') is None or pooled.get('tau_lead_s') is None:
            return '— | —'
        return (f"{pooled['fpr']:.3f} [{pooled['fpr_ci95'][0]:.3f}, {pooled['fpr_ci95'][1]:.3f}] | "
                f"{pooled['tau_lead_s']:.2f} [{pooled['tau_lead_ci95'][0]:.2f}, "
                f"{pooled['tau_lead_ci95'][1]:.2f}]")

    lines = ['', '## Nested selection and fixed settings (method §11)', '',
             f"Rule: {document['rule']}. Hindsight = chosen and reported on all folds (optimistic).",
             '', '| operating point | FPR [95 % CI] | tau_lead [s] [95 % CI] | misses | settings chosen |',
             '|---|---|---|---|---|']
    for entry in document['nested']:
        outer, hind = entry['outer'], entry['hindsight']
        chosen = sorted({tuple(s) for s in entry['chosen_per_fold']})
        lines.append(f"| best lead at FPR ≤ {entry['max_fpr']} (nested) | {fig(outer)} | "
                     f"{outer['n_missed']}/{outer['n_fallen']} | "
                     + ', '.join(f'({a:+.2f}, {b:.3f})' for a, b in chosen) + ' |')
        lines.append(f"| same, hindsight | {fig(hind)} | {hind['n_missed']}/{hind['n_fallen']} | "
                     f"({entry['selected_in_hindsight'][0]:+.2f}, "
                     f"{entry['selected_in_hindsight'][1]:.3f}) |")
    for name, entry in document['paper_settings_fixed'].items():
        setting = f"({entry['setting'][0]:+.2f}, {entry['setting'][1]:.3f})"
        if entry.get('in_grid') is False:
            lines.append(f'| {name} settings (fixed) | not in the grid | | | {setting} |')
        else:
            lines.append(f"| {name} settings (fixed) | {fig(entry)} | "
                         f"{entry['n_missed']}/{entry['n_fallen']} | {setting} |")
    return lines
