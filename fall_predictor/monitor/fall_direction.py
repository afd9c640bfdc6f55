"""Where the robot is falling: a heading-frame direction predicted from the features.

The monitor publishes, with each falling event, the horizontal direction in which the CoM is
expected to leave. The physical default is the instantaneous capture point of the linear
inverted pendulum, taken relative to the feature frame's origin (the CoP, method §6): the
point the CoM "aims at" is ``xi = c + v / omega`` with ``omega = sqrt(g / c_z)``; a robot
whose capture point lies at bearing ``theta`` from the CoP tips towards ``theta``.

Everything is in the feature frame (x along the pelvis heading, y to its left, z up), so the
result is a direction in the robot's heading frame, not in the world.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2

#: Feature columns used: CoM position relative to the CoP [m] and linear momentum [kg m/s].
_COM_X, _COM_Y, _COM_Z, _P_X, _P_Y = 0, 1, 2, 3, 4
#: Smallest CoM height [m] used for omega (a CoM on the ground would make omega infinite).
_MIN_HEIGHT_M = 0.05


def capture_point_direction(x: Sequence[float], mass_kg: float) -> np.ndarray:
    """Unit vector (3,) in the heading frame from the CoP towards the capture point.

    Args:
        x: the 15 features of one sample (method §6, CoP frame).
        mass_kg: total robot mass [kg], to turn the linear momentum into a CoM velocity.

    Returns:
        ``(cos theta, sin theta, 0)``; ``(nan, nan, nan)`` when the direction is undefined
        (non-finite features, or the capture point exactly on the CoP).
    """
    if not (math.isfinite(mass_kg) and mass_kg > 0.0):
        raise ValueError(f'mass_kg must be a finite number > 0, got {mass_kg!r}')
    com_x, com_y, com_z = float(x[_COM_X]), float(x[_COM_Y]), float(x[_COM_Z])
    omega = math.sqrt(STANDARD_GRAVITY_M_S2 / max(com_z, _MIN_HEIGHT_M))
    xi_x = com_x + float(x[_P_X]) / (mass_kg * omega)
    xi_y = com_y + float(x[_P_Y]) / (mass_kg * omega)
    norm = math.hypot(xi_x, xi_y)
    if not (math.isfinite(norm) and norm > 0.0):
        return np.full(3, np.nan)
    return np.array([xi_x / norm, xi_y / norm, 0.0])


def angular_error_rad(predicted: Sequence[float], actual: Sequence[float]) -> float:
    """Angle [rad] in [0, pi] between two horizontal directions (their z is ignored)."""
    a = math.atan2(float(predicted[1]), float(predicted[0]))
    b = math.atan2(float(actual[1]), float(actual[0]))
    return abs((a - b + math.pi) % (2.0 * math.pi) - math.pi)


def momentum_direction(x: Sequence[float], mass_kg: float) -> np.ndarray:
    """Unit vector (3,) in the heading frame along the horizontal linear momentum.

    Same signature as :func:`capture_point_direction` (``mass_kg`` is checked but does not
    change a direction). At trigger time the CoM already moves the way it falls, while the
    capture point relative to the CoP is dominated by the CoM's offset from a CoP that sits on
    the support edge: on 36 held-out trajectories the momentum's direction erred by 10 deg
    (median) against 34 deg for the capture point (docs/results.md).

    Returns ``(nan, nan, nan)`` for non-finite or zero horizontal momentum.
    """
    if not (math.isfinite(mass_kg) and mass_kg > 0.0):
        raise ValueError(f'mass_kg must be a finite number > 0, got {mass_kg!r}')
    px, py = float(x[_P_X]), float(x[_P_Y])
    norm = math.hypot(px, py)
    if not (math.isfinite(norm) and norm > 0.0):
        return np.full(3, np.nan)
    return np.array([px / norm, py / norm, 0.0])
