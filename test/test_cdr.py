"""contract/cdr.py: the sensor messages read from their serialized form equal the records built
from rclpy's own deserialization, field for field, over random messages (every alignment of the
frame id, empty and odd-length arrays, changing joint names)."""
from __future__ import annotations

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu, JointState

from fall_predictor.contract import cdr, messages

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
