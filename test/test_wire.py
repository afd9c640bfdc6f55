"""The wire contract: layouts round-trip bit-exactly and every malformed input is rejected."""
import array
import math
from types import SimpleNamespace

import numpy as np
import pytest

from fall_predictor.monitor.records import N_FEATURES
from fall_predictor.contract.topics import (CONTROLLER_MODE, FEATURES_LABEL, LATCHED_QOS, MEASUREMENT_LABEL, SIM_RATE_HZ, STREAM_QOS, TOPICS, TOPICS_BY_NAME, QosSpec, WireFormatError, check_controller_mode, topics_markdown_table)
from fall_predictor.contract.wire import (
    I_STATE_CONTACT_MODE, I_STATE_FALLING, I_STATE_LATCHED, I_STATE_STATUS, I_STATE_T,
    I_STATE_TAU_HIS, I_STATE_TIME_TO_FALL, MEASUREMENT_HEADER_LEN, STATE_LEN, STATUS_DISABLED,
    STATUS_OK, STATUS_STALE, JointStateSample, PredictorState, PushEvent, check_layout,
    pack_features, pack_measurement, pack_state, push_from_wire, unpack_features,
    unpack_measurement, unpack_state)
from fall_predictor.contract.topics import time_to_ns, time_to_stamp
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

@pytest.mark.parametrize('state,status,message', [
    (PredictorState(0.25, False, True, False, False, 0, 0.044), STATUS_OK, 'balanced'),
    (PredictorState(1.001, True, True, True, True, 15, 0.016, time_to_fall_s=0.31,
                    fall_direction=(0.6, -0.8)), STATUS_OK, 'falling'),
    (PredictorState(2.0, False, True, False, True, 4, 0.05, enabled=False), STATUS_DISABLED,
     'disabled'),
    (PredictorState(3.0, False, False, False, False, None, 0.06, 'stale'), STATUS_STALE, 'stale'),
])
def test_state_round_trip(state, status, message):
    data = pack_state(state)
    assert data.shape == (STATE_LEN,) and data[I_STATE_STATUS] == status
    assert state.message == message
    # Slots as a C++ consumer reads them, by index (documented in the README).
    assert data[I_STATE_T] == state.t and data[I_STATE_FALLING] == float(state.falling)
    assert data[I_STATE_LATCHED] == float(state.latched)
    assert data[I_STATE_CONTACT_MODE] == (-1 if state.contact_mode is None else state.contact_mode)
    back = unpack_state(data)
    assert back.t == state.t and back.status == status
    assert (back.falling, back.atomic, back.guard, back.latched) == (
        state.falling, state.atomic, state.guard, state.latched)
    assert back.contact_mode == state.contact_mode and back.tau_his_s == state.tau_his_s
    np.testing.assert_array_equal(back.fall_direction, state.fall_direction)
    np.testing.assert_array_equal(back.time_to_fall_s, state.time_to_fall_s)


def test_stale_reason_stays_off_the_wire():
    state = PredictorState(3.0, False, False, False, True, None, 0.06, 'no features for 0.6 s')
    back = unpack_state(pack_state(state))
    assert back.stale_reason == 'stale' and back.latched


def _state_array():
    return pack_state(PredictorState(0.5, True, True, False, True, 3, 0.044,
                                     time_to_fall_s=0.2, fall_direction=(1.0, 0.0)))


@pytest.mark.parametrize('index,value,match', [
    (I_STATE_STATUS, 3.0, 'status must be 0, 1 or 2'),
    (I_STATE_FALLING, 0.5, 'falling must be 0 or 1'),
    (I_STATE_LATCHED, np.nan, 'latched is not finite'),
    (I_STATE_CONTACT_MODE, 16.0, 'contact_mode must be < 16'),
    (I_STATE_CONTACT_MODE, -2.0, 'contact_mode must be a non-negative integer'),
    (I_STATE_TAU_HIS, -0.01, 'tau_his_s must be >= 0'),
    (I_STATE_TIME_TO_FALL, -1.0, 'time_to_fall_s must be NaN or in'),
    (9, 0.5, 'fall_direction must be a unit vector'),
    (I_STATE_T, 2.0 ** 31, 'sample time'),
])
def test_malformed_state_is_rejected(index, value, match):
    data = _state_array()
    data[index] = value
    with pytest.raises(WireFormatError, match=match):
        unpack_state(data)

def test_state_must_have_eleven_slots():
    with pytest.raises(WireFormatError, match='10 values, expected 11'):
        unpack_state(np.zeros(10))


# ---------------------------------------------------------------------------- time, joints, push

def test_time_on_the_1khz_grid_is_exact():
    for k in range(0, 3_000_000, 997):
        assert time_to_ns(k * 1e-3) == k * 1_000_000
        assert time_to_ns(k / SIM_RATE_HZ) == k * 1_000_000
    assert time_to_stamp(12.345) == (12, 345_000_000)


@pytest.mark.parametrize('t', [math.nan, math.inf, -1e-3, 1e7 + 1.0, 9.3e9])
def test_time_must_be_finite_and_within_the_bounds(t):
    with pytest.raises(WireFormatError, match='time must be finite and within'):
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
        # REP 2003: sensor-style streams are read best effort with a shallow queue.
        if spec.sub_qos is not None:
            assert spec.sub_qos.reliability == 'best_effort' and spec.sub_qos.depth <= 10
        assert spec.ros_name == (spec.name if spec.name in ('/clock', '/diagnostics')
                                 else spec.name[1:])
        assert (spec.layout is not None) == (spec.msg_type == 'std_msgs/msg/Float64MultiArray')
    assert CONTROLLER_MODE.qos == LATCHED_QOS
    assert TOPICS_BY_NAME['/fall_predictor/push'].frame_id == 'world'


def test_markdown_table_lists_every_topic():
    table = topics_markdown_table()
    rows = table.strip().splitlines()
    assert len(rows) == 2 + len(TOPICS)
    for spec in TOPICS:
        assert f'`{spec.ros_name}`' in table and f'`{spec.msg_type}`' in table
    assert 'reliable, transient_local, keep_last 1' in table


@pytest.mark.parametrize('args,match', [
    (('reliable', 'volatile', 0), 'depth must be >= 1'),
    (('sometimes', 'volatile', 1), 'unknown reliability'),
    (('reliable', 'persistent', 1), 'unknown durability'),
])
def test_qos_spec_validates(args, match):
    with pytest.raises(ValueError, match=match):
        QosSpec(*args)
