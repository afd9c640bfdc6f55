"""Hindsight labels (SPEC §4) and the training selection and weights (SPEC §8).

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

from .records import BALANCED, FALLEN, FALLEN_COM_HEIGHT_M, FALLING, TrajectoryFeatures

#: Default jitter tolerance of :func:`height_drop_time` [m]. The CoM of a robot held by stiff
#: joint servos in a 1 kHz contact simulation vibrates by micrometres; 0.1 mm is well above
#: that and still negligible against a fall (0.59 m -> 0.33 m) or the CoM's oscillation during
#: the gait (centimetres), so a real pause or rise of the CoM still ends the descent.
HEIGHT_DROP_TOLERANCE_M = 1e-4


def first_fallen_time(t: np.ndarray, com_z: np.ndarray, non_foot_contact: np.ndarray,
                      fallen_height_m: float = FALLEN_COM_HEIGHT_M) -> Optional[float]:
    """Time [s] of the first fallen state (CoM height below ``fallen_height_m`` [m] or a
    non-foot link on the ground), or None if the trajectory never falls."""
    fallen = (np.asarray(com_z) < fallen_height_m) | np.asarray(non_foot_contact, dtype=bool)
    if not fallen.any():
        return None
    return float(np.asarray(t)[np.argmax(fallen)])


def _index_of(t: np.ndarray, time: float) -> int:
    """Index of the sample nearest to ``time``."""
    return int(np.argmin(np.abs(t - time)))


def height_drop_time(t: np.ndarray, com_z: np.ndarray, t_fallen: float,
                     tolerance_m: float = HEIGHT_DROP_TOLERANCE_M) -> float:
    """``t_height_drop`` [s]: the instant from which the CoM height decreases monotonically
    until ``t_fallen``.

    Walks back from the fallen sample while each earlier sample is at least as high as every
    later one up to ``t_fallen``, less ``tolerance_m`` [m]; the descent starts at the highest
    sample of that stretch (the first one if several are equally high). The tolerance is
    measured against the running maximum, not sample to sample, so that jitter cannot
    accumulate into a slow rise being taken for part of the fall. With ``tolerance_m = 0``
    this is the plain non-increasing run ending at ``t_fallen``.
    """
    t = np.asarray(t, dtype=float)
    z = np.asarray(com_z, dtype=float)
    i_fallen = _index_of(t, t_fallen)
    back = z[i_fallen::-1]                          # from t_fallen back to the start
    highest_later = np.maximum.accumulate(back)     # highest sample between here and t_fallen
    broken = np.flatnonzero(back[1:] < highest_later[:-1] - tolerance_m)
    n = broken[0] + 1 if broken.size else back.size  # samples in the descent stretch
    i_start = i_fallen - n + 1
    return float(t[i_start + np.argmax(z[i_start:i_fallen + 1])])


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
    """Which samples of ``traj`` to train on, their labels and weights (SPEC §8).

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
