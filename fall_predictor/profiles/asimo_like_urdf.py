"""The ASIMO-like humanoid of method §1: its links, joints and masses, and its URDF.

The robot's profile (``profiles/asimo_like/profile.yaml``) holds what the rest of the package
knows of it (total mass, soles, IMU, gains); the tables below are the geometry of its links, from
which ``python -m fall_predictor.profiles.asimo_like_urdf`` writes the profile's two URDFs (a test checks they
are up to date). The controller reads its leg geometry back from the URDF, as it does for any
robot (robot/leg_geometry.py).

Frames: x forward, y left, z up. The base link is the torso (pelvis and trunk are one rigid
body: the robot has no waist joint); its frame origin is the midpoint between the hip joints,
``HIP_DROP_M`` above them. Leg joint axes intersect at the hip and at the ankle, so the legs
have a closed-form inverse kinematics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape

from fall_predictor.profiles.profile import load_profile

PROFILE = load_profile('asimo_like')
#: The robot description (``/robot_description``, Pinocchio): with the sole frames.
URDF_PATH = PROFILE.urdf_path
#: The same robot for PyBullet, without the sole frames: PyBullet numbers joints depth-first,
#: so fixed joints under the feet would shift the joint indices (and merging them with
#: URDF_MERGE_FIXED_LINKS prints to stdout). Generated from the same tables.
SIM_URDF_PATH = PROFILE.sim_urdf_path

TOTAL_MASS_KG = PROFILE.total_mass_kg
# Leg geometry [m]
HIP_DROP_M = 0.06            # torso origin to the hip joint centre, downwards
HIP_HALF_WIDTH_M = 0.09      # lateral offset of each hip joint from the torso origin
THIGH_LENGTH_M = 0.28        # hip pitch axis to knee axis
SHANK_LENGTH_M = 0.28        # knee axis to ankle axis
_LEFT_FOOT = PROFILE.feet['l']
ANKLE_HEIGHT_M = -_LEFT_FOOT.sole_origin_in_foot_m[2]          # ankle axis above the sole
SOLE_LENGTH_M = _LEFT_FOOT.sole_length_m
SOLE_WIDTH_M = _LEFT_FOOT.sole_width_m
SOLE_THICKNESS_M = 0.04
SOLE_FORWARD_OFFSET_M = _LEFT_FOOT.sole_origin_in_foot_m[0]    # sole centre ahead of the ankle axis

LEG_JOINTS = ('hip_yaw', 'hip_roll', 'hip_pitch', 'knee_pitch', 'ankle_pitch', 'ankle_roll')
ARM_JOINTS = ('shoulder_pitch', 'shoulder_roll', 'shoulder_yaw', 'elbow_pitch', 'wrist_yaw', 'hand')
HEAD_JOINTS = ('head_pan', 'head_tilt')
SIDES = ('l', 'r')

#: All 26 joint names in URDF order: left leg, right leg, left arm, right arm, head.
JOINT_NAMES: tuple[str, ...] = (
    tuple(f'{s}_{j}' for s in SIDES for j in LEG_JOINTS)
    + tuple(f'{s}_{j}' for s in SIDES for j in ARM_JOINTS)
    + HEAD_JOINTS
)
FOOT_LINKS = tuple(PROFILE.feet[side].foot_link for side in SIDES)
#: Sole frames (massless links on fixed joints, after the 26 joints in the URDF): origin at the
#: centre of the sole's underside, axes parallel to the foot's. The ankle F/T sensors report
#: their wrenches in these frames.
SOLE_FRAMES = tuple(PROFILE.feet[side].sole_frame for side in SIDES)
#: Sole frame origin in the foot link frame (the ankle centre) [m].
SOLE_ORIGIN_IN_FOOT_M = _LEFT_FOOT.sole_origin_in_foot_m


@dataclass(frozen=True)
class JointSpec:
    name: str
    parent: str
    child: str
    origin_xyz: tuple[float, float, float]
    axis: tuple[float, float, float]
    lower_rad: float
    upper_rad: float
    effort_nm: float
    velocity_rad_s: float


@dataclass(frozen=True)
class LinkSpec:
    """A link with a box (or sphere when ``radius_m`` is set) shape of uniform density."""

    name: str
    mass_kg: float
    com_xyz: tuple[float, float, float]
    size_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius_m: float = 0.0
    collision: bool = True
    rgba: str = '0.85 0.85 0.88 1'

    def inertia_diagonal(self) -> tuple[float, float, float]:
        m = self.mass_kg
        if self.radius_m > 0:
            i = 0.4 * m * self.radius_m ** 2
            return (i, i, i)
        x, y, z = self.size_xyz
        # Small links without a visible shape still need a physically plausible inertia.
        x, y, z = max(x, 0.04), max(y, 0.04), max(z, 0.04)
        return (m * (y * y + z * z) / 12.0, m * (x * x + z * z) / 12.0, m * (x * x + y * y) / 12.0)


def _leg(side: str) -> tuple[list[LinkSpec], list[JointSpec]]:
    s = 1.0 if side == 'l' else -1.0
    p = f'{side}_'
    # Hip roll: abduction (leg outward) is positive for the left leg, negative for the right.
    roll_lo, roll_hi = (-0.35, 0.8) if side == 'l' else (-0.8, 0.35)
    links = [
        LinkSpec(p + 'hip_yaw_link', 0.5, (0, 0, 0), (0.06, 0.06, 0.06), collision=False),
        LinkSpec(p + 'hip_roll_link', 0.6, (0, 0, 0), (0.07, 0.07, 0.07), collision=False),
        LinkSpec(p + 'thigh', 4.4, (0, 0, -0.12), (0.10, 0.09, 0.26)),
        LinkSpec(p + 'shank', 2.5, (0, 0, -0.12), (0.08, 0.07, 0.26)),
        LinkSpec(p + 'ankle_link', 0.3, (0, 0, 0), (0.05, 0.05, 0.05), collision=False),
        LinkSpec(p + 'foot', 1.2, (SOLE_FORWARD_OFFSET_M, 0, -ANKLE_HEIGHT_M + SOLE_THICKNESS_M / 2),
                 (SOLE_LENGTH_M, SOLE_WIDTH_M, SOLE_THICKNESS_M), rgba='0.3 0.3 0.35 1'),
    ]
    joints = [
        JointSpec(p + 'hip_yaw', 'torso', p + 'hip_yaw_link', (0, s * HIP_HALF_WIDTH_M, -HIP_DROP_M),
                  (0, 0, 1), -0.6, 0.6, 80.0, 6.0),
        JointSpec(p + 'hip_roll', p + 'hip_yaw_link', p + 'hip_roll_link', (0, 0, 0),
                  (1, 0, 0), roll_lo, roll_hi, 180.0, 6.0),
        JointSpec(p + 'hip_pitch', p + 'hip_roll_link', p + 'thigh', (0, 0, 0),
                  (0, 1, 0), -1.9, 0.6, 180.0, 7.0),
        JointSpec(p + 'knee_pitch', p + 'thigh', p + 'shank', (0, 0, -THIGH_LENGTH_M),
                  (0, 1, 0), 0.0, 2.5, 220.0, 8.0),
        JointSpec(p + 'ankle_pitch', p + 'shank', p + 'ankle_link', (0, 0, -SHANK_LENGTH_M),
                  (0, 1, 0), -1.2, 1.0, 150.0, 7.0),
        JointSpec(p + 'ankle_roll', p + 'ankle_link', p + 'foot', (0, 0, 0),
                  (1, 0, 0), -0.6, 0.6, 100.0, 6.0),
    ]
    return links, joints


def _arm(side: str) -> tuple[list[LinkSpec], list[JointSpec]]:
    s = 1.0 if side == 'l' else -1.0
    p = f'{side}_'
    links = [
        LinkSpec(p + 'shoulder_pitch_link', 0.2, (0, 0, 0), (0.05, 0.05, 0.05), collision=False),
        LinkSpec(p + 'shoulder_roll_link', 0.2, (0, 0, 0), (0.05, 0.05, 0.05), collision=False),
        LinkSpec(p + 'upper_arm', 1.0, (0, 0, -0.10), (0.07, 0.07, 0.20)),
        LinkSpec(p + 'forearm', 0.7, (0, 0, -0.10), (0.06, 0.06, 0.20)),
        LinkSpec(p + 'wrist_link', 0.1, (0, 0, 0), (0.04, 0.04, 0.04), collision=False),
        LinkSpec(p + 'hand', 0.3, (0, 0, -0.05), (0.04, 0.07, 0.10)),
    ]
    roll_lo, roll_hi = (-0.3, 2.0) if side == 'l' else (-2.0, 0.3)
    joints = [
        JointSpec(p + 'shoulder_pitch', 'torso', p + 'shoulder_pitch_link', (0, s * 0.17, 0.33),
                  (0, 1, 0), -3.0, 1.5, 40.0, 6.0),
        JointSpec(p + 'shoulder_roll', p + 'shoulder_pitch_link', p + 'shoulder_roll_link', (0, 0, 0),
                  (1, 0, 0), roll_lo, roll_hi, 40.0, 6.0),
        JointSpec(p + 'shoulder_yaw', p + 'shoulder_roll_link', p + 'upper_arm', (0, 0, 0),
                  (0, 0, 1), -1.6, 1.6, 25.0, 6.0),
        JointSpec(p + 'elbow_pitch', p + 'upper_arm', p + 'forearm', (0, 0, -0.20),
                  (0, 1, 0), -2.5, 0.0, 25.0, 6.0),
        JointSpec(p + 'wrist_yaw', p + 'forearm', p + 'wrist_link', (0, 0, -0.20),
                  (0, 0, 1), -1.6, 1.6, 8.0, 6.0),
        JointSpec(p + 'hand', p + 'wrist_link', p + 'hand', (0, 0, -0.02),
                  (0, 1, 0), -0.5, 1.0, 5.0, 4.0),
    ]
    return links, joints


def _head() -> tuple[list[LinkSpec], list[JointSpec]]:
    links = [
        LinkSpec('neck_link', 0.3, (0, 0, 0.03), (0.06, 0.06, 0.06), collision=False),
        LinkSpec('head', 2.0, (0.0, 0, 0.12), radius_m=0.12),
    ]
    joints = [
        JointSpec('head_pan', 'torso', 'neck_link', (0, 0, 0.42), (0, 0, 1), -1.5, 1.5, 10.0, 4.0),
        JointSpec('head_tilt', 'neck_link', 'head', (0, 0, 0.05), (0, 1, 0), -0.5, 0.7, 10.0, 4.0),
    ]
    return links, joints


def _limb_mass() -> float:
    links = [lk for s in SIDES for lk in _leg(s)[0] + _arm(s)[0]] + _head()[0]
    return sum(lk.mass_kg for lk in links)


#: Torso (pelvis + trunk): takes the mass the limbs leave to reach the profile's total mass; its CoM
#: height above the torso origin is set so the whole-body CoM is 0.59 m in the walking posture.
TORSO = LinkSpec('torso', round(TOTAL_MASS_KG - _limb_mass(), 4), (0.0, 0.0, 0.112), (0.20, 0.30, 0.50))
TORSO_SHAPE_CENTRE_Z_M = 0.19


def all_links_and_joints() -> tuple[list[LinkSpec], list[JointSpec]]:
    links: list[LinkSpec] = [TORSO]
    joints: list[JointSpec] = []
    for part in [_leg('l'), _leg('r'), _arm('l'), _arm('r'), _head()]:
        links += part[0]
        joints += part[1]
    return links, joints


def _fmt(v) -> str:
    return ' '.join(f'{x:.6g}' for x in v)


def _shape_xml(lk: LinkSpec, origin: tuple[float, float, float]) -> str:
    if lk.radius_m > 0:
        geom = f'<sphere radius="{lk.radius_m:.6g}"/>'
    else:
        geom = f'<box size="{_fmt(lk.size_xyz)}"/>'
    return f'<origin xyz="{_fmt(origin)}" rpy="0 0 0"/><geometry>{geom}</geometry>'


def urdf_xml(sole_frames: bool = True) -> str:
    """The robot's URDF text (``sole_frames=False``: the PyBullet variant)."""
    links, joints = all_links_and_joints()
    out = ['<?xml version="1.0"?>',
           '<!-- Generated by fall_predictor.profiles.asimo_like_urdf; do not edit by hand. -->',
           '<robot name="asimo_like">',
           '  <material name="shell"><color rgba="0.85 0.85 0.88 1"/></material>']
    for lk in links:
        ixx, iyy, izz = lk.inertia_diagonal()
        shape_origin = lk.com_xyz if lk.name != 'torso' else (0.0, 0.0, TORSO_SHAPE_CENTRE_Z_M)
        out.append(f'  <link name="{escape(lk.name)}">')
        out.append(f'    <inertial><origin xyz="{_fmt(lk.com_xyz)}" rpy="0 0 0"/>'
                   f'<mass value="{lk.mass_kg:.6g}"/>'
                   f'<inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/>'
                   '</inertial>')
        if lk.collision:
            out.append(f'    <visual>{_shape_xml(lk, shape_origin)}'
                       f'<material name="{lk.name}_mat"><color rgba="{lk.rgba}"/></material></visual>')
            out.append(f'    <collision>{_shape_xml(lk, shape_origin)}</collision>')
        out.append('  </link>')
    for j in joints:
        out.append(f'  <joint name="{j.name}" type="revolute">')
        out.append(f'    <parent link="{j.parent}"/><child link="{j.child}"/>')
        out.append(f'    <origin xyz="{_fmt(j.origin_xyz)}" rpy="0 0 0"/><axis xyz="{_fmt(j.axis)}"/>')
        out.append(f'    <limit lower="{j.lower_rad:.6g}" upper="{j.upper_rad:.6g}" '
                   f'effort="{j.effort_nm:.6g}" velocity="{j.velocity_rad_s:.6g}"/>')
        out.append('    <dynamics damping="0" friction="0"/>')
        out.append('  </joint>')
    for side, frame in zip(SIDES, SOLE_FRAMES if sole_frames else ()):
        # Massless frame links (Pinocchio makes them frames of the feet).
        out.append(f'  <link name="{frame}"><inertial><mass value="0"/>'
                   '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>')
        out.append(f'  <joint name="{frame}_fixed" type="fixed">')
        out.append(f'    <parent link="{side}_foot"/><child link="{frame}"/>')
        out.append(f'    <origin xyz="{_fmt(SOLE_ORIGIN_IN_FOOT_M)}" rpy="0 0 0"/>')
        out.append('  </joint>')
    out.append('</robot>')
    return '\n'.join(out) + '\n'


def joint_specs() -> dict[str, JointSpec]:
    return {j.name: j for j in all_links_and_joints()[1]}


def leg_length_m() -> float:
    """Hip joint centre to sole with a straight leg [m]."""
    return THIGH_LENGTH_M + SHANK_LENGTH_M + ANKLE_HEIGHT_M


def write_urdf(path: Path = URDF_PATH, sim_path: Path = SIM_URDF_PATH) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(urdf_xml())
    sim_path.write_text(urdf_xml(sole_frames=False))
    return path


if __name__ == '__main__':
    print(write_urdf())
    print(f'torso mass {TORSO.mass_kg} kg; straight leg {leg_length_m():.3f} m; '
          f'knee range for 0.5 m hip-ankle: {2 * math.degrees(math.acos(0.25 / THIGH_LENGTH_M)):.1f} deg')
