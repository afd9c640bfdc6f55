"""contract/cdr_encode.py: the messages a generated bag holds, packed straight to CDR, are the
bytes ``rosbags`` serializes from the message objects (an independent serializer), over random
messages (every alignment of the frame id, names and fault, empty and odd-length arrays and
contact lists), and read back by this package's decoders and by rosbags."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fall_predictor.contract import cdr, cdr_encode, messages
from fall_predictor.contract.topics import WireFormatError
from fall_predictor.data.bagio import typestore
from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading

RNG = np.random.default_rng(23)
FRAMES = ['', 'a', 'ab', 'abc', 'l_sole', 'imu_in_torso', 'ü']


def _serialized(msg, msg_type: str) -> bytes:
    return bytes(typestore().serialize_cdr(msg, msg_type))


def _stamp_ns() -> int:
    return int(RNG.integers(0, 2 ** 31 - 1)) * 1_000_000_000 + int(RNG.integers(0, 10 ** 9))


@pytest.mark.parametrize('frame_id', FRAMES)
def test_joint_states_are_rosbags_bytes_and_read_back(frame_id: str) -> None:
    types = typestore().types
    decode = cdr.JointStateDecoder()
    for n in (0, 1, 2, 3, 29):
        names = tuple('j' * int(RNG.integers(1, 9)) + str(k) for k in range(n))
        for n_velocity, n_effort in ((n, n), (0, 0), (n, 0), (int(RNG.integers(0, 5)), 3)):
            reading = JointStateReading(_stamp_ns(), names, RNG.normal(size=n), RNG.normal(size=n_velocity),
                                        RNG.normal(size=n_effort))
            data = cdr_encode.joint_state_cdr(reading, frame_id)
            assert data == _serialized(messages.joint_state_msg(types, reading, frame_id),
                                       'sensor_msgs/msg/JointState')
            back = decode(data)
            assert back.stamp_ns == reading.stamp_ns and back.names == names
            for field in ('position', 'velocity', 'effort'):
                np.testing.assert_array_equal(getattr(back, field), getattr(reading, field))


@pytest.mark.parametrize('frame_id', FRAMES)
def test_imu_and_wrenches_are_rosbags_bytes_and_read_back(frame_id: str) -> None:
    types = typestore().types
    imu = ImuReading(_stamp_ns(), frame_id, RNG.normal(size=4), RNG.normal(size=3), RNG.normal(size=3))
    data = cdr_encode.imu_cdr(imu)
    assert data == _serialized(messages.imu_msg(types, imu), 'sensor_msgs/msg/Imu')
    back = cdr.imu_reading(data)
    assert (back.stamp_ns, back.frame_id) == (imu.stamp_ns, frame_id)
    np.testing.assert_array_equal(back.orientation_xyzw, imu.orientation_xyzw)
    np.testing.assert_array_equal(back.linear_acceleration, imu.linear_acceleration)
    wrench = WrenchReading(_stamp_ns(), frame_id, RNG.normal(size=6))
    data = cdr_encode.wrench_cdr(wrench)
    assert data == _serialized(messages.wrench_msg(types, wrench), 'geometry_msgs/msg/WrenchStamped')
    np.testing.assert_array_equal(cdr.wrench_reading(data).wrench, wrench.wrench)


def _rotation(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ np.array([[c, -s, 0.0], [s, c, 0.0],
                                                                              [0.0, 0.0, 1.0]])


@pytest.mark.parametrize('frame_id', FRAMES)
@pytest.mark.parametrize('left,right', [(0, 0), (1, 0), (0, 3), (4, 2)])
def test_measurements_are_rosbags_bytes_and_decode_to_the_record(frame_id: str, left: int, right: int) -> None:
    store = typestore()
    com = np.array([0.1, -0.05, 0.8])
    m = Measurement(t=1.5, com=com, lin_mom=RNG.normal(size=3), ang_mom=RNG.normal(size=3),
                    heading=float(RNG.uniform(-3, 3)),
                    cop=np.full(3, np.nan) if left + right == 0 else np.array([0.12, -0.04, 0.0]),
                    left_contacts=np.column_stack([RNG.uniform(-0.1, 0.1, (left, 2)), RNG.uniform(0, 300, left)]),
                    right_contacts=np.column_stack([RNG.uniform(-0.1, 0.1, (right, 2)), RNG.uniform(0, 300, right)]),
                    left_foot=np.array([0.0, 0.09, 0.1]), right_foot=np.array([0.05, -0.09, -0.2]),
                    non_foot_contact=left == 1, push_force=RNG.normal(size=3), torso_rotation=_rotation(0.3))
    ns = 1_500_000_000
    data = cdr_encode.measurement_cdr(ns, frame_id, m)
    assert data == _serialized(messages.measurement_msg(store.types, ns, frame_id, m),
                               'fall_predictor/msg/Measurement')
    back = messages.measurement_from_msg(store.deserialize_cdr(data, 'fall_predictor/msg/Measurement'))
    assert (back.stamp_ns, back.frame_id, back.fault) == (ns, frame_id, '')
    for field in ('com', 'lin_mom', 'ang_mom', 'cop', 'left_contacts', 'right_contacts', 'left_foot',
                  'right_foot', 'push_force'):
        np.testing.assert_array_equal(getattr(back.measurement, field), getattr(m, field))
    np.testing.assert_allclose(back.measurement.torso_rotation, m.torso_rotation, atol=1e-15)
    assert back.measurement.non_foot_contact == m.non_foot_contact


@pytest.mark.parametrize('fault', ['x', 'stale: /imu', 'estimator: four'])
def test_a_fault_measurement_is_rosbags_bytes(fault: str) -> None:
    store = typestore()
    data = cdr_encode.measurement_cdr(7, 'odom', None, fault)
    assert data == _serialized(messages.measurement_msg(store.types, 7, 'odom', None, fault),
                               'fall_predictor/msg/Measurement')
    assert messages.measurement_from_msg(store.deserialize_cdr(data, 'fall_predictor/msg/Measurement')).fault == fault
    with pytest.raises(WireFormatError, match='needs a fault'):
        cdr_encode.measurement_cdr(7, 'odom', None)


@pytest.mark.parametrize('ns', [-1, (2 ** 31) * 1_000_000_000])
def test_stamps_outside_builtin_time_are_refused_as_the_message_types_refuse_them(ns: int) -> None:
    reading = WrenchReading(ns, '', np.zeros(6))
    with pytest.raises(WireFormatError, match='outside builtin_interfaces/Time'):
        messages.wrench_msg(typestore().types, reading)
    with pytest.raises(WireFormatError, match='outside builtin_interfaces/Time'):
        cdr_encode.wrench_cdr(reading)
