"""The wire contract: layouts round-trip bit-exactly and every malformed input is rejected."""
import array
import math
from types import SimpleNamespace

import numpy as np
import pytest

from fall_predictor.monitor.records import CONTACT_MODE_NAMES, N_FEATURES
from fall_predictor.data.topics import (CONTROLLER_MODE, FEATURES_LABEL, LATCHED_QOS, MEASUREMENT_LABEL, SIM_RATE_HZ, STREAM_QOS, TOPICS, TOPICS_BY_NAME, QosSpec, WireFormatError, check_controller_mode, topics_markdown_table)
from fall_predictor.data.wire import (MEASUREMENT_HEADER_LEN, JointStateSample, PredictorState, PushEvent, check_layout, pack_features, pack_measurement, push_from_wire, state_from_diagnostic, state_to_status, unpack_features, unpack_measurement)
from fall_predictor.data.topics import time_to_ns, time_to_stamp
from random_records import make_measurement


def assert_same_measurement(a, b):
    assert type(a.t) is float and a.t == b.t
    assert type(a.heading) is float and a.heading == b.heading
    assert a.non_foot_contact is b.non_foot_contact
    for name in ('com', 'lin_mom', 'ang_mom', 'cop', 'left_contacts', 'right_contacts',
                 'left_foot', 'right_foot', 'push_force'):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == np.float64 and x.shape == y.shape, name
        assert np.array_equal(x, y, equal_nan=True), name


@pytest.fixture
def rng():
    return np.random.default_rng(7)


# ---------------------------------------------------------------------------- measurement

@pytest.mark.parametrize('n_left,n_right', [(0, 0), (4, 0), (0, 8), (3, 5), (1, 1)])
def test_measurement_round_trip_is_exact(rng, n_left, n_right):
    m = make_measurement(rng, n_left, n_right)
    data = pack_measurement(m)
    assert data.dtype == np.float64
    assert data.shape == (MEASUREMENT_HEADER_LEN + 3 * (n_left + n_right),)
    back = unpack_measurement(data)
    assert_same_measurement(back, m)
    assert pack_measurement(back).tobytes() == data.tobytes()     # bit-exact, NaN cop included


def test_measurement_layout_positions(rng):
    m = make_measurement(rng, 2, 1, t=1.5)
    data = pack_measurement(m)
    assert data[0] == 1.5
    assert np.array_equal(data[1:4], m.com)
    assert data[10] == m.heading
    assert data[20] == float(m.non_foot_contact)
    assert np.array_equal(data[21:24], m.push_force)
    assert (data[24], data[25]) == (2, 1)
    assert np.array_equal(data[26:32], m.left_contacts.ravel())
    assert np.array_equal(data[32:35], m.right_contacts.ravel())


def test_extreme_values_round_trip(rng):
    m = make_measurement(rng, 1, 0)
    # Extremes the bounds allow: a negative zero, a denormal and the largest CoM height.
    m.com = np.array([-0.0, 5e-324, 2.0])
    m.left_contacts[:, :2] = 0.0
    back = unpack_measurement(pack_measurement(m))
    assert back.com.tobytes() == m.com.tobytes()


@pytest.mark.parametrize('container', [list, lambda a: array.array('d', a), np.asarray])
def test_unpack_accepts_sequences(rng, container):
    data = pack_measurement(make_measurement(rng, 2, 2))
    assert_same_measurement(unpack_measurement(container(data)), unpack_measurement(data))


def test_unpacked_arrays_do_not_alias_the_input(rng):
    data = pack_measurement(make_measurement(rng, 1, 1))
    m = unpack_measurement(data)
    data[1] = 99.0
    assert m.com[0] != 99.0


def _valid(rng):
    return pack_measurement(make_measurement(rng, 2, 1))


def _with(data, index, value):
    out = data.copy()
    out[index] = value
    return out


