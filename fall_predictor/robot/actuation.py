"""The joint servos of the humanoid: PD torque control with the limits of real drives.

Every joint is driven by an electric motor through a reduction gear, closed by a joint-level
PD loop at 1 kHz, as on a position-controlled humanoid:

    tau = Kp (q_target - q) - Kd dq           [N m]

limited by the drive's torque-speed envelope: at most ``effort_nm`` at standstill, falling
linearly to zero at the joint's rated speed ``velocity_rad_s`` (the URDF limits) in the
direction of motion, so no joint can be driven faster than its rated speed. Braking torque
(against the motion) is limited by the effort only. Two passive effects are simulated as
physics, not as control: viscous joint friction ``damping_nms`` and the rotor's reflected
inertia ``armature_kgm2`` (N^2 J_rotor).

Gains are per joint group. They were chosen so that (1) the stance leg deflects by less than
~1.5 deg under the robot's weight (Kp of the hip, knee and ankle pitch joints several times the
inverted-pendulum gravity stiffness m g h ~ 250 N m/rad of this 42 kg robot), (2) each loop is
near critically damped on the inertia it drives when its limb is in the air, with the
reflected armature included (damping ratio 0.5 to 1), and (3) the explicit 1 ms loop is stable
on that inertia (Kd dt / I < 1 and sqrt(Kp / I) dt < 0.5). The table is the robot profile's
(``servo_gains``), shown in the README.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from fall_predictor.profiles.profile import RobotProfile, ServoGains
from fall_predictor.profiles import asimo_like_urdf as rm


#: Joint group (the joint's name without its side prefix) -> servo gains: the robot profile's.
SERVO_GAINS: dict[str, ServoGains] = rm.PROFILE.servo_gains


def joint_group(joint_name: str) -> str:
    """'l_knee_pitch' -> 'knee_pitch'; 'head_pan' -> 'head_pan'."""
    return joint_name[2:] if joint_name[:2] in ('l_', 'r_') else joint_name


@dataclass(frozen=True)
class ServoArrays:
    """The servo table as arrays in ``model.JOINT_NAMES`` order."""

    kp: np.ndarray
    kd: np.ndarray
    damping: np.ndarray
    armature: np.ndarray
    effort: np.ndarray
    velocity: np.ndarray


def servo_arrays(gain_scale: float = 1.0, profile: Optional[RobotProfile] = None,
                 joint_names: Optional[Sequence[str]] = None) -> ServoArrays:
    """Per-joint arrays of a robot's servos (its profile's gains, its URDF's effort and velocity
    limits) in ``joint_names`` order (default: the URDF's); ``gain_scale`` scales Kp and Kd."""
    if not gain_scale > 0:
        raise ValueError(f'gain_scale must be > 0, got {gain_scale!r}')
    profile = profile or rm.PROFILE
    limits = _urdf_limits(profile.urdf_path)
    names = tuple(joint_names) if joint_names is not None else tuple(limits)
    gains = [profile.gains_for(name) for name in names]
    return ServoArrays(
        kp=gain_scale * np.array([g.kp_nm_per_rad for g in gains]),
        kd=gain_scale * np.array([g.kd_nms_per_rad for g in gains]),
        damping=np.array([g.damping_nms for g in gains]),
        armature=np.array([g.armature_kgm2 for g in gains]),
        effort=np.array([limits[n][0] for n in names]),
        velocity=np.array([limits[n][1] for n in names]))


def _urdf_limits(path) -> dict[str, tuple[float, float]]:
    """Joint name -> (effort [N m], velocity [rad/s]) of every movable joint, in URDF order."""
    import xml.etree.ElementTree as ET
    out = {}
    for joint in ET.parse(path).getroot().iter('joint'):
        if joint.get('type') in ('revolute', 'continuous', 'prismatic'):
            limit = joint.find('limit')
            out[joint.get('name')] = (float(limit.get('effort')), float(limit.get('velocity')))
    return out


def servo_torques(servo: ServoArrays, q_target: np.ndarray, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Motor torques [N m] of the PD loops within the drives' torque-speed envelope."""
    tau = servo.kp * (q_target - q) - servo.kd * dq
    # Torque that drives the motion: the envelope shrinks linearly to 0 at the rated speed.
    # (np.maximum / np.minimum: np.clip's result, without its ~5 us of argument handling a call.)
    driving = np.maximum(servo.effort * (1.0 - np.abs(dq) / servo.velocity), 0.0)
    upper = np.where(dq > 0.0, driving, servo.effort)
    lower = np.where(dq < 0.0, -driving, -servo.effort)
    return np.minimum(np.maximum(tau, lower), upper)
