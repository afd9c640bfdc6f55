"""The robot description as the state estimator uses it: a Pinocchio model of the URDF with the
sole frames, the joints and their limits, and the frames named by the sensors' messages.

The sole frames (origin at the centre of the sole's underside, x forward, z up, method §10) come
from the URDF when it has them, else from the robot profile: a frame fixed to a link at a given
offset, added to the model. A sensor names its frame in its messages (``header.frame_id``); the
frame must be a frame of the description (a link, a joint or a fixed frame), else the sensor cannot
be used and :meth:`RobotDescription.frame_id` says so.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np
import pinocchio as pin

from fall_predictor.errors import TeamFileError
from fall_predictor.monitor import rotations

from fall_predictor.monitor.plausibility import JointBounds
from fall_predictor.monitor.records import SoleGeometry

SIDES = ('l', 'r')


@dataclass(frozen=True)
class SensorLayout:
    """What the monitor needs to know of a robot beyond its URDF (from its robot profile): the
    soles, the IMU frame of readings that name none, and the feet with a force/torque sensor."""

    soles: dict[str, SoleGeometry]
    imu_frame: str
    force_sensors: tuple[str, ...] = SIDES
    #: Per joint, limits in place of the URDF's (``lower_rad``, ``upper_rad``, ``velocity_rad_s``).
    joint_limits: dict = field(default_factory=dict)

    def description(self, urdf_xml: str) -> 'RobotDescription':
        """The robot description of ``urdf_xml`` with these soles and joint limits."""
        return RobotDescription(urdf_xml, self.soles, self.joint_limits)


#: The fields of one joint of a robot profile's ``monitor.joint_limits``.
JOINT_LIMIT_FIELDS = ('lower_rad', 'upper_rad', 'velocity_rad_s')


def joint_limits_of(raw: object, where: str = 'monitor.joint_limits') -> dict[str, dict[str, float]]:
    """A profile's ``monitor.joint_limits``: per joint, its own position limits [rad] and rated
    speed [rad/s] in place of the URDF's (monitor/plausibility.py: past them a sample is flagged,
    not refused). ValueError names the entry that is wrong."""
    if not isinstance(raw, dict):
        raise ValueError(f'{where} must be a mapping of joint names, got {raw!r}')
    out = {}
    for joint, fields in raw.items():
        if not isinstance(fields, dict) or set(fields) - set(JOINT_LIMIT_FIELDS):
            unknown = (sorted(set(fields) - set(JOINT_LIMIT_FIELDS)) if isinstance(fields, dict)
                       else fields)
            raise ValueError(f'{where}.{joint}: unknown keys {unknown} (known: '
                             f'{", ".join(JOINT_LIMIT_FIELDS)})')
        for key, value in fields.items():
            low = 1e-3 if key == 'velocity_rad_s' else -100.0
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= 1e3:
                raise ValueError(f'{where}.{joint}.{key} must be a number in [{low:g}, 1000], '
                                 f'got {value!r}')
        if fields.get('lower_rad', -np.inf) > fields.get('upper_rad', np.inf):
            raise ValueError(f'{where}.{joint}: lower_rad must be <= upper_rad')
        out[str(joint)] = {key: float(value) for key, value in fields.items()}
    return out


class DescriptionError(TeamFileError):
    """The robot description cannot serve the estimator; the message says why."""


class RobotDescription:
    """Pinocchio model and data of one robot, with the frames and joints the estimator needs.

    ``urdf_xml``: the URDF text (``/robot_description``); ``soles``: per side ('l', 'r');
    ``package_dirs``: where ``package://`` mesh paths resolve (meshes are not needed: only the
    kinematic tree and the inertias are read).
    """

    def __init__(self, urdf_xml: str, soles: dict[str, SoleGeometry],
                 joint_limits: Optional[dict] = None) -> None:
        try:
            self.model = pin.buildModelFromXML(urdf_xml, pin.JointModelFreeFlyer())
        except Exception as exc:  # Pinocchio raises its own types on malformed XML
            raise DescriptionError(f'cannot build a model from the URDF: {exc}') from exc
        self.soles = dict(soles)
        for side in SIDES:
            self._ensure_sole_frame(side)
        self.data = self.model.createData()
        self.sole_ids = {side: self.model.getFrameId(self.soles[side].frame) for side in SIDES}
        self.total_mass_kg = float(sum(inertia.mass for inertia in self.model.inertias))
        self.joint_names, iq, iv, continuous = [], [], [], []
        lower, upper, velocity, effort = [], [], [], []
        for j in range(2, self.model.njoints):     # 0: universe, 1: the floating base
            joint = self.model.joints[j]
            if joint.nv != 1:
                raise DescriptionError(f'joint {self.model.names[j]!r} has {joint.nv} degrees of '
                                       'freedom: only revolute, continuous and prismatic joints are '
                                       'supported')
            self.joint_names.append(self.model.names[j])
            iq.append(joint.idx_q)
            iv.append(joint.idx_v)
            is_continuous = joint.nq == 2          # cos/sin parametrisation
            continuous.append(is_continuous)
            lower.append(-np.inf if is_continuous else self.model.lowerPositionLimit[joint.idx_q])
            upper.append(np.inf if is_continuous else self.model.upperPositionLimit[joint.idx_q])
            v_max = self.model.velocityLimit[joint.idx_v]
            velocity.append(v_max if 0.0 < v_max < 1e10 else np.inf)
            effort_max = self.model.effortLimit[joint.idx_v]
            effort.append(effort_max if 0.0 < effort_max < 1e10 else np.inf)
        self.joint_names = tuple(self.joint_names)
        self.idx_q = np.array(iq, dtype=np.int64)
        self.idx_v = np.array(iv, dtype=np.int64)
        self.continuous = np.array(continuous, dtype=bool)
        self.joint_bounds = JointBounds(self.joint_names, np.array(lower), np.array(upper),
                                        np.array(velocity), np.array(effort))
        if joint_limits:
            try:
                self.joint_bounds = self.joint_bounds.with_limits(joint_limits)
            except ValueError as error:
                raise DescriptionError(str(error)) from None
        self._frame_cache: dict[str, int] = {}
        self._neutral = pin.neutral(self.model)
        self._any_continuous = bool(self.continuous.any())
        # Where the joints fill the configuration (velocity) in order, a slice: assigning through
        # it costs a third of assigning through an index array, once per sample.
        self._q_index = slice_if_consecutive(self.idx_q)
        self._v_index = slice_if_consecutive(self.idx_v)

    def _ensure_sole_frame(self, side: str) -> None:
        sole = self.soles[side]
        if self.model.existFrame(sole.frame):
            return
        if sole.link is None or not self.model.existFrame(sole.link):
            raise DescriptionError(
                f'the URDF has no frame {sole.frame!r} and the robot profile gives no link of the '
                f'URDF to put it on (link {sole.link!r}): the estimator needs both sole frames')
        parent = self.model.frames[self.model.getFrameId(sole.link)]
        placement = parent.placement * pin.SE3(rotations.rpy_matrix(*sole.origin_rpy),
                                               np.asarray(sole.origin_xyz, dtype=float))
        self.model.addFrame(pin.Frame(sole.frame, parent.parentJoint, self.model.getFrameId(sole.link),
                                      placement, pin.FrameType.OP_FRAME))

    def frame_id(self, name: str, sensor: str) -> int:
        """The model's id of the frame ``name`` a ``sensor`` reports in; DescriptionError if the
        description has no such frame."""
        cached = self._frame_cache.get(name)
        if cached is not None:
            return cached
        if not name or not self.model.existFrame(name):
            raise DescriptionError(f'{sensor} frame {name!r} is not a frame of the robot description')
        self._frame_cache[name] = frame = self.model.getFrameId(name)
        return frame

    def joint_order(self, names: Sequence[str]) -> np.ndarray:
        """Indices into :attr:`joint_names` of ``names`` (DescriptionError for an unknown one)."""
        index = {n: i for i, n in enumerate(self.joint_names)}
        unknown = [n for n in names if n not in index]
        if unknown:
            raise DescriptionError(f'joints {unknown} are not in the robot description')
        return np.array([index[n] for n in names], dtype=np.int64)

    def velocity(self, dq_joints: np.ndarray) -> np.ndarray:
        """The full velocity (the base not moving) for joint velocities in :attr:`joint_names`
        order."""
        v = np.zeros(self.model.nv)
        v[self._v_index] = dq_joints
        return v

    def configuration(self, q_joints: np.ndarray) -> np.ndarray:
        """The full configuration (base at the origin, identity orientation) for joint positions in
        :attr:`joint_names` order (continuous joints as cos, sin)."""
        q = self._neutral.copy()
        if not self._any_continuous:
            q[self._q_index] = q_joints
            return q
        regular = ~self.continuous
        q[self.idx_q[regular]] = q_joints[regular]
        angles = q_joints[self.continuous]
        q[self.idx_q[self.continuous]] = np.cos(angles)
        q[self.idx_q[self.continuous] + 1] = np.sin(angles)
        return q


def slice_if_consecutive(index: np.ndarray):
    """``index`` as a slice when it counts up by one, else ``index`` itself."""
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index
