"""rclpy conversions: QoS profiles, message round trips, live and bag bytes agree."""
import array
import importlib
import os
import subprocess
import sys

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from fall_predictor.ros import conversions as ros_qos
from fall_predictor.data.topics import (MEASUREMENT, MEASUREMENT_LABEL, TOPICS, WireFormatError)
from fall_predictor.data.wire import PredictorState, pack_measurement
from random_records import make_measurement


@pytest.fixture
def rng():
    return np.random.default_rng(3)


@pytest.mark.parametrize('spec', TOPICS, ids=lambda s: s.name)
def test_qos_profile_matches_spec(spec):
    profile = ros_qos.qos_profile(spec.qos)
    assert profile.history == HistoryPolicy.KEEP_LAST
    assert profile.depth == spec.qos.depth
    assert profile.reliability == ReliabilityPolicy.RELIABLE
    latched = spec.name in ('/fall_predictor/controller_mode', '/fall_predictor/falling',
                            '/fall_predictor/fall_direction')
    expected = DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
    assert profile.durability == expected
    if spec.rate_hz == 1000.0 and spec.name not in ('/clock', '/fall_predictor/joint_commands'):
        sub = ros_qos.qos_profile(spec.subscription_qos)
        assert sub.reliability == ReliabilityPolicy.BEST_EFFORT and sub.depth <= 10


@pytest.mark.parametrize('n_left,n_right', [(0, 0), (4, 4), (8, 0)])
def test_measurement_message_round_trip_through_serialization(rng, n_left, n_right):
    m = make_measurement(rng, n_left, n_right, t=4.321)
    msg = ros_qos.measurement_to_msg(m)
    assert isinstance(msg.data, array.array) and msg.data.typecode == 'd'
    n = len(msg.data)
    assert [(d.label, d.size, d.stride) for d in msg.layout.dim] == [(MEASUREMENT_LABEL, n, n)]
    assert msg.layout.data_offset == 0
    received = deserialize_message(serialize_message(msg), Float64MultiArray)
    back = ros_qos.measurement_from_msg(received)
    assert pack_measurement(back).tobytes() == pack_measurement(m).tobytes()


def test_measurement_from_msg_checks_layout(rng):
    msg = ros_qos.measurement_to_msg(make_measurement(rng, 1, 1))
    msg.layout.dim[0].label = 'fall_predictor/features/v1'
    with pytest.raises(WireFormatError, match="label 'fall_predictor/features/v1'"):
        ros_qos.measurement_from_msg(msg)
    msg = ros_qos.measurement_to_msg(make_measurement(rng, 1, 1))
    msg.layout.dim = [MultiArrayDimension(label=MEASUREMENT_LABEL, size=3, stride=3)]
    with pytest.raises(WireFormatError, match='size/stride 3/3 disagree'):
        ros_qos.measurement_from_msg(msg)


def test_features_state_joint_push_round_trips(rng):
    x = rng.normal(size=15) * 0.1
    x[2] = 0.6          # within the plausibility bounds
    sample = ros_qos.features_from_msg(ros_qos.features_to_msg(0.5, x, 7))
    assert sample.t == 0.5 and sample.mode == 7 and np.array_equal(sample.x, x)

    for state in (PredictorState(2.0, True, True, False, True, 9, 0.06, time_to_fall_s=0.2,
                                 fall_direction=(0.0, -1.0)),
                  PredictorState(2.001, False, False, False, False, None, 0.06, 'stale')):
        msg = ros_qos.state_to_msg(state)
        assert msg.layout.dim[0].label == 'fall_predictor/state/v2'
        assert msg.data[0] == state.t and msg.data[1] == state.status
        assert ros_qos.state_from_msg(msg) == state
    assert ros_qos.falling_msg(True).data is True
    direction = ros_qos.fall_direction_msg(1.5, (0.6, 0.8))
    assert direction.header.frame_id == 'base_footprint' and direction.header.stamp.sec == 1
    assert (direction.vector.x, direction.vector.y, direction.vector.z) == (0.6, 0.8, 0.0)

    js = ros_qos.joint_state_from_msg(
        ros_qos.joint_state_to_msg(0.01, ['hip', 'knee'], [0.1, -0.2], [1.0, 2.0]))
    assert js.t == 0.01 and js.names == ('hip', 'knee')
    assert np.array_equal(js.position, [0.1, -0.2]) and js.effort.size == 0

    push = ros_qos.push_from_msg(ros_qos.push_to_msg(1.25, [300.0, -40.0, 0.0]))
    assert push.t == 1.25 and np.array_equal(push.force, [300.0, -40.0, 0.0])

    assert ros_qos.controller_mode_msg('balance').data == 'balance'
    with pytest.raises(WireFormatError):
        ros_qos.controller_mode_msg('run')


