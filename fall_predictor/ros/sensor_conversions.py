"""rclpy messages of the robot's sensor topics (sensor_msgs/Imu, WrenchStamped, JointState,
std_msgs/String) to and from the records of :mod:`fall_predictor.sim.sensors` and
:mod:`fall_predictor.monitor.estimator`. Topic names, types, QoS and frames are in
:data:`fall_predictor.data.topics.SENSOR_TOPICS`."""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Quaternion, Vector3, Wrench, WrenchStamped
from sensor_msgs.msg import Imu, JointState

from fall_predictor.data.topics import IMU_FRAME, SOLE_FRAME_IDS, stamp_to_ns
from fall_predictor.ros.conversions import joint_state_to_msg, stamp


def _vec(v) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _arr(v: Vector3) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=float)


def stamp_ns(msg) -> int:
    """A stamped message's header time [ns]."""
    return stamp_to_ns(msg.header.stamp.sec, msg.header.stamp.nanosec)


def reading_to_msgs(r) -> tuple[JointState, Imu, WrenchStamped, WrenchStamped]:
    """A :class:`~fall_predictor.sim.sensors.SensorReading` as the four sensor messages."""
    joints = joint_state_to_msg(r.t, r.joint_names, r.q, r.dq, r.tau)
    imu = Imu()
    imu.header.stamp = stamp(r.t)
    imu.header.frame_id = IMU_FRAME
    x, y, z, w = (float(v) for v in r.imu_quat_xyzw)
    imu.orientation = Quaternion(x=x, y=y, z=z, w=w)
    imu.angular_velocity = _vec(r.gyro_rad_s)
    imu.linear_acceleration = _vec(r.accel_m_s2)
    wrenches = []
    for side, w6 in (('l', r.left_wrench), ('r', r.right_wrench)):
        msg = WrenchStamped()
        msg.header.stamp = stamp(r.t)
        msg.header.frame_id = SOLE_FRAME_IDS[side]
        msg.wrench = Wrench(force=_vec(w6[:3]), torque=_vec(w6[3:]))
        wrenches.append(msg)
    return joints, imu, wrenches[0], wrenches[1]


def imu_from_msg(msg: Imu) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(quaternion x, y, z, w; angular velocity [rad/s]; specific force [m/s^2])."""
    o = msg.orientation
    return (np.array([o.x, o.y, o.z, o.w], dtype=float), _arr(msg.angular_velocity),
            _arr(msg.linear_acceleration))


def wrench_from_msg(msg: WrenchStamped) -> np.ndarray:
    """(fx, fy, fz, tx, ty, tz) [N, N m]."""
    return np.concatenate([_arr(msg.wrench.force), _arr(msg.wrench.torque)])
