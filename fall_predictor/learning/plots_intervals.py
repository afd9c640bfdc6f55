"""The Pareto fronts with interval bands (method §11): ``pareto_intervals.png``.

For the learned predictors, each Pareto point of the cross-validated grid is pooled over the
folds (:func:`~fall_predictor.learning.nested.fixed_setting`) and drawn with its Wilson FPR
interval (horizontal bar) and its bootstrap tau_lead interval (shaded band along the front);
the nested operating points of the learned lists and of the baselines
(``baselines_nested`` of the sweep) are drawn with both intervals as error bars.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Optional, Sequence

from fall_predictor.learning.baselines import pareto_front
from fall_predictor.learning.crossval import FoldFit
from fall_predictor.learning.nested import fixed_setting
from fall_predictor.learning.plots import save_figure


def _errorbar(ax: Any, pooled: dict, **style: Any) -> None:
    fpr, lead = pooled.get('fpr'), pooled.get('tau_lead_s')
    if fpr is None or lead is None or None in pooled['fpr_ci95'] + pooled['tau_lead_ci95']:
        return
    ax.errorbar([fpr], [lead], xerr=[[fpr - pooled['fpr_ci95'][0]], [pooled['fpr_ci95'][1] - fpr]],
                yerr=[[lead - pooled['tau_lead_ci95'][0]], [pooled['tau_lead_ci95'][1] - lead]],
                capsize=3, **style)


def plot_pareto_intervals(path: Path, fits: Sequence[FoldFit], points: Sequence[Any],
                          nested: Optional[dict], baselines_nested: Optional[dict]) -> Path:
    """Write the plot to ``path`` and return it."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9.0, 5.5))
    front = sorted(pareto_front(points), key=lambda p: p.fpr)
    pooled = [fixed_setting(fits, (p.tau_plus_s, p.tau_his_s)) for p in front]
    pooled = [p for p in pooled if p.fpr == p.fpr and p.tau_lead_s == p.tau_lead_s]
    if pooled:
        x = [p.fpr for p in pooled]
        ax.plot(x, [p.tau_lead_s for p in pooled], 'k-', marker='o', ms=3,
                label='learned front (pooled over folds)')
        ax.fill_between(x, [p.tau_lead_ci95[0] for p in pooled],
                        [p.tau_lead_ci95[1] for p in pooled], color='k', alpha=0.15,
                        step=None, label='tau_lead bootstrap 95 %')
        for p in pooled:
            ax.plot(p.fpr_ci95, [p.tau_lead_s] * 2, color='k', alpha=0.3, lw=1)
    for entry in (nested or {}).get('nested', []):
        _errorbar(ax, entry['outer'], fmt='D', color='tab:red', ms=5,
                  label='learned, nested' if entry is nested['nested'][0] else None)
    colours = {'com_height': 'tab:blue', 'momentum': 'tab:green', 'capture_point': 'tab:orange',
               'imu_tilt': 'tab:purple'}
    for name, entries in (baselines_nested or {}).items():
        for k, entry in enumerate(entries):
            _errorbar(ax, entry['outer'], fmt='s', color=colours.get(name, 'gray'), ms=4,
                      label=f'{name}, nested' if k == 0 else None)
    ax.set_xlabel('FPR (Wilson 95 %)')
    ax.set_ylabel('tau_lead [s] (bootstrap 95 % over trajectories)')
    ax.set_xlim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc='lower right')
    ax.set_title('Pareto front and nested operating points with 95 % intervals')
    save_figure(fig, path)
    return path
