"""Rotations as unit quaternions (x, y, z, w), in plain floats: the state estimator's attitude
filter (method §10) and the simulated IMU's attitude error.

Float tuples rather than numpy arrays because the estimator runs these a few times per 1 kHz
sample: a quaternion product costs ~1 us in floats, a numpy call on a 4-vector about as much
before any arithmetic.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

Quaternion = tuple[float, float, float, float]

IDENTITY: Quaternion = (0.0, 0.0, 0.0, 1.0)


def multiply(a: Sequence[float], b: Sequence[float]) -> Quaternion:
    """The Hamilton product ``a b``: rotation ``b`` first, then ``a``."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def conjugate(q: Sequence[float]) -> Quaternion:
    """The inverse rotation of a unit quaternion."""
    x, y, z, w = q
    return (-x, -y, -z, w)


def normalized(q: Sequence[float]) -> Quaternion:
    """``q`` scaled to unit norm (``q`` must not be zero)."""
    x, y, z, w = q
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return (x / n, y / n, z / n, w / n)


def from_rotation_vector(vx: float, vy: float, vz: float) -> Quaternion:
    """The rotation by ``|v|`` [rad] about ``v`` (the exponential map)."""
    a = math.sqrt(vx * vx + vy * vy + vz * vz)
    if a < 1e-12:
        return (0.5 * vx, 0.5 * vy, 0.5 * vz, 1.0)        # first order: exact to ~1e-25
    s = math.sin(a / 2) / a
    return (vx * s, vy * s, vz * s, math.cos(a / 2))


def rotation_vector(q: Sequence[float]) -> tuple[float, float, float]:
    """The rotation vector [rad] of a unit quaternion, the angle in [0, pi] (the logarithm)."""
    x, y, z, w = q
    if w < 0.0:                                             # q and -q: the same rotation
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        return (2.0 * x, 2.0 * y, 2.0 * z)
    k = 2.0 * math.atan2(s, w) / s
    return (k * x, k * y, k * z)


def matrix(q: Sequence[float]) -> np.ndarray:
    """The rotation matrix of a unit quaternion."""
    x, y, z, w = q
    return np.array([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
                     2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                     2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]).reshape(3, 3)


def yaw(q: Sequence[float]) -> float:
    """The heading [rad] of a unit quaternion: the angle of its x axis seen from above."""
    x, y, z, w = q
    return math.atan2(2 * (x * y + z * w), 1 - 2 * (y * y + z * z))


def about_z(angle_rad: float) -> Quaternion:
    """The rotation by ``angle_rad`` about the z axis."""
    return (0.0, 0.0, math.sin(angle_rad / 2), math.cos(angle_rad / 2))
