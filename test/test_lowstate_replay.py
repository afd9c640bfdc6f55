"""Simulated G1 runs under Unitree's policy, replayed through the onboard monitor twice: as
``joint_states`` + ``imu/data``, and re-encoded as the ``lowstate`` a G1's board publishes (500 Hz,
29 motor slots with the held waist and arms, ``tick`` and no stamp, the pelvis IMU w-x-y-z, each
message serialized and read back as the estimator node reads it, received with latency jitter).
Known answer: the same falls at the same samples (within one), no alarm on a survived run; and
each fault of this stream gives a DEGRADED state that names it, never a fall."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fall_predictor.contract.unitree_hg import lowstate_cdr, lowstate_record
from fall_predictor.data.onboard_replay import (lowstate_messages, onboard_chain, replay,
                                                standard_messages)
from fall_predictor.monitor.fall_monitor import STATUS_DEGRADED, STATUS_OK
from fall_predictor.monitor.lowstate import LowStateConverter
from fall_predictor.monitor.records import PushSpec
from fall_predictor.profiles.profile import load_profile
from fall_predictor.sim.lowstate_driver import RECEIVE_EPOCH_NS, BoardTiming, lowstate_records

PROFILE = load_profile('g1_12dof')
MODEL = Path(__file__).resolve().parents[1] / 'models' / PROFILE.model_for()   # as the monitor loads it
#: (name, push force [N], direction [deg], commanded vx [m/s]): two that fall, two that do not.
RUNS = (('fall_forward', 900.0, 0.0, 0.3), ('fall_sideways', 700.0, 90.0, 0.0),
        ('survived_forward', 250.0, 0.0, 0.3), ('survived_sideways', 300.0, 90.0, 0.0))
PUSH_AT_S = 2.5


@pytest.fixture(scope='module')
def runs():
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.policy_runs import physics_dt_s
    from fall_predictor.sim.sensors import SensorParams, SensorSuite
    from fall_predictor.sim.trajectory import run_trajectory
    from fall_predictor.sim.world import make_world
    policy = PROFILE.controller_profile()
    out = {}
    for k, (name, force, angle, vx) in enumerate(RUNS):
        world = make_world(PROFILE, None, physics_dt_s(policy))
        run = run_trajectory(PushSpec(force, angle, 0.1, PUSH_AT_S), 4.0, world=world,
                             controller=make_controller(PROFILE, None, (vx, 0.0, 0.0), dt_s=world.dt_s),
                             sensors=SensorSuite(SensorParams(), k, world.dt_s, PROFILE))
        world.close()
        out[name] = run
    assert [out[n].fallen for n, *_ in RUNS] == [True, True, False, False]
    return out


def as_lowstate(readings, seed: int = 0):
    """The readings as a G1 board's messages, each through the wire and back."""
    return [(t, lowstate_record(lowstate_cdr(r)))
            for t, r in lowstate_records(readings, PROFILE.unitree_hg, 5, BoardTiming(seed=seed))]


def through_lowstate(records):
    converter = LowStateConverter(PROFILE.unitree_hg, PROFILE.imu_frame, PROFILE.joint_names,
                                  profile_name=PROFILE.name)
    messages, index = lowstate_messages(records, converter)
    return replay(onboard_chain(PROFILE, MODEL), messages, index), converter


def test_the_same_alarms_at_the_same_samples(runs):
    for name, *_ in RUNS:
        readings = runs[name].sensor_readings
        messages, index = standard_messages(readings, PROFILE.imu_frame, RECEIVE_EPOCH_NS)
        reference = replay(onboard_chain(PROFILE, MODEL), messages, index)
        lowstate, converter = through_lowstate(as_lowstate(readings))
        assert converter.counts['held_joint_warnings'] == 0
        if runs[name].fallen:
            assert reference.alarm_index is not None, name
            assert abs(lowstate.alarm_index - reference.alarm_index) <= 1, name
            # Before the fall, not before the push.
            assert PUSH_AT_S <= readings[lowstate.alarm_index].t < runs[name].t_fallen, name
        else:
            assert reference.alarm_index is None and lowstate.alarm_index is None, name
        # The same samples estimated: the lowstate path refuses none the standard one made.
        assert lowstate.statuses.count(STATUS_DEGRADED) <= reference.statuses.count(STATUS_DEGRADED)


def _never_a_fall(result) -> None:
    assert result.alarm_index is None