@pytest.mark.parametrize('mutate,match', [
    (lambda d: d[:10], 'fewer than the 26-value header'),
    (lambda d: d[:-1], 'n_left=2 and n_right=1 need 35'),
    (lambda d: np.append(d, 0.0), '36 values, but n_left=2 and n_right=1 need 35'),
    (lambda d: _with(d, 24, -1.0), 'n_left must be a non-negative integer'),
    (lambda d: _with(d, 25, -3.0), 'n_right must be a non-negative integer'),
    (lambda d: _with(d, 24, 1.5), 'n_left must be a non-negative integer, got 1.5'),
    (lambda d: _with(d, 25, np.nan), 'n_right must be a non-negative integer, got nan'),
    (lambda d: _with(d, 24, np.inf), 'n_left must be a non-negative integer, got inf'),
    (lambda d: _with(d, 0, np.nan), r'measurement.t is not finite'),
    (lambda d: _with(d, 0, np.inf), r'measurement.t is not finite'),
    (lambda d: _with(d, 0, -0.001), r'sample time -0.001 s is outside'),
    (lambda d: _with(d, 2, np.nan), r'measurement.com is not finite'),
    (lambda d: _with(d, 10, np.inf), r'measurement.heading is not finite'),
    (lambda d: _with(d, 12, np.nan), r'measurement.cop must be all finite or all NaN'),
    (lambda d: _with(_with(d, slice(11, 14), np.nan), 12, np.inf), r'cop must be all finite'),
    (lambda d: _with(d, 15, np.nan), r'measurement.left_foot is not finite'),
    (lambda d: _with(d, 22, np.nan), r'measurement.push_force is not finite'),
    (lambda d: _with(d, 20, 0.5), r'non_foot_contact must be 0 or 1'),
    (lambda d: _with(d, 26 + 3 * 2 + 2, np.nan), r'contacts row 2 column 2 is not finite'),
    (lambda d: d.reshape(5, 7), r'data must be 1-D'),
    (lambda d: ['x'] * 35, r'not a float64 vector'),
])
def test_malformed_measurement_is_rejected(rng, mutate, match):
    with pytest.raises(WireFormatError, match=match):
        unpack_measurement(mutate(_valid(rng)))


def test_cop_all_nan_is_accepted(rng):
    m = unpack_measurement(_with(_valid(rng), slice(11, 14), np.nan))
    assert np.isnan(m.cop).all()


@pytest.mark.parametrize('field,value,match', [
    ('com', np.zeros(2), r'measurement.com must have shape \(3,\)'),
    ('left_contacts', np.zeros((2, 2)), r'left_contacts must have shape \(k, 3\)'),
    ('right_contacts', np.zeros(3), r'right_contacts must have shape \(k, 3\)'),
    ('t', math.nan, 'measurement.t is not finite'),
    ('lin_mom', np.array([0.0, np.inf, 0.0]), 'lin_mom is not finite'),
])
def test_pack_rejects_what_a_receiver_would(rng, field, value, match):
    m = make_measurement(rng, 1, 1)
    setattr(m, field, value)
    with pytest.raises(WireFormatError, match=match):
        pack_measurement(m)


# ---------------------------------------------------------------------------- layouts

def _layout(*dims, data_offset=0):
    return SimpleNamespace(dim=[SimpleNamespace(label=label, size=size, stride=stride)
                                for label, size, stride in dims], data_offset=data_offset)


def test_check_layout_accepts_the_contract():
    check_layout(_layout((MEASUREMENT_LABEL, 35, 35)), MEASUREMENT_LABEL, 35)


@pytest.mark.parametrize('layout,match', [
    (_layout(('fall_predictor/measurement/v2', 35, 35)), "label 'fall_predictor/measurement/v2'"),
    (_layout((FEATURES_LABEL, 35, 35)), 'is not .fall_predictor/measurement/v1.'),
    (_layout(), 'exactly 1 dimension'),
    (_layout((MEASUREMENT_LABEL, 35, 35), (MEASUREMENT_LABEL, 1, 1)), 'exactly 1 dimension'),
    (_layout((MEASUREMENT_LABEL, 34, 35)), 'size/stride 34/35 disagree with 35'),
    (_layout((MEASUREMENT_LABEL, 35, 35), data_offset=1), 'data_offset must be 0'),
])
def test_check_layout_rejects(layout, match):
    with pytest.raises(WireFormatError, match=match):
        check_layout(layout, MEASUREMENT_LABEL, 35)


