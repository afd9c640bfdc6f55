"""Dataset statistics and the paper's Fig. 6-style plots (method §3)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from fall_predictor.data.dataset import IndexRow
from fall_predictor.monitor.records import (CONTACT_MODE_NAMES, N_CONTACT_MODES, STANDARD_GRAVITY_M_S2,
                                            TrajectoryFeatures)

#: Above this fraction of its standing CoM height a robot with no foot on the ground is airborne
#: while upright (the ASIMO-like robot's 0.45 m of 0.589 m; the same fraction for any robot).
UPRIGHT_COM_FRACTION = 0.45 / 0.589
#: The standing CoM height is the median over each trajectory's first this many seconds.
STANDING_WINDOW_S = 0.5
#: The ground-force peak of a touchdown is looked for this long after the foot lands [s].
TOUCHDOWN_WINDOW_S = 0.1

BALANCED_COLOUR = '#2e8b57'
FALLING_COLOUR = '#e0559a'


def _distribution(values) -> Optional[dict]:
    v = np.asarray(list(values), dtype=float)
    if v.size == 0:
        return None
    return {'n': int(v.size), 'min': float(v.min()), 'median': float(np.median(v)), 'mean': float(v.mean()),
            'p95': float(np.percentile(v, 95)), 'max': float(v.max())}


def _percentiles(values, quantiles=(50, 95, 99)) -> Optional[dict]:
    v = np.asarray(list(values), dtype=float)
    if v.size == 0:
        return None
    out = {f'p{q}': float(np.percentile(v, q)) for q in quantiles}
    out.update(n=int(v.size), max=float(v.max()))
    return out


def com_rise_m(traj: TrajectoryFeatures) -> float:
    """Highest CoM height after the push onset minus the CoM height at the onset [m]."""
    z = traj.com_height
    k = min(int(np.searchsorted(traj.t, traj.t_push - 1e-9)), len(z) - 1)
    return float(z[k:].max() - z[k])


def touchdown_force_peaks_n(traj: TrajectoryFeatures, after_push: bool = False) -> list[float]:
    """Peak total vertical ground force [N] after each swing-foot touchdown before the push
    (``after_push``: after it instead: the recovery steps).

    A touchdown is a foot whose vertical force goes from zero to positive; the peak is taken
    over :data:`TOUCHDOWN_WINDOW_S` after it, and only windows that end before the push (or
    that start after it and end within the trajectory).
    """
    if traj.foot_force_n is None:
        return []
    force = traj.foot_force_n
    total = force.sum(axis=1)
    peaks = []
    for side in range(2):
        loaded = force[:, side] > 0.0
        for k in np.flatnonzero(loaded[1:] & ~loaded[:-1]) + 1:
            end = int(np.searchsorted(traj.t, traj.t[k] + TOUCHDOWN_WINDOW_S))
            if end < len(total) and (traj.t[k] > traj.t_push if after_push
                                     else traj.t[end] < traj.t_push):
                peaks.append(float(total[k:end].max()))
    return peaks


def standing_com_height_m(trajectories: list[TrajectoryFeatures]) -> float:
    """The robot's standing CoM height [m]: the median over the trajectories' first
    :data:`STANDING_WINDOW_S`."""
    return float(np.median(np.concatenate([t.com_height[t.t <= t.t[0] + STANDING_WINDOW_S]
                                           for t in trajectories])))


def robot_credibility(trajectories: list[TrajectoryFeatures], total_mass_kg: float) -> dict:
    """How physical the simulated robot behaves: CoM rise after the push (launches), samples
    airborne while upright (CoM above :data:`UPRIGHT_COM_FRACTION` of the standing height: the
    same rule for any robot), and the ground-force peaks of unpushed touchdowns in body weights."""
    weight_n = total_mass_kg * STANDARD_GRAVITY_M_S2
    upright_m = UPRIGHT_COM_FRACTION * standing_com_height_m(trajectories) if trajectories else 0.0
    airborne = samples = 0
    peaks: list[float] = []
    for traj in trajectories:
        samples += len(traj.t)
        if traj.foot_force_n is not None:
            no_foot = traj.foot_force_n.sum(axis=1) <= 0.0
            airborne += int((no_foot & (traj.com_height > upright_m)).sum())
        peaks += touchdown_force_peaks_n(traj)
    known = all(traj.foot_force_n is not None for traj in trajectories)
    return {
        'com_rise_m': _percentiles(com_rise_m(traj) for traj in trajectories),
        'airborne_upright_fraction': airborne / samples if samples and known else None,
        'touchdown_force_peak_bw': _percentiles(p / weight_n for p in peaks),
    }


def dataset_stats(rows: list[IndexRow], trajectories: list[TrajectoryFeatures],
                  total_mass_kg: Optional[float] = None) -> dict:
    """Counts, fall fraction, duration and oracle-lead distributions, contact-mode occupancy."""
    fallen = [r for r in rows if r.fallen]
    occupancy = np.zeros(N_CONTACT_MODES)
    occupancy_falling = np.zeros(N_CONTACT_MODES)
    for traj in trajectories:
        occupancy += np.bincount(traj.mode, minlength=N_CONTACT_MODES)
        if traj.fallen:
            sel = (traj.t >= traj.t_push) & (traj.t < traj.t_fallen)
            occupancy_falling += np.bincount(traj.mode[sel], minlength=N_CONTACT_MODES)
    total = max(occupancy.sum(), 1)
    total_falling = max(occupancy_falling.sum(), 1)
    return {
        'trajectories': len(rows),
        'fallen': len(fallen),
        'fall_fraction': len(fallen) / len(rows) if rows else None,
        'samples': int(sum(r.samples for r in rows)),
        'duration_s': _distribution(r.t_end - r.t_start for r in rows),
        'oracle_lead_s': _distribution(r.t_fallen - r.t_push for r in fallen),
        'fall_after_force_end_s': _distribution(r.t_fallen - r.t_force_end for r in fallen),
        'height_drop_before_fallen_s': _distribution(r.t_fallen - r.t_height_drop for r in fallen),
        'reflex_fired_fraction': (sum(r.t_reflex is not None for r in rows) / len(rows)) if rows else None,
        'contact_mode_occupancy': {name: float(occupancy[i] / total) for i, name in enumerate(CONTACT_MODE_NAMES)},
        'contact_mode_occupancy_falling': {name: float(occupancy_falling[i] / total_falling)
                                           for i, name in enumerate(CONTACT_MODE_NAMES)},
        **(robot_credibility(trajectories, total_mass_kg) if total_mass_kg else {}),
    }


def plot_fig6(trajectories: list[TrajectoryFeatures], out_dir: Path, max_trajectories: int = 100,
              seed: int = 0) -> list[Path]:
    """Fig. 6 analogue: (a) CoM height against time after the push ends, (b) horizontal linear
    momentum (heading frame), balanced states green and falling states pink."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    chosen = list(trajectories)
    if len(chosen) > max_trajectories:
        chosen = [chosen[i] for i in sorted(rng.choice(len(chosen), max_trajectories, replace=False))]
    fig_a, ax_a = plt.subplots(figsize=(7, 4.2))
    fig_b, ax_b = plt.subplots(figsize=(5.6, 5.2))
    for traj in chosen:
        after = traj.t >= traj.t_push - 0.1
        t_rel = traj.t[after] - traj.t_force_end
        colour = FALLING_COLOUR if traj.fallen else BALANCED_COLOUR
        style = '--' if traj.fallen else '-'
        ax_a.plot(t_rel, traj.X[after, 2], style, color=colour, lw=0.7, alpha=0.75)
        ax_b.plot(traj.X[after, 3], traj.X[after, 4], style, color=colour, lw=0.6, alpha=0.7)
    ax_a.axvspan(-0.1, 0.0, color='0.85', zorder=0, label='push (0.1 s)')
    ax_a.axhline(0.33, color='k', lw=0.8, ls=':', label='fallen: 0.33 m')
    ax_a.axhline(0.48, color='0.4', lw=0.8, ls='-.', label='CoM guard: 0.48 m')
    ax_a.set_xlabel('time after the push ends [s]')
    ax_a.set_ylabel('CoM height [m]')
    for ax in (ax_a, ax_b):
        ax.plot([], [], '-', color=BALANCED_COLOUR, label='balanced')
        ax.plot([], [], '--', color=FALLING_COLOUR, label='falling')
    ax_a.legend(loc='lower left', fontsize=8)
    ax_a.set_title(f'(a) CoM height, {len(chosen)} trajectories')
    ax_b.set_xlabel('linear momentum x (sagittal) [kg m/s]')
    ax_b.set_ylabel('linear momentum y (frontal) [kg m/s]')
    ax_b.set_title('(b) horizontal linear momentum')
    ax_b.legend(loc='upper right', fontsize=8)
    ax_b.set_aspect('equal', adjustable='datalim')
    paths = [out_dir / 'fig6a_com_height.png', out_dir / 'fig6b_linear_momentum.png']
    for fig, path in zip((fig_a, fig_b), paths):
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return paths


def stats_by_cause(rows) -> dict:
    """Per cause of the index ``rows`` (data/dataset.py IndexRow.cause): runs, falls, the fall fraction, the runs whose disturbance never acted (no
    onset), the median onset-to-fall time [s] and the simulated hours of a long walk."""
    out = {}
    for cause in sorted({r.cause for r in rows}):
        mine = [r for r in rows if r.cause == cause]
        fell = [r for r in mine if r.fallen]
        delays = [r.t_fallen - r.onset_s for r in fell if r.onset_s is not None]
        out[cause] = {'runs': len(mine), 'fallen': len(fell), 'fall_fraction': len(fell) / len(mine),
                      'without_onset': sum(r.onset_s is None for r in mine) if cause != 'walk' else None,
                      'onset_to_fall_s_median': float(np.median(delays)) if delays else None,
                      'hours': round(sum(r.t_end - r.t_start for r in mine) / 3600.0, 4)}
    return out
