"""contract/cdr.py: the sensor messages read from their serialized form equal the records built
from rclpy's own deserialization, field for field, over random messages (every alignment of the
frame id, empty and odd-length arrays, changing joint names); the messages written to their
serialized form are rosbags' bytes (see the writing tests below)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, JointState

from fall_predictor.contract import cdr, messages
from fall_predictor.contract.topics import WireFormatError
from fall_predictor.data.bagio import typestore
from fall_predictor.msg import FallState
from fall_predictor.monitor.fall_monitor import (STATUS_DEGRADED, STATUS_FALLEN, STATUS_OK,
                                                 STATUS_STALE, MonitorState)
from fall_predictor.monitor.records import Measurement
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading

RNG = np.random.default_rng(7)


def _stamp(msg) -> None:
    msg.header.stamp.sec = int(RNG.integers(0, 2 ** 31 - 1))
    msg.header.stamp.nanosec = int(RNG.integers(0, 10 ** 9))
    msg.header.frame_id = 'f' * int(RNG.integers(0, 10)) + ('ü' if RNG.random() < 0.2 else '')


def _joint_state(names: list[str]) -> JointState:
    msg = JointState(name=names)
    _stamp(msg)
    for field in ('position', 'velocity', 'effort'):
        n = len(names) if RNG.random() < 0.7 else int(RNG.integers(0, 5))
        setattr(msg, field, RNG.normal(size=n).tolist())
    return msg


def _same_joint_state(a, b) -> None:
    assert a.stamp_ns == b.stamp_ns and a.names == b.names
    for field in ('position', 'velocity', 'effort'):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_joint_states_read_from_cdr_equal_rclpys_decoding() -> None:
    decoder = cdr.JointStateDecoder()
    name_sets = [[f'joint_{k}' * int(RNG.integers(1, 3)) for k in range(n)] for n in (0, 1, 7, 29)]
    for _ in range(400):
        names = name_sets[int(RNG.integers(0, len(name_sets)))]
        if RNG.random() < 0.1:                       # same count, one name changed
            names = list(names[:-1]) + ['other'] if names else names
        msg = _joint_state(list(names))
        _same_joint_state(decoder(serialize_message(msg)), messages.joint_state_reading(msg))


def test_imu_and_wrenches_read_from_cdr_equal_rclpys_decoding() -> None:
    for _ in range(200):
        imu = Imu()
        _stamp(imu)
        q, w, a = RNG.normal(size=4), RNG.normal(size=3), RNG.normal(size=3)
        imu.orientation.x, imu.orientation.y, imu.orientation.z, imu.orientation.w = q.tolist()
        imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = w.tolist()
        imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z = a.tolist()
        imu.orientation_covariance = RNG.normal(size=9).tolist()
        got, want = cdr.imu_reading(serialize_message(imu)), messages.imu_reading(imu)
        assert (got.stamp_ns, got.frame_id) == (want.stamp_ns, want.frame_id)
        for field in ('orientation_xyzw', 'angular_velocity', 'linear_acceleration'):
            np.testing.assert_array_equal(getattr(got, field), getattr(want, field))
        wrench = WrenchStamped()
        _stamp(wrench)
        f, t = RNG.normal(size=3), RNG.normal(size=3)
        wrench.wrench.force.x, wrench.wrench.force.y, wrench.wrench.force.z = f.tolist()
        wrench.wrench.torque.x, wrench.wrench.torque.y, wrench.wrench.torque.z = t.tolist()
        got, want = cdr.wrench_reading(serialize_message(wrench)), messages.wrench_reading(wrench)
        assert (got.stamp_ns, got.frame_id) == (want.stamp_ns, want.frame_id)
        np.testing.assert_array_equal(got.wrench, want.wrench)


@pytest.mark.parametrize('damage', ['big_endian', 'truncated', 'empty'])
def test_what_is_not_plain_little_endian_cdr_is_refused_for_the_general_decoder(damage: str
                                                                               ) -> None:
    data = serialize_message(_joint_state(['a', 'b', 'c']))
    data = {'big_endian': b'\x00\x00' + data[2:], 'truncated': data[:-9], 'empty': b''}[damage]
    with pytest.raises(cdr.CdrError):
        cdr.JointStateDecoder()(data)
    with pytest.raises(cdr.CdrError):
        cdr.imu_reading(data[:30])
    with pytest.raises(cdr.CdrError):
        cdr.wrench_reading(data[:20])


# -- writing ------------------------------------------------------------------------------
# The bytes of the writers equal rosbags' serializer of the message objects (an independent
# serializer), for every alignment of frame id, names and fault, empty and odd-length arrays and
# contact lists; they read back through this module's readers and rosbags.
WRITE_RNG = np.random.default_rng(23)
FRAMES = ['', 'a', 'ab', 'abc', 'l_sole', 'imu_in_torso', 'ü']


def _serialized(msg, msg_type: str) -> bytes:
    return bytes(typestore().serialize_cdr(msg, msg_type))


def _stamp_ns() -> int:
    return int(WRITE_RNG.integers(0, 2 ** 31 - 1)) * 1_000_000_000 + int(WRITE_RNG.integers(0, 10 ** 9))


@pytest.mark.parametrize('frame_id', FRAMES)
def test_joint_states_are_rosbags_bytes_and_read_back(frame_id: str) -> None:
    types = typestore().types
    decode = cdr.JointStateDecoder()
    for n in (0, 1, 2, 3, 29):
        names = tuple('j' * int(WRITE_RNG.integers(1, 9)) + str(k) for k in range(n))
        for n_velocity, n_effort in ((n, n), (0, 0), (n, 0), (int(WRITE_RNG.integers(0, 5)), 3)):
            reading = JointStateReading(_stamp_ns(), names, WRITE_RNG.normal(size=n), WRITE_RNG.normal(size=n_velocity),
                                        WRITE_RNG.normal(size=n_effort))
            data = cdr.joint_state_cdr(reading, frame_id)
            assert data == _serialized(messages.joint_state_msg(types, reading, frame_id),
                                       'sensor_msgs/msg/JointState')
            back = decode(data)
            assert back.stamp_ns == reading.stamp_ns and back.names == names
            for field in ('position', 'velocity', 'effort'):
                np.testing.assert_array_equal(getattr(back, field), getattr(reading, field))


@pytest.mark.parametrize('frame_id', FRAMES)
def test_imu_and_wrenches_are_rosbags_bytes_and_read_back(frame_id: str) -> None:
    types = typestore().types
    imu = ImuReading(_stamp_ns(), frame_id, WRITE_RNG.normal(size=4), WRITE_RNG.normal(size=3), WRITE_RNG.normal(size=3))
    data = cdr.imu_cdr(imu)
    assert data == _serialized(messages.imu_msg(types, imu), 'sensor_msgs/msg/Imu')
    back = cdr.imu_reading(data)
    assert (back.stamp_ns, back.frame_id) == (imu.stamp_ns, frame_id)
    np.testing.assert_array_equal(back.orientation_xyzw, imu.orientation_xyzw)
    np.testing.assert_array_equal(back.linear_acceleration, imu.linear_acceleration)
    wrench = WrenchReading(_stamp_ns(), frame_id, WRITE_RNG.normal(size=6))
    data = cdr.wrench_cdr(wrench)
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
    m = Measurement(t=1.5, com=com, lin_mom=WRITE_RNG.normal(size=3), ang_mom=WRITE_RNG.normal(size=3),
                    heading=float(WRITE_RNG.uniform(-3, 3)),
                    cop=np.full(3, np.nan) if left + right == 0 else np.array([0.12, -0.04, 0.0]),
                    left_contacts=np.column_stack([WRITE_RNG.uniform(-0.1, 0.1, (left, 2)), WRITE_RNG.uniform(0, 300, left)]),
                    right_contacts=np.column_stack([WRITE_RNG.uniform(-0.1, 0.1, (right, 2)), WRITE_RNG.uniform(0, 300, right)]),
                    left_foot=np.array([0.0, 0.09, 0.1]), right_foot=np.array([0.05, -0.09, -0.2]),
                    non_foot_contact=left == 1, push_force=WRITE_RNG.normal(size=3), torso_rotation=_rotation(0.3))
    ns = 1_500_000_000
    data = cdr.measurement_cdr(ns, frame_id, m)
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
    data = cdr.measurement_cdr(7, 'odom', None, fault)
    assert data == _serialized(messages.measurement_msg(store.types, 7, 'odom', None, fault),
                               'fall_predictor/msg/Measurement')
    assert messages.measurement_from_msg(store.deserialize_cdr(data, 'fall_predictor/msg/Measurement')).fault == fault
    with pytest.raises(WireFormatError, match='needs a fault'):
        cdr.measurement_cdr(7, 'odom', None)


@pytest.mark.parametrize('ns', [-1, (2 ** 31) * 1_000_000_000])
def test_stamps_outside_builtin_time_are_refused_as_the_message_types_refuse_them(ns: int) -> None:
    reading = WrenchReading(ns, '', np.zeros(6))
    with pytest.raises(WireFormatError, match='outside builtin_interfaces/Time'):
        messages.wrench_msg(typestore().types, reading)
    with pytest.raises(WireFormatError, match='outside builtin_interfaces/Time'):
        cdr.wrench_cdr(reading)


@pytest.mark.parametrize('frame_id', ['', 'base_footprint', 'heading_frame_x'])
@pytest.mark.parametrize('state', [
    MonitorState(STATUS_OK, contact_mode=3, tau_his_s=0.044),
    MonitorState(STATUS_OK, '', True, True, True, False, 12, 0.41, (0.6, -0.8), 0.08),
    MonitorState(STATUS_DEGRADED, 'no IMU message for 0.052 s', contact_mode=None),
    MonitorState(STATUS_FALLEN, 'fallen', False, True, False, True, 15, math.nan, (math.nan, math.nan)),
    MonitorState(STATUS_STALE, 'x' * 7, tau_his_s=0.2),
])
def test_fall_states_are_rclpys_bytes_and_rosbags_bytes(state: MonitorState, frame_id: str) -> None:
    """The predictor node publishes these bytes in place of the message object: they must be
    rosbags' serialization of it byte for byte (padding zeroed; rclpy leaves its padding bytes
    as they were in its buffer, so its bytes are compared as what they decode to)."""
    data = cdr.fall_state_cdr(123_456_789_012, frame_id, state)
    assert data == _serialized(messages.fall_state_msg(typestore().types, 123_456_789_012,
                                                       frame_id, state),
                               'fall_predictor/msg/FallState')
    msg = messages.fall_state_msg(ros_qos.TYPES, 123_456_789_012, frame_id, state)
    decoded = deserialize_message(data, FallState)
    assert len(data) == len(serialize_message(msg))
    assert decoded.header == msg.header
    assert _fields(decoded) == _fields(msg)
    stamp_ns, back = messages.fall_state_from_msg(decoded)
    assert stamp_ns == 123_456_789_012 and back.reason == state.reason
    assert (back.status, back.latched, back.contact_mode) == (state.status, state.latched,
                                                             state.contact_mode)


def _fields(msg: FallState) -> list[object]:
    """The message's values, NaN as a string (so that equal messages compare equal)."""
    d = msg.fall_direction
    values = [msg.status, msg.reason, msg.falling, msg.latched, msg.atomic, msg.guard,
              msg.contact_mode, msg.time_to_fall, d.x, d.y, d.z, msg.tau_his]
    return [repr(v) if isinstance(v, float) and math.isnan(v) else v for v in values]