# ---------------------------------------------------------------------------- features

def plausible_features(rng):
    x = rng.normal(size=N_FEATURES) * 0.1
    x[2] = 0.6      # CoM height within [0, 2] m
    return x


def test_features_round_trip(rng):
    x = plausible_features(rng)
    data = pack_features(2.5, x, 15)
    assert data.shape == (17,) and data[0] == 2.5 and data[16] == 15
    sample = unpack_features(data)
    assert sample.t == 2.5 and sample.mode == 15 and type(sample.mode) is int
    assert sample.x.tobytes() == x.tobytes()


@pytest.mark.parametrize('mutate,match', [
    (lambda d: d[:-1], '16 values, expected 17'),
    (lambda d: _with(d, 0, np.nan), 'features.t is not finite'),
    (lambda d: _with(d, 3, np.inf), 'features.com_z is not finite'),
    (lambda d: _with(d, 16, 16.0), 'contact mode must be < 16'),
    (lambda d: _with(d, 16, -1.0), 'contact mode must be a non-negative integer'),
    (lambda d: _with(d, 16, 2.5), 'contact mode must be a non-negative integer'),
])
def test_malformed_features_are_rejected(rng, mutate, match):
    with pytest.raises(WireFormatError, match=match):
        unpack_features(mutate(pack_features(0.1, plausible_features(rng), 3)))


def test_pack_features_rejects_wrong_shape():
    with pytest.raises(WireFormatError, match=r'shape \(15,\)'):
        pack_features(0.0, np.zeros(14), 0)


# ---------------------------------------------------------------------------- state

def _status(fields):
    """StatusFields -> (stamp, rosbags-like status list) as a subscriber would see them."""
    status = SimpleNamespace(level=fields.level, name=fields.name, message=fields.message,
                             values=[SimpleNamespace(key=k, value=v) for k, v in fields.values])
    return fields.stamp_ns, [status]


@pytest.mark.parametrize('state,level,message', [
    (PredictorState(0.25, False, True, False, False, 0, 0.044), 0, 'balanced'),
    (PredictorState(1.001, True, True, True, True, 15, 0.016), 1, 'falling'),
    (PredictorState(3.0, False, False, False, False, None, 0.06, 'no measurement for 0.05 s'),
     3, 'stale: no measurement for 0.05 s'),
])
def test_state_round_trip(state, level, message):
    fields = state_to_status(state)
    assert (fields.level, fields.message, fields.name) == (level, message, 'fall_predictor')
    assert fields.stamp_ns == time_to_ns(state.t)
    values = dict(fields.values)
    assert values['contact_mode'] in (*CONTACT_MODE_NAMES, 'unknown')
    assert float(values['t']) == state.t
    assert state_from_diagnostic(*_status(fields)) == state


def test_state_level_accepts_rclpy_bytes():
    fields = state_to_status(PredictorState(0.5, True, True, False, False, 3, 0.044))
    stamp, statuses = _status(fields)
    statuses[0].level = bytes((fields.level,))
    assert state_from_diagnostic(stamp, statuses).falling


def _edit(fields, **changes):
    values = dict(fields.values)
    values.update(changes.pop('values', {}))
    for key in changes.pop('drop', ()):
        del values[key]
    return fields._replace(values=tuple(values.items()), **changes)


@pytest.mark.parametrize('edit,match', [
    (dict(level=0), 'disagree with falling=true'),
    (dict(message='balanced'), 'disagree with falling=true'),
    (dict(name='other'), "status name 'other'"),
    (dict(drop=('guard',)), 'must have keys'),
    (dict(values={'falling': 'yes'}), "'falling' must be 'true' or 'false'"),
    (dict(values={'contact_mode': 'L-RIGHT'}), "'L-RIGHT' is not a contact mode name"),
    (dict(values={'tau_his_s': 'nan'}), "'tau_his_s' is not finite"),
    (dict(values={'t': 'soon'}), "'t' is not a number"),
    (dict(stamp_ns=123), 'header stamp 123 ns disagrees with t=0.5'),
])
def test_malformed_state_is_rejected(edit, match):
    fields = state_to_status(PredictorState(0.5, True, True, False, False, 3, 0.044))
    with pytest.raises(WireFormatError, match=match):
        state_from_diagnostic(*_status(_edit(fields, **edit)))