def test_bag_and_live_serialisations_are_interchangeable(rng, tmp_path):
    """A measurement recorded by bagio decodes in rclpy, and a live message in rosbags.

    (Byte equality does not hold: rclpy leaves CDR alignment padding uninitialised.)
    """
    from rosbags.rosbag2 import Reader

    from fall_predictor.data.bagio import BagWriter, typestore

    m = make_measurement(rng, 3, 2, t=0.002)
    with BagWriter(tmp_path / 'bag') as writer:
        writer.write_measurement(m)
    with Reader(tmp_path / 'bag') as reader:
        [(_, t_ns, raw)] = list(reader.messages())
    assert t_ns == 2_000_000
    from_bag = ros_qos.measurement_from_msg(deserialize_message(bytes(raw), Float64MultiArray))
    assert pack_measurement(from_bag).tobytes() == pack_measurement(m).tobytes()

    live = serialize_message(ros_qos.measurement_to_msg(m))
    assert len(live) == len(raw)
    msg = typestore().deserialize_cdr(live, MEASUREMENT.msg_type)
    assert msg.layout.dim[0].label == MEASUREMENT_LABEL
    assert msg.data.tobytes() == pack_measurement(m).tobytes()


_STRICT_SCRIPT = '''
import numpy as np
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.monitor.records import Measurement
from fall_predictor.data.wire import PredictorState
m = Measurement(t=0.1, com=np.array([0.0, 0.0, 0.6]), lin_mom=np.zeros(3), ang_mom=np.zeros(3), heading=0.0,
                cop=np.full(3, np.nan), left_contacts=np.zeros((2, 3)),
                right_contacts=np.zeros((0, 3)), left_foot=np.zeros(3), right_foot=np.zeros(3),
                non_foot_contact=False)
assert ros_qos.measurement_from_msg(ros_qos.measurement_to_msg(m)).t == 0.1
assert ros_qos.features_from_msg(ros_qos.features_to_msg(0.1, np.zeros(15), 1)).mode == 1
ros_qos.falling_msg(True)
ros_qos.fall_direction_msg(0.1, (1.0, 0.0))
s = PredictorState(0.1, True, True, True, True, 2, 0.04)
assert ros_qos.state_from_msg(ros_qos.state_to_msg(s)) == s
ros_qos.joint_state_from_msg(ros_qos.joint_state_to_msg(0.1, ['a'], [1.0], [0.0], [0.0]))
ros_qos.push_from_msg(ros_qos.push_to_msg(0.1, [1.0, 2.0, 0.0]))
ros_qos.controller_mode_msg('fall')
'''


def test_conversions_pass_rclpy_strict_field_checks():
    """With ROS_PYTHON_CHECK_FIELDS=1 rclpy asserts every field's type (numpy arrays fail)."""
    env = dict(os.environ, ROS_PYTHON_CHECK_FIELDS='1')
    result = subprocess.run([sys.executable, '-c', _STRICT_SCRIPT], env=env,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize('spec', TOPICS, ids=lambda s: s.name)
def test_every_topic_type_exists_in_rclpy(spec):
    package, kind, name = spec.msg_type.split('/')
    msg_class = getattr(importlib.import_module(f'{package}.{kind}'), name)
    assert (spec.frame_id is not None) == hasattr(msg_class(), 'header'), spec.name
