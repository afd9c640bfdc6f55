"""The ROS side of the contract: QoS profiles, the typed messages through rclpy's serialisation,
and live (rclpy) and bag (rosbags) bytes that decode in each other."""
import dataclasses
import importlib
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message

from fall_predictor.contract import messages
from fall_predictor.contract.topics import MEASUREMENT, TOPICS, WireFormatError
from fall_predictor.contract.wire import pack_measurement
from fall_predictor.monitor.fall_monitor import (EVENT_FALLING, STATUS_DEGRADED, STATUS_OK,
                                                 MonitorState)
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading
from fall_predictor.msg import FallEvent, FallState, Features, Measurement
from fall_predictor.ros import conversions as ros_qos
from random_records import make_measurement

#: A stamp as a robot publishes it (2026-11-24 12:00:00.123456789 UTC) [ns].
EPOCH_NS = 1_795_521_600_123_456_789
LATCHED = ('/fall_predictor/controller_mode', '/fall_predictor/falling',
           '/fall_predictor/fall_direction', '/fall_predictor/fall_event', '/robot_description')


@pytest.fixture
def rng():
    return np.random.default_rng(3)


def through_the_wire(msg, msg_type):
    return deserialize_message(serialize_message(msg), msg_type)


@pytest.mark.parametrize('spec', TOPICS, ids=lambda s: s.name)
def test_qos_profile_matches_spec(spec):
    profile = ros_qos.qos_profile(spec.qos)
    assert profile.history == HistoryPolicy.KEEP_LAST
    assert profile.depth == spec.qos.depth
    assert profile.reliability == ReliabilityPolicy.RELIABLE
    expected = DurabilityPolicy.TRANSIENT_LOCAL if spec.name in LATCHED else DurabilityPolicy.VOLATILE
    assert profile.durability == expected
    if spec.rate_hz == 1000.0 and spec.name not in ('/clock', '/fall_predictor/joint_commands'):
        sub = ros_qos.qos_profile(spec.subscription_qos)
        assert sub.reliability == ReliabilityPolicy.BEST_EFFORT and sub.depth <= 10


@pytest.mark.parametrize('spec', TOPICS, ids=lambda s: s.name)
def test_every_topic_type_exists_in_rclpy(spec):
    package, kind, name = spec.msg_type.split('/')
    msg_class = getattr(importlib.import_module(f'{package}.{kind}'), name)
    assert (spec.frame_id is not None) == hasattr(msg_class(), 'header'), spec.name


@pytest.mark.parametrize('n_left,n_right', [(0, 0), (4, 4), (8, 0)])
def test_measurement_round_trip_keeps_the_stamp_and_every_value(rng, n_left, n_right):
    m = make_measurement(rng, n_left, n_right, t=4.321)
    msg = through_the_wire(messages.measurement_msg(ros_qos.TYPES, EPOCH_NS, 'odom', m), Measurement)
    back = messages.measurement_from_msg(msg)
    assert (back.stamp_ns, back.frame_id, back.fault) == (EPOCH_NS, 'odom', '')
    assert back.measurement.t == EPOCH_NS / 1e9
    same_time = dataclasses.replace(back.measurement, t=m.t)
    assert pack_measurement(same_time).tobytes() == pack_measurement(m).tobytes()


def test_a_measurement_with_a_fault_carries_only_the_fault():
    msg = messages.measurement_msg(ros_qos.TYPES, EPOCH_NS, 'odom', None,
                                   'no /imu/data within 5 ms of /joint_states')
    back = messages.measurement_from_msg(through_the_wire(msg, Measurement))
    assert back == (EPOCH_NS, 'odom', 'no /imu/data within 5 ms of /joint_states', None, False)
    with pytest.raises(WireFormatError, match='needs a fault'):
        messages.measurement_msg(ros_qos.TYPES, EPOCH_NS, 'odom', None)