def test_state_needs_exactly_one_status():
    stamp, statuses = _status(state_to_status(PredictorState(0.5, False, False, False, False,
                                                             3, 0.044)))
    with pytest.raises(WireFormatError, match='exactly 1 status, got 2'):
        state_from_diagnostic(stamp, statuses * 2)


# ---------------------------------------------------------------------------- time, joints, push

def test_time_on_the_1khz_grid_is_exact():
    for k in range(0, 3_000_000, 997):
        assert time_to_ns(k * 1e-3) == k * 1_000_000
        assert time_to_ns(k / SIM_RATE_HZ) == k * 1_000_000
    assert time_to_stamp(12.345) == (12, 345_000_000)


@pytest.mark.parametrize('t', [math.nan, math.inf, -1e-3])
def test_time_must_be_finite_and_non_negative(t):
    with pytest.raises(WireFormatError, match='time must be finite and >= 0'):
        time_to_ns(t)


def test_joint_state_sample_checks_lengths():
    sample = JointStateSample(0.01, ('a', 'b'), [1, 2])
    assert sample.velocity.shape == (0,) and sample.position.dtype == np.float64
    with pytest.raises(WireFormatError, match='2 names but 1 position values'):
        JointStateSample(0.01, ('a', 'b'), [1])
    with pytest.raises(WireFormatError, match='2 names but 3 effort values'):
        JointStateSample(0.01, ('a', 'b'), [1, 2], [], [1, 2, 3])
    with pytest.raises(WireFormatError, match='not unique'):
        JointStateSample(0.01, ('a', 'a'), [1, 2])
    with pytest.raises(WireFormatError, match='velocity is not finite'):
        JointStateSample(0.01, ('a',), [1], [np.nan])


def test_push_checks_frame_and_force():
    push = push_from_wire(1_500_000_000, 'world', (100.0, -20.0, 0.0))
    assert push.t == 1.5 and np.array_equal(push.force, [100.0, -20.0, 0.0])
    with pytest.raises(WireFormatError, match="frame_id 'base_link' is not 'world'"):
        push_from_wire(0, 'base_link', (1.0, 0.0, 0.0))
    with pytest.raises(WireFormatError, match='3 finite values'):
        PushEvent(0.0, np.array([1.0, np.nan, 0.0]))


def test_controller_mode():
    assert check_controller_mode('fall') == 'fall'
    with pytest.raises(WireFormatError, match="'walk' is not one of"):
        check_controller_mode('walk')


# ---------------------------------------------------------------------------- the table

def test_topic_table_is_consistent():
    assert len(TOPICS_BY_NAME) == len(TOPICS)
    for spec in TOPICS:
        package, kind, name = spec.msg_type.split('/')
        assert package and kind == 'msg' and name[0].isupper()
        if spec.rate_hz == SIM_RATE_HZ:
            assert spec.qos == STREAM_QOS, spec.name
        assert (spec.layout is not None) == (spec.msg_type == 'std_msgs/msg/Float64MultiArray')
    assert CONTROLLER_MODE.qos == LATCHED_QOS
    assert TOPICS_BY_NAME['/fall_predictor/push'].frame_id == 'world'


def test_markdown_table_lists_every_topic():
    table = topics_markdown_table()
    rows = table.strip().splitlines()
    assert len(rows) == 2 + len(TOPICS)
    for spec in TOPICS:
        assert f'`{spec.name}`' in table and f'`{spec.msg_type}`' in table
    assert 'reliable, transient_local, keep_last 1' in table


@pytest.mark.parametrize('args,match', [
    (('reliable', 'volatile', 0), 'depth must be >= 1'),
    (('sometimes', 'volatile', 1), 'unknown reliability'),
    (('reliable', 'persistent', 1), 'unknown durability'),
])
def test_qos_spec_validates(args, match):
    with pytest.raises(ValueError, match=match):
        QosSpec(*args)
