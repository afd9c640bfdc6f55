"""How a recorded trajectory ended: its first fallen state, the start of its final descent, and
whether a trajectory that did not fall had settled when its recording ended.

These times annotate every trajectory in a dataset's index (``t_fallen``, ``t_height_drop``);
the hindsight labels of :mod:`fall_predictor.learning.labels` are made from them. Times are
simulation seconds taken from the trajectory's own time array.

A trajectory is balanced only if its horizon was long enough for the robot to settle (method
§4): :func:`unsettled_at_horizon` finds the ones whose recording ended while the robot was still
moving far faster than it walked, typically mid-fall (their outcome is unknown, not balanced).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from fall_predictor.monitor.records import FALLEN_COM_HEIGHT_M

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


#: :func:`unsettled_at_horizon`: the stretch at the end of a recording that is checked [s],
SETTLE_TAIL_S = 0.1
#: the factor over the walking level (the 99th percentile of the horizontal momentum's magnitude
#: before the push) that the momentum must stay under in that stretch (walking robots' settled
#: recordings stay under 1.2 on both shipped robots),
SETTLE_MOMENTUM_FACTOR = 1.5
#: and a floor [m/s, times the robot's mass]: a robot that stood still before the push has a
#: walking level of sensor noise alone, which a settled sway exceeds.
SETTLE_MOMENTUM_FLOOR_MPS = 0.1


def unsettled_at_horizon(t: np.ndarray, horizontal_momentum: np.ndarray, t_push: float,
                         mass_kg: float) -> Optional[str]:
    """Why a trajectory that did not fall had not settled when its recording ended, or None.

    ``horizontal_momentum`` (N, 2) [kg m/s] per sample at times ``t`` [s]. Unsettled: over the
    last :data:`SETTLE_TAIL_S` the momentum's magnitude exceeds both
    :data:`SETTLE_MOMENTUM_FACTOR` times its walking level (before ``t_push``) and
    :data:`SETTLE_MOMENTUM_FLOOR_MPS` times ``mass_kg``.
    """
    t = np.asarray(t, dtype=float)
    magnitude = np.hypot(*np.asarray(horizontal_momentum, dtype=float).T)
    before = t < t_push
    if not before.any():
        return None
    walking = float(np.percentile(magnitude[before], 99))
    bound = max(SETTLE_MOMENTUM_FACTOR * walking, SETTLE_MOMENTUM_FLOOR_MPS * mass_kg)
    end = float(magnitude[t >= t[-1] - SETTLE_TAIL_S].max())
    if end <= bound:
        return None
    return (f'its recording ended {t[-1] - t_push:.2f} s after the push with the horizontal '
            f'momentum at {end:.1f} kg m/s, above {bound:.1f} ({SETTLE_MOMENTUM_FACTOR:g} x its '
            f'walking level {walking:.1f}): still moving, its outcome is unknown')
