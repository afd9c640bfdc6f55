"""Hindsight labels (method §4) and the training selection and weights (method §8).

Labels are made on trajectories run with the balance controller throughout:

* BALANCED: every state before the push onset, and every state of a trajectory that never
  falls;
* FALLING: on a trajectory that falls, every state from the push onset ``t_push`` up to, not
  including, the first fallen state ``t_fallen``;
* FALLEN: from ``t_fallen`` on.

Times are simulation seconds and are compared with the sample times as they are: pass times
taken from the trajectory's own time array.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from fall_predictor.monitor.records import BALANCED, FALLEN, FALLING, TrajectoryFeatures

def label_states(t: np.ndarray, t_push: float, t_fallen: Optional[float]) -> np.ndarray:
    """State class per sample (int8: BALANCED, FALLING, FALLEN) of one trajectory.

    ``t_fallen`` is None on a trajectory that never falls (then every state is BALANCED).
    """
    t = np.asarray(t, dtype=float)
    labels = np.full(t.shape, BALANCED, dtype=np.int8)
    if t_fallen is None:
        return labels
    if t_fallen < t_push:
        raise ValueError(f't_fallen={t_fallen} precedes t_push={t_push}: the robot fell '
                         'before the push, the trajectory cannot be labelled')
    labels[t >= t_push] = FALLING
    labels[t >= t_fallen] = FALLEN
    return labels


def training_mask_and_weights(traj: TrajectoryFeatures, tau_plus_s: float,
                              balanced_weight: float = 4.0, falling_weight: float = 1.0
                              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which samples of ``traj`` to train on, their labels and weights (method §8).

    Returns ``mask`` (N,) bool, ``y`` (N,) int8 state labels for all samples (as
    :func:`label_states`), and ``w`` (N,) float weights, zero outside the mask. Trained on:
    every BALANCED state with ``balanced_weight``; FALLING states only at
    ``t_height_drop + tau_plus_s <= t < t_fallen`` with ``falling_weight``. ``tau_plus_s`` [s]
    may be negative; the window never reaches before ``t_push`` since earlier states are
    balanced. FALLEN states are never trained on.
    """
    if traj.fallen and (traj.t_fallen is None or traj.t_height_drop is None):
        raise ValueError(f'trajectory {traj.trajectory_id} fell but lacks t_fallen or '
                         't_height_drop')
    y = label_states(traj.t, traj.t_push, traj.t_fallen if traj.fallen else None)
    mask = y == BALANCED
    if traj.fallen:
        mask |= (y == FALLING) & (traj.t >= traj.t_height_drop + tau_plus_s)
    w = np.where(mask, np.where(y == BALANCED, balanced_weight, falling_weight), 0.0)
    return mask, y, w
