"""The robot's sensor topics in bags: joint encoders, torso IMU, ankle F/T, description.

Writes what the simulator's sensor model produces (:mod:`fall_predictor.sim.sensors`) on the
topics of :data:`fall_predictor.data.topics.SENSOR_TOPICS`, and reads them back as
:class:`~fall_predictor.monitor.estimator.SensorSample` records for the state estimator:
offline estimation runs the same estimator code over a bag that the live node runs over the
topics. The ground truth goes on ``/fall_predictor/measurement`` of the generated bags (the
layout the feature code reads); the sensor parameters are in the bag's ``custom_data``.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Optional

import numpy as np
import yaml

from fall_predictor.data.bagio import BagError, BagWriter, iter_messages
from fall_predictor.data.topics import (IMU, IMU_FRAME, LEFT_FOOT_WRENCH, RIGHT_FOOT_WRENCH, ROBOT_DESCRIPTION,
                                        SENSOR_JOINT_STATES, SENSOR_PARAMS_METADATA_KEY, SOLE_FRAME_IDS,
                                        stamp_to_ns, time_to_ns)
from fall_predictor.monitor.estimator import SensorSample

_SENSOR_TOPIC_NAMES = (SENSOR_JOINT_STATES.name, IMU.name, LEFT_FOOT_WRENCH.name, RIGHT_FOOT_WRENCH.name)


def write_sensor_params(bag: BagWriter, params: dict) -> None:
    """The sensor model's parameters, as JSON in the bag metadata."""
    bag.set_custom_data(SENSOR_PARAMS_METADATA_KEY, json.dumps(params, sort_keys=True))


def write_robot_description(bag: BagWriter, t: float, urdf: str) -> None:
    msg = bag._types['std_msgs/msg/String'](data=urdf)
    bag.write(ROBOT_DESCRIPTION.name, ROBOT_DESCRIPTION.msg_type, time_to_ns(t), msg)


def write_sensor_reading(bag: BagWriter, r) -> None:
    """One sample of every sensor (a :class:`fall_predictor.sim.sensors.SensorReading`)."""
    types = bag._types
    bag.write_joint_state(r.t, r.joint_names, r.q, r.dq, r.tau)
    vec = types['geometry_msgs/msg/Vector3']
    x, y, z, w = (float(v) for v in r.imu_quat_xyzw)
    unknown = np.zeros(9)           # covariances not provided (sensor_msgs/Imu: all zero = unknown)
    imu = types['sensor_msgs/msg/Imu'](
        header=bag._header(r.t, IMU_FRAME),
        orientation=types['geometry_msgs/msg/Quaternion'](x=x, y=y, z=z, w=w),
        orientation_covariance=unknown, angular_velocity=vec(*(float(v) for v in r.gyro_rad_s)),
        angular_velocity_covariance=unknown, linear_acceleration=vec(*(float(v) for v in r.accel_m_s2)),
        linear_acceleration_covariance=unknown)
    bag.write(IMU.name, IMU.msg_type, time_to_ns(r.t), imu)
    for spec, side, wrench in ((LEFT_FOOT_WRENCH, 'l', r.left_wrench), (RIGHT_FOOT_WRENCH, 'r', r.right_wrench)):
        if wrench is None:
            continue
        msg = types['geometry_msgs/msg/WrenchStamped'](
            header=bag._header(r.t, SOLE_FRAME_IDS[side]),
            wrench=types['geometry_msgs/msg/Wrench'](force=vec(*(float(v) for v in wrench[:3])),
                                                     torque=vec(*(float(v) for v in wrench[3:]))))
        bag.write(spec.name, spec.msg_type, time_to_ns(r.t), msg)


def _vec(v) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=float)


def read_sensor_samples(path: str | os.PathLike[str]) -> list[SensorSample]:
    """The sensor samples of a bag, one per header stamp that has joint states and IMU data
    (in stamp order); a stamp without a foot's wrench has that wrench None."""
    bag = Path(path)
    rows: dict[int, dict] = {}
    for message in iter_messages(bag, _SENSOR_TOPIC_NAMES):
        msg = message.msg
        ns = stamp_to_ns(msg.header.stamp.sec, msg.header.stamp.nanosec)
        row = rows.setdefault(ns, {})
        if message.topic == SENSOR_JOINT_STATES.name:
            row['joints'] = (tuple(msg.name), np.asarray(msg.position, dtype=float),
                             np.asarray(msg.velocity, dtype=float))
        elif message.topic == IMU.name:
            o = msg.orientation
            row['imu'] = (np.array([o.x, o.y, o.z, o.w]), _vec(msg.angular_velocity),
                          _vec(msg.linear_acceleration))
        else:
            side = 'left' if message.topic == LEFT_FOOT_WRENCH.name else 'right'
            row[side] = np.concatenate([_vec(msg.wrench.force), _vec(msg.wrench.torque)])
    samples = []
    for ns in sorted(rows):
        row = rows[ns]
        if 'joints' not in row or 'imu' not in row:
            continue
        names, q, dq = row['joints']
        if len(dq) != len(q):
            raise BagError(f'{bag}: /joint_states at {ns} ns has {len(dq)} velocities for {len(q)} positions')
        quat, gyro, acc = row['imu']
        samples.append(SensorSample(t=ns / 1e9, joint_names=names, q=q, dq=dq, imu_quat_xyzw=quat,
                                    gyro_rad_s=gyro, accel_m_s2=acc, left_wrench=row.get('left'),
                                    right_wrench=row.get('right')))
    return samples


def read_robot_description(path: str | os.PathLike[str]) -> Optional[str]:
    """The URDF recorded on ``/robot_description``, or None."""
    for message in iter_messages(Path(path), (ROBOT_DESCRIPTION.name,)):
        return str(message.msg.data)
    return None


def read_sensor_params(path: str | os.PathLike[str]) -> Optional[dict]:
    """The sensor parameters recorded in the bag metadata, or None."""
    meta = Path(path) / 'metadata.yaml'
    try:
        info = yaml.safe_load(meta.read_text())['rosbag2_bagfile_information']
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise BagError(f'{meta}: unreadable bag metadata: {exc}') from exc
    text = (info.get('custom_data') or {}).get(SENSOR_PARAMS_METADATA_KEY)
    return None if text is None else json.loads(text)


def read_imu(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bag's ``/imu/data``: header times [s] (n,), orientations (n, 4) as x, y, z, w and
    angular velocities [rad/s] (n, 3) in the IMU frame, in stamp order. A bag without IMU
    messages raises :class:`BagError`."""
    bag = Path(path)
    rows = []
    for message in iter_messages(bag, (IMU.name,)):
        msg = message.msg
        o, w = msg.orientation, msg.angular_velocity
        rows.append((stamp_to_ns(msg.header.stamp.sec, msg.header.stamp.nanosec),
                     o.x, o.y, o.z, o.w, w.x, w.y, w.z))
    if not rows:
        raise BagError(f'{bag}: no {IMU.name} messages (was it generated with --sensor-noise?)')
    a = np.array(sorted(rows), dtype=float)
    return a[:, 0] / 1e9, a[:, 1:5], a[:, 5:8]
