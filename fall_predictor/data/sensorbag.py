"""The robot's sensor topics in bags: joint encoders, IMU, foot force/torque, description.

Writes what the simulator's sensor model produces (:mod:`fall_predictor.sim.sensors`) on the
topics of :data:`fall_predictor.contract.topics.SENSOR_TOPICS`, each stream as the robot's drivers
publish it (:mod:`fall_predictor.sim.drivers`: the simulator's timing by default, or a robot's
rates, offsets, split joint states and clock), and reads them back as the sequence of readings in
the order they were received: offline estimation feeds them to the same
:class:`~fall_predictor.monitor.sensor_pipeline.SensorPipeline` the live node runs. The ground
truth goes on ``/fall_predictor/measurement`` of the generated bags; the sensor parameters and
the drivers' timing are in the bag's ``custom_data``.

A Unitree humanoid's recording (``ros2 bag record /lowstate``) is read too: each
``unitree_hg/msg/LowState`` goes through :class:`~fall_predictor.monitor.lowstate.LowStateConverter`
(the motor table of the robot's profile), its receive time the recorder's log time, exactly as the
estimator node converts it live (stream ``'lowstate'``).
"""
from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Optional, Union

import yaml

from fall_predictor.contract import cdr, messages
from fall_predictor.contract.topics import (IMU, LEFT_FOOT_WRENCH, RIGHT_FOOT_WRENCH,
                                            ROBOT_DESCRIPTION, SENSOR_JOINT_STATES,
                                            SENSOR_PARAMS_METADATA_KEY, time_to_ns)
from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.contract.unitree_hg import LOWSTATE, lowstate_from_msg
from fall_predictor.data.bagio import BagError, iter_messages
from fall_predictor.monitor.lowstate import LowStateConverter, LowStateSample
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading

Reading = Union[JointStateReading, ImuReading, WrenchReading, LowStateSample]
#: Sensor topic of each stream name of :mod:`fall_predictor.sim.drivers`, and back.
STREAM_TOPICS = {'joints': SENSOR_JOINT_STATES, 'imu': IMU, 'l': LEFT_FOOT_WRENCH,
                 'r': RIGHT_FOOT_WRENCH}
_TOPIC_STREAMS = {spec.name: stream for stream, spec in STREAM_TOPICS.items()}
#: Each stream's message, serialized (what ``rosbags`` would write for its message object).
_ENCODERS = {'joints': cdr.joint_state_cdr, 'imu': cdr.imu_cdr,
             'l': cdr.wrench_cdr, 'r': cdr.wrench_cdr}


def write_sensor_params(bag: BagWriter, params: dict) -> None:
    """The sensor model's parameters (and drivers' timing), as JSON in the bag metadata."""
    bag.set_custom_data(SENSOR_PARAMS_METADATA_KEY, json.dumps(params, sort_keys=True))


def write_robot_description(bag: BagWriter, t: float, urdf: str) -> None:
    msg = bag._types['std_msgs/msg/String'](data=urdf)
    bag.write(ROBOT_DESCRIPTION.name, ROBOT_DESCRIPTION.msg_type, time_to_ns(t), msg)


def write_sensor_message(bag: BagWriter, stream: str, reading: Reading) -> None:
    """One driver message (a stream of :mod:`fall_predictor.sim.drivers` and its reading), logged
    at its stamp."""
    spec = STREAM_TOPICS[stream]
    bag.write_raw(spec.name, spec.msg_type, reading.stamp_ns, _ENCODERS[stream](reading))


def read_sensor_messages(path: str | os.PathLike[str], robot: Optional[str] = None
                         ) -> Iterator[tuple[str, Reading]]:
    """The sensor messages of a bag in the order they were received (log time): (stream,
    reading), stream one of 'joints', 'imu', 'l', 'r', or 'lowstate' (a Unitree humanoid's, named
    by the motor table of profile ``robot``, a name or path; converted samples, a repeated
    delivery left out)."""
    convert = {'joints': messages.joint_state_reading, 'imu': messages.imu_reading,
               'l': messages.wrench_reading, 'r': messages.wrench_reading}
    converter: Optional[LowStateConverter] = None
    for message in iter_messages(Path(path), (*_TOPIC_STREAMS, LOWSTATE.name)):
        if message.topic == LOWSTATE.name:
            if converter is None:
                converter = lowstate_converter(path, robot)
            sample = converter.convert(lowstate_from_msg(message.msg), message.t_ns)
            if sample is not None:
                yield 'lowstate', sample
            continue
        stream = _TOPIC_STREAMS[message.topic]
        yield stream, convert[stream](message.msg)


def lowstate_converter(path: str | os.PathLike[str], robot: Optional[str]) -> LowStateConverter:
    """The converter of a recording's ``/lowstate``: the motor table of profile ``robot``
    (BagError when there is none to name the motors with)."""
    from fall_predictor.profiles.profile import load_profile
    profile = None if robot is None else load_profile(robot)
    if profile is None or profile.unitree_hg is None:
        raise BagError(f'{path}: {LOWSTATE.name} names its motors by index only: give the robot '
                       'profile with their table (--robot g1, or g1_12dof for the 12-joint policy)')
    return LowStateConverter(profile.unitree_hg, profile.imu_frame, profile.joint_names,
                             LOWSTATE.name, f'robot profile {profile.name}')


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


def read_imu(path: str | os.PathLike[str], robot: Optional[str] = None):
    """The bag's ``/imu/data`` (or the IMU of its ``/lowstate``, robot ``robot``): header times
    [s] (n,), orientations (n, 4) as x, y, z, w and angular velocities [rad/s] (n, 3) in the IMU
    frame, in stamp order. A bag without IMU messages raises :class:`BagError`."""
    import numpy as np
    bag = Path(path)
    imus = (r if stream == 'imu' else r.imu for stream, r in read_sensor_messages(bag, robot)
            if stream == 'imu' or (stream == 'lowstate' and r.imu is not None))
    rows = sorted((r.stamp_ns, *r.orientation_xyzw, *r.angular_velocity) for r in imus)
    if not rows:
        raise BagError(f'{bag}: no {IMU.name} messages (was it generated with --sensor-noise?)')
    a = np.array(rows, dtype=float)
    return a[:, 0] / 1e9, a[:, 1:5], a[:, 5:8]
