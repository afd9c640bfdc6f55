"""The robot's sensor data as the monitor reads it: one record per sensor message, and one
synchronised sample per estimate.

The per-message records mirror the ROS messages a robot's drivers publish (``sensor_msgs/JointState``,
``sensor_msgs/Imu``, ``geometry_msgs/WrenchStamped``) with the stamp as integer nanoseconds of ROS
time; :mod:`fall_predictor.monitor.sensor_sync` merges them into :class:`SensorSample`, the state
estimator's input, which the simulator's sensor model also produces. ROS-free: the nodes, the bag
readers and the simulator fill these records.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np


def _empty() -> np.ndarray:
    return np.zeros(0)


@dataclass(slots=True)
class JointStateReading:
    """One ``sensor_msgs/JointState``: any subset of the joints, in any order.

    ``velocity`` and ``effort`` are empty when the driver does not report them.
    """

    stamp_ns: int
    names: tuple[str, ...]
    position: np.ndarray            #: [rad] (prismatic joints: [m])
    velocity: np.ndarray = field(default_factory=_empty)    #: [rad/s]
    effort: np.ndarray = field(default_factory=_empty)      #: [N m]


@dataclass(slots=True)
class ImuReading:
    """One ``sensor_msgs/Imu``: attitude of ``frame_id`` in a gravity-aligned world frame, angular
    velocity and specific force (reads +g up at rest) in ``frame_id``."""

    stamp_ns: int
    frame_id: str
    orientation_xyzw: np.ndarray    #: (4,) quaternion x, y, z, w
    angular_velocity: np.ndarray    #: (3,) [rad/s]
    linear_acceleration: np.ndarray  #: (3,) [m/s^2]


@dataclass(slots=True)
class WrenchReading:
    """One ``geometry_msgs/WrenchStamped`` of a foot force/torque sensor: the ground's reaction on
    the sole, expressed in ``frame_id`` (fx, fy, fz [N], tx, ty, tz [N m])."""

    stamp_ns: int
    frame_id: str
    wrench: np.ndarray              #: (6,)


@dataclass(slots=True)
class SensorSample:
    """Every sensor at one instant: the state estimator's input (one per driving message).

    ``t`` is run time [s] (see :mod:`fall_predictor.monitor.timeline`; simulation time offline).
    Joint arrays follow ``joint_names``; ``dq`` is reported or estimated from positions; ``tau`` is
    empty when no efforts are reported. The IMU fields are in ``imu_frame`` (empty: the robot
    profile's IMU link). Wrenches are the ground's reaction on each sole, expressed in
    ``wrench_frames[side]`` (empty: the sole frame); None where that foot has no force sensor or its
    reading is missing.
    """

    t: float
    joint_names: tuple[str, ...]
    q: np.ndarray
    dq: np.ndarray
    imu_quat_xyzw: np.ndarray
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    left_wrench: Optional[np.ndarray] = None
    right_wrench: Optional[np.ndarray] = None
    tau: np.ndarray = field(default_factory=_empty)
    imu_frame: str = ''
    wrench_frames: tuple[str, str] = ('', '')