def test_decoding_refuses_what_the_contract_forbids(rng):
    msg = messages.measurement_msg(ros_qos.TYPES, EPOCH_NS, 'odom', make_measurement(rng, 1, 1))
    msg.com.z = 1e154
    with pytest.raises(WireFormatError, match='CoM height'):
        messages.measurement_from_msg(msg)
    msg.com.z, msg.heading = 0.6, math.nan
    with pytest.raises(WireFormatError, match='non-finite'):
        messages.measurement_from_msg(msg)
    features = messages.features_msg(ros_qos.TYPES, EPOCH_NS, np.zeros(15), 3)
    features.contact_mode = 16
    with pytest.raises(WireFormatError, match='contact_mode must be < 16'):
        messages.features_from_msg(features)
    state = messages.fall_state_msg(ros_qos.TYPES, EPOCH_NS, 'base_footprint', MonitorState(STATUS_OK))
    state.status = 9
    with pytest.raises(WireFormatError, match='STATUS_'):
        messages.fall_state_from_msg(state)
    with pytest.raises(WireFormatError, match='outside builtin_interfaces/Time'):
        messages.time_msg(ros_qos.TYPES, 2 ** 31 * 10 ** 9)


def test_features_state_event_and_sensor_round_trips(rng):
    x = rng.normal(size=15) * 0.1
    x[2] = 0.6          # within the plausibility bounds
    f = messages.features_from_msg(through_the_wire(
        messages.features_msg(ros_qos.TYPES, EPOCH_NS, x, 7, 0.2), Features))
    assert (f.stamp_ns, f.fault, f.mode, f.base_tilt_rad) == (EPOCH_NS, '', 7, 0.2)
    assert np.array_equal(f.x[:15], x) and np.isnan(f.x[15:]).all()     # sent without an attitude
    for state in (MonitorState(STATUS_OK, '', True, True, True, False, 9, 0.2, (0.0, -1.0), 0.06),
                  MonitorState(STATUS_DEGRADED, 'joint l_knee_pitch never received', latched=True,
                               tau_his_s=0.06)):
        msg = through_the_wire(messages.fall_state_msg(ros_qos.TYPES, EPOCH_NS, 'base_footprint',
                                                        state), FallState)
        assert msg.header.frame_id == 'base_footprint'
        stamp, back = messages.fall_state_from_msg(msg)
        assert stamp == EPOCH_NS and back.reason == state.reason and back.status == state.status
        assert back.fall_direction == state.fall_direction or math.isnan(back.fall_direction[0])
    event = through_the_wire(messages.fall_event_msg(ros_qos.TYPES, EPOCH_NS, 'base_footprint',
                                                     EVENT_FALLING, (0.6, 0.8), 0.4, 4), FallEvent)
    assert (event.event, event.direction.x, event.direction.y, event.time_to_fall,
            event.contact_mode) == (FallEvent.EVENT_FALLING, 0.6, 0.8, 0.4, 4)

    joints = JointStateReading(EPOCH_NS, ('hip', 'knee'), np.array([0.1, -0.2]), np.array([1.0, 2.0]))
    back = messages.joint_state_reading(messages.joint_state_msg(ros_qos.TYPES, joints))
    assert back.stamp_ns == EPOCH_NS and back.names == ('hip', 'knee') and back.effort.size == 0
    imu = ImuReading(EPOCH_NS, 'imu_link', np.array([0.0, 0.0, 0.6, 0.8]), np.ones(3), np.zeros(3))
    back = messages.imu_reading(messages.imu_msg(ros_qos.TYPES, imu))
    assert back.frame_id == 'imu_link' and np.array_equal(back.orientation_xyzw, imu.orientation_xyzw)
    wrench = WrenchReading(EPOCH_NS, 'l_ankle_ft', np.arange(6.0))
    assert np.array_equal(messages.wrench_reading(messages.wrench_msg(ros_qos.TYPES, wrench)).wrench,
                          np.arange(6.0))
    assert ros_qos.falling_msg(True).data is True
    direction = ros_qos.fall_direction_msg(1_500_000_000, (0.6, 0.8))
    assert direction.header.frame_id == 'base_footprint' and direction.header.stamp.sec == 1
    push = ros_qos.push_from_msg(ros_qos.push_to_msg(1.25, [300.0, -40.0, 0.0]))
    assert push.t == 1.25 and np.array_equal(push.force, [300.0, -40.0, 0.0])
    assert ros_qos.controller_mode_msg('balance').data == 'balance'
    with pytest.raises(WireFormatError):
        ros_qos.controller_mode_msg('run')