@pytest.mark.parametrize('fault, words', [
    ('repeated_tick', 'repeated with new readings'),
    ('tick_back', 'tick went back'),
    ('motor_error', 'motor 3 (left_knee_joint) status 0x20'),
    ('zero_quaternion', 'not a unit quaternion'),
    ('mode_machine', 'mode_machine 4'),
])
def test_each_fault_is_a_named_degraded_state_never_a_fall(runs, fault, words):
    records = as_lowstate(runs['survived_forward'].sensor_readings, seed=1)
    at = len(records) // 2
    receive_ns, record = records[at]
    if fault == 'repeated_tick':
        record = replace(record, tick=records[at - 1][1].tick)
    elif fault == 'tick_back':
        record = replace(record, tick=17)
        records[at + 1:] = [(t, replace(r, tick=17 + 2 * (k + 1)))
                            for k, (t, r) in enumerate(records[at + 1:])]
    elif fault == 'motor_error':
        status = record.motor_status.copy()
        status[3] = 0x20
        record = replace(record, motor_status=status)
    elif fault == 'zero_quaternion':
        record = replace(record, imu_quat_wxyz=np.zeros(4))
    else:
        record = replace(record, mode_machine=4)
    records[at] = (receive_ns, record)
    result, _ = through_lowstate(records)
    degraded = [r for s, r in zip(result.statuses, result.reasons) if s == STATUS_DEGRADED]
    assert degraded and all(words in r for r in degraded), (fault, degraded[:2])
    assert len(degraded) <= 3, fault                   # that sample (and the next, at most)
    assert result.statuses[-1] == STATUS_OK
    _never_a_fall(result)


def test_a_tick_wrap_keeps_the_spacing_and_the_alarm(runs):
    """The 32-bit tick wraps mid-run (49.7 days of board time): read modulo 2^32, nothing changes."""
    readings = runs['fall_forward'].sensor_readings
    wrap_at = len(readings) // 3
    first_tick = (1 << 32) - round(readings[wrap_at].t * 1e3) - 1
    records = [(t, lowstate_record(lowstate_cdr(r))) for t, r in lowstate_records(
        readings, PROFILE.unitree_hg, 5, BoardTiming(first_tick_ms=first_tick))]
    assert records[wrap_at + 1][1].tick < records[wrap_at][1].tick
    wrapped, converter = through_lowstate(records)
    plain, _ = through_lowstate(as_lowstate(readings))
    assert converter.counts['tick_wraps'] == 1
    assert wrapped.statuses == plain.statuses and wrapped.alarm_index == plain.alarm_index


def test_held_joints_off_target_are_a_warning_in_words(runs):
    records = as_lowstate(runs['survived_sideways'].sensor_readings[:50])
    receive_ns, record = records[-1]
    q = record.q.copy()
    q[18] = 1.2                                        # left elbow bent: not held
    converter = LowStateConverter(PROFILE.unitree_hg, PROFILE.imu_frame, PROFILE.joint_names,
                                  profile_name=PROFILE.name)
    for t, r in records[:-1]:
        assert converter.convert(r, t).warning == ''
    sample = converter.convert(replace(record, q=q), receive_ns)
    assert not sample.fault
    assert 'left_elbow_joint at 1.20 rad (held at 0.00)' in sample.warning
    assert 'trained with them held' in sample.warning


def test_a_lowstate_recording_imports_as_a_dataset(runs, tmp_path):
    """``ros2 bag record /lowstate`` of the G1 (no robot_description, log time = receive time)
    imports with the profile's table and URDF: a fall where the simulator saw it."""
    from fall_predictor.contract.unitree_hg import LOWSTATE, LOWSTATE_TYPE
    from fall_predictor.data.bag_writer import BagWriter
    from fall_predictor.data.robot_import import import_robot_recordings, is_robot_recording
    bags = []
    for name in ('fall_forward', 'survived_sideways'):
        bag = tmp_path / name
        with BagWriter(bag) as writer:
            for receive_ns, record in lowstate_records(runs[name].sensor_readings, PROFILE.unitree_hg, 5):
                writer.write_raw(LOWSTATE.name, LOWSTATE_TYPE, receive_ns, lowstate_cdr(record))
        assert is_robot_recording(bag)
        bags.append(bag)
    rows, rejected = import_robot_recordings(bags, tmp_path / 'dataset', robot='g1_12dof')
    assert not rejected and [r.fallen for r in rows] == [True, False]
    start_s = RECEIVE_EPOCH_NS / 1e9 + runs['fall_forward'].sensor_readings[0].t
    assert abs((rows[0].t_fallen - start_s) - runs['fall_forward'].t_fallen) < 0.1
    # The URDF the estimator used (the profile's) goes with the dataset, so it estimates again.
    assert (tmp_path / 'dataset' / 'robot.urdf').read_text() == PROFILE.urdf_xml()
    rows, rejected = import_robot_recordings(bags[:1], tmp_path / 'no_table', robot='asimo_like')
    assert not rows and 'names its motors by index only' in next(iter(rejected.values()))


def test_the_29_joint_state_with_held_joints_matches_the_12_joint_models_estimate(runs):
    """The bounds docs/method.md §12 states (benchmarks/bench_lowstate_g1.py measures them on 20
    held-out runs): CoM within 1.5 cm, CoM velocity within 0.06 m/s (p99), the same contact mode
    at 99 % of the samples, angular momentum within 0.05 kg m^2/s (median)."""
    from fall_predictor.data.held_joints import held_joint_errors, summarise_held
    summary = summarise_held([held_joint_errors(runs[name].sensor_readings, PUSH_AT_S, seed=k)
                              for k, (name, *_) in enumerate(RUNS)])
    assert summary['com_m']['p99'] <= 0.015, summary['com_m']
    assert summary['com_velocity_m_s']['p99'] <= 0.06, summary['com_velocity_m_s']
    assert summary['contact_mode_agreement'] >= 0.99
    assert summary['angular_momentum_kg_m2_s']['median'] <= 0.05
