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


def from_matrix(r) -> Quaternion:
    """The unit quaternion (w >= 0) of a rotation matrix, to the matrix's own precision.

    Shepperd's method: the largest of |x|, |y|, |z|, |w| from the diagonal (a square root of a
    number >= 1), the others from the off-diagonal sums divided by it. Taking each component's
    own square root instead loses half the digits of the small ones (an error of ~1e-8 where a
    component is near zero, as for a robot standing upright).
    """
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = ((float(v) for v in row) for row in r)
    trace = r00 + r11 + r22
    if trace >= max(r00, r11, r22):
        s = 2.0 * math.sqrt(1.0 + trace)                        # s = 4 w
        q = ((r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s, 0.25 * s)
    elif r00 >= r11 and r00 >= r22:
        s = 2.0 * math.sqrt(max(1.0 + r00 - r11 - r22, 0.0))   # s = 4 x
        q = (0.25 * s, (r01 + r10) / s, (r02 + r20) / s, (r21 - r12) / s)
    elif r11 >= r22:
        s = 2.0 * math.sqrt(max(1.0 - r00 + r11 - r22, 0.0))   # s = 4 y
        q = ((r01 + r10) / s, 0.25 * s, (r12 + r21) / s, (r02 - r20) / s)
    else:
        s = 2.0 * math.sqrt(max(1.0 - r00 - r11 + r22, 0.0))   # s = 4 z
        q = ((r02 + r20) / s, (r12 + r21) / s, 0.25 * s, (r10 - r01) / s)
    return normalized(q if q[3] >= 0.0 else tuple(-v for v in q))


def yaw(q: Sequence[float]) -> float:
    """The heading [rad] of a unit quaternion: the angle of its x axis seen from above."""
    x, y, z, w = q
    return math.atan2(2 * (x * y + z * w), 1 - 2 * (y * y + z * z))


def about_z(angle_rad: float) -> Quaternion:
    """The rotation by ``angle_rad`` about the z axis."""
    return (0.0, 0.0, math.sin(angle_rad / 2), math.cos(angle_rad / 2))


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """The rotation of URDF's fixed-axis roll, pitch, yaw [rad]: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])
