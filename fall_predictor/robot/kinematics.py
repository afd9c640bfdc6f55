"""Closed-form leg kinematics of the humanoid (hip yaw-roll-pitch, knee, ankle pitch-roll).

The three hip axes intersect at the hip joint centre and the two ankle axes at the ankle
centre, so the six leg angles follow from the hip and ankle poses in closed form (the
classic derivation in Kajita et al., *Introduction to Humanoid Robotics*, §2.5).
"""
from __future__ import annotations

import math

import numpy as np

from fall_predictor.profiles import asimo_like_urdf as rm

THIGH = rm.THIGH_LENGTH_M
SHANK = rm.SHANK_LENGTH_M


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def leg_ik(hip: np.ndarray, body_rot: np.ndarray, ankle: np.ndarray, foot_rot: np.ndarray,
           thigh: float = THIGH, shank: float = SHANK) -> np.ndarray:
    """Leg joint angles [rad] (hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll).

    ``hip`` is the hip joint centre, ``ankle`` the ankle joint centre (world, m); the
    rotations are world orientations of the torso and of the foot. An unreachable ankle
    (too far) gives the straight-leg solution pointing at it: the knee never hyper-extends.
    """
    r = foot_rot.T @ (hip - ankle)
    dist = float(np.linalg.norm(r))
    cos_knee = (dist * dist - thigh * thigh - shank * shank) / (2.0 * thigh * shank)
    knee = math.acos(min(1.0, max(-1.0, cos_knee)))
    ankle_pitch_inner = math.asin(min(1.0, thigh / max(dist, 1e-9) * math.sin(math.pi - knee)))
    ankle_roll = math.atan2(r[1], r[2])
    if ankle_roll > math.pi / 2:
        ankle_roll -= math.pi
    elif ankle_roll < -math.pi / 2:
        ankle_roll += math.pi
    ankle_pitch = -math.atan2(r[0], math.copysign(math.hypot(r[1], r[2]), r[2])) - ankle_pitch_inner
    hip_rot = body_rot.T @ foot_rot @ rot_x(-ankle_roll) @ rot_y(-ankle_pitch - knee)
    hip_yaw = math.atan2(-hip_rot[0, 1], hip_rot[1, 1])
    cz, sz = math.cos(hip_yaw), math.sin(hip_yaw)
    hip_roll = math.atan2(hip_rot[2, 1], -hip_rot[0, 1] * sz + hip_rot[1, 1] * cz)
    hip_pitch = math.atan2(-hip_rot[2, 0], hip_rot[2, 2])
    return np.array([hip_yaw, hip_roll, hip_pitch, knee, ankle_pitch, ankle_roll])


def leg_ik_parallel(hip: tuple[float, float, float], ankle: tuple[float, float, float],
                    yaw: float = 0.0, thigh: float = THIGH, shank: float = SHANK) -> list[float]:
    """:func:`leg_ik` for a torso and a sole with the same orientation, upright, at ``yaw``.

    Then the hip rotation reduces to roll(-ankle roll) pitch(-ankle pitch - knee) with zero
    hip yaw; plain floats, for the 1 kHz controller.
    """
    dx, dy, dz = hip[0] - ankle[0], hip[1] - ankle[1], hip[2] - ankle[2]
    c, s = math.cos(yaw), math.sin(yaw)
    rx, ry, rz = c * dx + s * dy, -s * dx + c * dy, dz
    dist = math.sqrt(rx * rx + ry * ry + rz * rz)
    cos_knee = (dist * dist - thigh * thigh - shank * shank) / (2.0 * thigh * shank)
    knee = math.acos(min(1.0, max(-1.0, cos_knee)))
    ankle_pitch_inner = math.asin(min(1.0, thigh / max(dist, 1e-9) * math.sin(math.pi - knee)))
    ankle_roll = math.atan2(ry, rz)
    if ankle_roll > math.pi / 2:
        ankle_roll -= math.pi
    elif ankle_roll < -math.pi / 2:
        ankle_roll += math.pi
    ankle_pitch = -math.atan2(rx, math.copysign(math.hypot(ry, rz), rz)) - ankle_pitch_inner
    return [0.0, -ankle_roll, -ankle_pitch - knee, knee, ankle_pitch, ankle_roll]


def leg_fk(hip: np.ndarray, body_rot: np.ndarray, q: np.ndarray,
           thigh: float = THIGH, shank: float = SHANK) -> tuple[np.ndarray, np.ndarray]:
    """Ankle centre position and foot orientation (world) for leg angles ``q``."""
    rot = body_rot @ rot_z(q[0]) @ rot_x(q[1]) @ rot_y(q[2])
    knee = hip + rot @ np.array([0.0, 0.0, -thigh])
    rot = rot @ rot_y(q[3])
    ankle = knee + rot @ np.array([0.0, 0.0, -shank])
    foot_rot = rot @ rot_y(q[4]) @ rot_x(q[5])
    return ankle, foot_rot


def hip_position(torso_pos: np.ndarray, body_rot: np.ndarray, side: str) -> np.ndarray:
    """World position of a hip joint centre from the torso origin pose."""
    s = 1.0 if side == 'l' else -1.0
    return torso_pos + body_rot @ np.array([0.0, s * rm.HIP_HALF_WIDTH_M, -rm.HIP_DROP_M])


def ankle_from_sole(sole_centre: np.ndarray, foot_rot: np.ndarray) -> np.ndarray:
    """Ankle joint centre above a sole centre point on the ground."""
    return sole_centre + foot_rot @ np.array([-rm.SOLE_FORWARD_OFFSET_M, 0.0, rm.ANKLE_HEIGHT_M])