def test_bag_and_live_serialisations_are_interchangeable(rng, tmp_path):
    """A measurement recorded by the bag writer decodes in rclpy, and a live message in rosbags.

    (Byte equality does not hold: rclpy leaves CDR alignment padding uninitialised.)
    """
    from rosbags.rosbag2 import Reader

    from fall_predictor.data.bag_writer import BagWriter
    from fall_predictor.data.bagio import typestore

    m = make_measurement(rng, 3, 2, t=0.002)
    with BagWriter(tmp_path / 'bag') as writer:
        writer.write_measurement(m)
    with Reader(tmp_path / 'bag') as reader:
        [(connection, t_ns, raw)] = list(reader.messages())
    assert t_ns == 2_000_000 and connection.msgtype == 'fall_predictor/msg/Measurement'
    from_bag = messages.measurement_from_msg(deserialize_message(bytes(raw), Measurement))
    assert pack_measurement(from_bag.measurement).tobytes() == pack_measurement(m).tobytes()

    live = serialize_message(messages.measurement_msg(ros_qos.TYPES, 2_000_000, 'odom', m))
    assert len(live) == len(raw)
    decoded = messages.measurement_from_msg(typestore().deserialize_cdr(live, MEASUREMENT.msg_type))
    assert pack_measurement(decoded.measurement).tobytes() == pack_measurement(m).tobytes()


_STRICT_SCRIPT = '''
import numpy as np
from fall_predictor.contract import messages
from fall_predictor.monitor.fall_monitor import MonitorState
from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading
from fall_predictor.ros import conversions as ros_qos
T = ros_qos.TYPES
m = Measurement(t=0.1, com=np.array([0.0, 0.0, 0.6]), lin_mom=np.zeros(3), ang_mom=np.zeros(3), heading=0.0,
                cop=np.full(3, np.nan), left_contacts=np.zeros((2, 3)),
                right_contacts=np.zeros((0, 3)), left_foot=np.zeros(3), right_foot=np.zeros(3),
                non_foot_contact=False)
assert messages.measurement_from_msg(messages.measurement_msg(T, 100, 'odom', m)).stamp_ns == 100
assert messages.features_from_msg(messages.features_msg(T, 100, np.zeros(15), 1)).mode == 1
messages.fall_state_msg(T, 100, 'base_footprint', MonitorState(0, '', True, True))
messages.fall_event_msg(T, 100, 'base_footprint', 0, (1.0, 0.0), 0.2, 1)
messages.joint_state_msg(T, JointStateReading(100, ('a',), np.ones(1), np.zeros(1), np.zeros(1)))
messages.imu_msg(T, ImuReading(100, 'imu', np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(3)))
messages.wrench_msg(T, WrenchReading(100, 'l_sole', np.zeros(6)))
ros_qos.falling_msg(True)
ros_qos.fall_direction_msg(100, (1.0, 0.0))
ros_qos.joint_state_to_msg(100, ['a'], [1.0], [0.0], [0.0])
ros_qos.push_from_msg(ros_qos.push_to_msg(0.1, [1.0, 2.0, 0.0]))
ros_qos.controller_mode_msg('fall')
'''


def test_conversions_pass_rclpy_strict_field_checks():
    """With ROS_PYTHON_CHECK_FIELDS=1 rclpy asserts every field's type (numpy arrays in
    sequence fields fail)."""
    env = dict(os.environ, ROS_PYTHON_CHECK_FIELDS='1')
    result = subprocess.run([sys.executable, '-c', _STRICT_SCRIPT], env=env,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr


def test_features_carry_the_attitude_through_the_wire():
    """19 values (the features, then the base's attitude) arrive as sent; 15 arrive with the
    attitude NaN (no base orientation); an attitude no base can have is refused."""
    x = np.concatenate([np.zeros(15), [0.1, -0.2, 1.5, -0.5]])
    x[2] = 0.6
    sent = messages.features_msg(ros_qos.TYPES, EPOCH_NS, x, 3, 0.2)
    decoded = messages.features_from_msg(deserialize_message(serialize_message(sent), Features))
    np.testing.assert_array_equal(decoded.x, x)
    plain = messages.features_from_msg(messages.features_msg(ros_qos.TYPES, EPOCH_NS, x[:15], 3))
    assert plain.x.shape == (19,) and np.isnan(plain.x[15:]).all()
    np.testing.assert_array_equal(plain.x[:15], x[:15])
    sent.base_attitude[0] = 2.0             # a fused roll lies in [-pi/2, pi/2]
    with pytest.raises(WireFormatError, match='base_attitude'):
        messages.features_from_msg(sent)
    with pytest.raises(WireFormatError, match=r'\(15,\) or \(19,\)'):
        messages.features_msg(ros_qos.TYPES, EPOCH_NS, x[:17], 3)
