"""The sweep's figures (PNG): the Fig. 10 analogue (tau_lead against FPR for every predictor,
the Pareto fronts of the learned predictors and the baselines, the paper's FP-L1..3), the
Fig. 11 analogue (FPR, tau_lead and rule size against tau_plus) and the learning curve.
Each file is written atomically (:func:`fall_predictor.monitor.fileio.atomic_output`).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from fall_predictor.learning.baselines import pareto_front
from fall_predictor.learning.crossval import SweepPoint
from fall_predictor.learning.evaluation import BaselineCurves
from fall_predictor.learning.selection import PaperPredictor
from fall_predictor.learning.sweep_results import SweepConfig
from fall_predictor.monitor.fileio import atomic_output


def save_figure(fig: Any, path: Path) -> None:
    """Write ``fig`` to ``path`` (its suffix gives the format) atomically, then close it."""
    import matplotlib.pyplot as plt

    with atomic_output(path) as temporary:
        fig.savefig(temporary, dpi=110)
    plt.close(fig)


def plot_sweep(out_dir: Path, points: Sequence[SweepPoint], pareto: Sequence[SweepPoint],
               selected: Sequence[tuple[PaperPredictor, SweepPoint]],
               learning_curve: Sequence[SweepPoint], baselines: BaselineCurves,
               config: SweepConfig) -> list[Path]:
    """Write the sweep's PNGs: ``fig10_tradeoff.png`` (tau_lead against FPR for every
    predictor, the Pareto front, the baselines and the paper's FP-L1..3),
    ``fig11_parameters.png`` (FPR, tau_lead, rule size against tau_plus, a line per tau_his)
    and, with a learning curve, ``fig11_learning_curve.png``. Returns the paths."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    paths = []
    markers = ('o', 's', '^')
    # Fig. 10: trade-off.
    fig, ax = plt.subplots(figsize=(10.0, 5.5))
    tau_plus_values = sorted({p.tau_plus_s for p in points})
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(tau_plus_values)))
    for colour, tau_plus in zip(colours, tau_plus_values):
        group = [p for p in points if p.tau_plus_s == tau_plus]
        ax.scatter([p.fpr for p in group], [p.tau_lead_s for p in group], s=14, color=colour,
                   label=f'learned, tau+ = {tau_plus:+.2f} s')
    # Fronts as steps: between two front points the better lead needs the higher FPR.
    ax.plot([p.fpr for p in pareto], [p.tau_lead_s for p in pareto], '-', color='k', lw=1.2,
            drawstyle='steps-post', label='Pareto front (learned)')
    for (name, curve), style, colour in zip(baselines.named().items(), ('--', ':', '-.'),
                                            ('tab:red', 'tab:orange', 'tab:brown')):
        front = pareto_front(curve)
        if front:
            ax.plot([p.fpr for p in front], [p.tau_lead_s for p in front], style, color=colour,
                    lw=1.3, drawstyle='steps-post',
                    label=f'baseline front: {name.replace("_", " ")}')
    for marker, (paper, ours) in zip(markers, selected):
        ax.scatter([paper.fpr], [paper.tau_lead_s], marker=marker, s=70, facecolors='none',
                   edgecolors='tab:blue', label=f'{paper.name} (paper)')
        ax.scatter([ours.fpr], [ours.tau_lead_s], marker=marker, s=70, color='tab:blue',
                   label=f'{paper.name} analogue')
    ax.set_xlim(-0.02, 1.02)
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel('FPR (fraction of balanced trajectories with a false alarm)')
    ax.set_ylabel('tau_lead [s]')
    ax.set_title(f'Fig. 10 analogue: {config.folds}-fold cross-validated predictors')
    ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3)
    paths.append(out_dir / 'fig10_tradeoff.png')
    fig.tight_layout()
    save_figure(fig, paths[-1])

    # Fig. 11 (left column): statistics against tau_plus.
    fig, axes = plt.subplots(3, 1, figsize=(6.5, 8.5), sharex=True)
    tau_his_values = sorted({p.tau_his_s for p in points})
    colours = plt.cm.plasma(np.linspace(0.0, 0.85, len(tau_his_values)))
    for colour, tau_his in zip(colours, tau_his_values):
        group = sorted((p for p in points if p.tau_his_s == tau_his), key=lambda p: p.tau_plus_s)
        x = [p.tau_plus_s for p in group]
        axes[0].plot(x, [p.fpr for p in group], '.-', color=colour, label=f'tau_his = {tau_his:g} s')
        axes[1].plot(x, [p.tau_lead_s for p in group], '.-', color=colour)
    by_tau_plus = {p.tau_plus_s: p.mean_rule_size for p in points}
    axes[2].plot(sorted(by_tau_plus), [by_tau_plus[k] for k in sorted(by_tau_plus)], '.-', color='k')
    for marker, (paper, ours) in zip(markers, selected):
        for ax, value in zip(axes, (ours.fpr, ours.tau_lead_s, ours.mean_rule_size)):
            ax.scatter([ours.tau_plus_s], [value], marker=marker, s=60, facecolors='none',
                       edgecolors='tab:blue', zorder=5)
        axes[0].annotate(paper.name, (ours.tau_plus_s, ours.fpr), fontsize=7,
                         textcoords='offset points', xytext=(4, 4))
    axes[0].set_ylabel('FPR')
    axes[1].set_ylabel('tau_lead [s]')
    axes[2].set_ylabel('mean rule size')
    axes[2].set_xlabel('tau_plus [s]')
    axes[0].legend(fontsize=6.5, ncol=2)
    axes[0].set_title('Fig. 11 analogue (rule size does not depend on tau_his)')
    for ax in axes:
        ax.grid(alpha=0.3)
    paths.append(out_dir / 'fig11_parameters.png')
    fig.tight_layout()
    save_figure(fig, paths[-1])

    # Fig. 11 (right column): learning curve.
    if learning_curve:
        fig, axes = plt.subplots(3, 1, figsize=(5.5, 8.5), sharex=True)
        n = [p.n_train for p in learning_curve]
        axes[0].errorbar(n, [p.fpr for p in learning_curve],
                         yerr=[p.fpr_std for p in learning_curve], fmt='o-', capsize=3)
        axes[1].errorbar(n, [p.tau_lead_s for p in learning_curve],
                         yerr=[p.tau_lead_std_s for p in learning_curve], fmt='o-', capsize=3)
        axes[2].plot(n, [p.mean_rule_size for p in learning_curve], 'o-')
        axes[0].set_ylabel('FPR')
        axes[1].set_ylabel('tau_lead [s]')
        axes[2].set_ylabel('mean rule size')
        axes[2].set_xlabel('training trajectories')
        axes[0].set_title(f'learning curve: tau_plus {config.learning_curve_tau_plus_s} s, '
                          f'tau_his {config.learning_curve_tau_his_s} s')
        for ax in axes:
            ax.grid(alpha=0.3)
        paths.append(out_dir / 'fig11_learning_curve.png')
        fig.tight_layout()
        save_figure(fig, paths[-1])
    return paths
