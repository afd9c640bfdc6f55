"""Unitree's LowState as the monitor's records (monitor/lowstate.py, contract/unitree_hg.py):
the wire layout against rosbags' own serialization of Unitree's .msg files, the profile's motor
tables against the robots' URDFs, and the tick rule's stamps on known timings."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fall_predictor.contract.unitree_hg import (LOWSTATE, LOWSTATE_TYPE, lowstate_cdr,
                                                lowstate_from_msg, lowstate_record)
from fall_predictor.contract.topics import WireFormatError
from fall_predictor.data.bagio import typestore
from fall_predictor.monitor.lowstate import (MOTOR_SLOTS, LowStateConverter, LowStateRecord,
                                             parse_unitree_hg)
from fall_predictor.profiles.profile import load_profile

G1 = load_profile('g1')
G1_12 = load_profile('g1_12dof')
EPOCH_NS = 1_764_000_000_000_000_000


def record(tick: int, k: int = 0, **changes) -> LowStateRecord:
    base = LowStateRecord(
        tick=tick, mode_machine=5, mode_pr=0, imu_quat_wxyz=np.array([1.0, 0.0, 0.0, 0.0]),
        gyro_rad_s=np.array([0.01, -0.02, 0.03]), accel_m_s2=np.array([0.0, 0.0, 9.81]),
        q=np.linspace(-1, 1, MOTOR_SLOTS) + 1e-3 * k, dq=np.full(MOTOR_SLOTS, 0.1 * k),
        tau_est=np.arange(MOTOR_SLOTS, dtype=float), motor_status=np.zeros(MOTOR_SLOTS, np.uint32))
    return replace(base, **changes)


def test_the_wire_layout_is_the_vendor_definition_byte_for_byte():
    store = typestore()
    r = record(4_294_967_295, 3, mode_machine=4, mode_pr=1,
               motor_status=np.arange(MOTOR_SLOTS, dtype=np.uint32) << 3)
    data = lowstate_cdr(r)
    msg = store.deserialize_cdr(data, LOWSTATE_TYPE)
    assert store.serialize_cdr(msg, LOWSTATE_TYPE) == data          # rosbags writes the same bytes
    assert (msg.tick, msg.mode_machine, msg.mode_pr) == (4_294_967_295, 4, 1)
    assert msg.motor_state[28].q == pytest.approx(r.q[28]) and msg.motor_state[28].mode == 1
    for read in (lowstate_record(data), lowstate_from_msg(msg)):
        assert read.tick == r.tick and read.mode_machine == 4 and read.mode_pr == 1
        for field in ('q', 'dq', 'tau_est', 'imu_quat_wxyz', 'gyro_rad_s', 'accel_m_s2'):
            np.testing.assert_allclose(getattr(read, field), getattr(r, field), rtol=1e-6, atol=1e-7)
        np.testing.assert_array_equal(read.motor_status, r.motor_status)
    with pytest.raises(WireFormatError, match='bytes'):
        lowstate_record(data[:100])
    assert LOWSTATE.subscription_qos.reliability == 'best_effort'


def test_the_motor_tables_name_joints_of_the_urdfs():
    urdf_joints = set(G1.joint_names)
    for variant in G1.unitree_hg.variants.values():
        named = {m for m in variant.motors if m} | set(variant.fixed_joints)
        assert named == urdf_joints, variant.name           # every joint once, nothing else
    assert G1.unitree_hg.variants[5].motors == G1.joint_names   # the URDF's order is the motors'
    assert G1.unitree_hg.variants[4].motors.count('') == 6
    twelve = G1_12.unitree_hg.variants[5]
    assert twelve.motors[:12] == G1_12.joint_names                   # leg_joint2motor_idx 0..11
    assert set(twelve.motors[12:]) == set(G1_12.unitree_hg.held_joints)   # motors 12..28 held
    with pytest.raises(ValueError, match='mode_machine'):
        parse_unitree_hg('p', {'variants': [{'name': 'x', 'motors': []}]})


def converted(receive_ns, ticks, **kwargs):
    converter = LowStateConverter(G1.unitree_hg, G1.imu_frame, **kwargs)
    return converter, [converter.convert(record(t, k), r) for k, (t, r) in enumerate(zip(ticks, receive_ns))]


def test_stamps_keep_the_ticks_spacing_not_the_receive_jitter():
    rng = np.random.default_rng(0)
    n = 400
    ticks = 1000 + 2 * np.arange(n)
    receive = EPOCH_NS + ticks * 1_000_000 + 400_000 + rng.integers(0, 3_000_000, n)
    converter, samples = converted(receive, ticks)
    stamps = np.array([s.stamp_ns for s in samples])
    steps = np.diff(stamps)
    # After the least-delayed message has been seen, a step is the tick's 2 ms plus the drift
    # allowance (200 ppm: 400 ns), less a correction when a message comes quicker; before it, a
    # step is at least half of it. The receive jitter (3 ms) never shows.
    assert steps.min() >= 1_000_000
    settled = steps[np.argmin(receive - ticks * 1_000_000):]
    assert np.median(settled) == 2_000_400
    assert np.all(np.abs(settled - 2_000_000) <= 50_000)
    assert np.all(stamps <= receive)                       # never later than the message arrived
    assert samples[0].joints.names == G1.joint_names and samples[0].imu.frame_id == 'imu_in_pelvis'
    assert converter.take_notices() == ['/lowstate: mode_machine 5 (g1_29dof_rev_1_0), 29 motors '
                                        'named by the robot profile']
    np.testing.assert_allclose(samples[0].imu.orientation_xyzw, [0, 0, 0, 1])


def test_a_gap_in_the_ticks_stays_a_gap_and_a_duplicate_is_dropped():
    ticks = [10, 12, 14, 24, 26]                           # four messages lost after 14
    receive = [EPOCH_NS + t * 1_000_000 for t in ticks]
    converter, samples = converted(receive, ticks)
    assert samples[3].stamp_ns - samples[2].stamp_ns == 10_000_000
    again = converter.convert(record(26, 4), receive[-1] + 300_000)
    assert again is None and converter.counts['duplicate_messages'] == 1


def test_a_mode_machine_the_profile_does_not_describe_is_said_in_words():
    converter = LowStateConverter(G1_12.unitree_hg, G1_12.imu_frame, profile_name='g1_12dof')
    sample = converter.convert(record(5, mode_machine=4), EPOCH_NS)
    assert sample.joints is None
    assert sample.fault == ('/lowstate says mode_machine 4, but g1_12dof describes 5 '
                            '(g1_29dof_rev_1_0): its motors would be named wrong; start the monitor '
                            'with the profile of this robot\'s variant')
    ab = converter.convert(record(7, 1, mode_pr=1), EPOCH_NS + 2_000_000)
    assert 'motors A/B (mode_pr 1)' in ab.fault


def test_the_23_joint_variant_fills_the_joints_it_lacks():
    converter = LowStateConverter(G1.unitree_hg, G1.imu_frame, G1.joint_names)
    sample = converter.convert(record(5, mode_machine=4), EPOCH_NS)
    assert not sample.fault and sorted(sample.joints.names) == sorted(G1.joint_names)
    names = list(sample.joints.names)
    assert sample.joints.position[names.index('waist_roll_joint')] == 0.0
    assert sample.joints.position[names.index('left_shoulder_pitch_joint')] == pytest.approx(record(5).q[15])


def g1_standing_lowstate(n: int):
    """test/g1_streams.py's standing G1 (known CoM height) as its board's lowstate: the joints
    at their motor slots, the IMU w-x-y-z, tick in ms, received 0.4 ms after each tick."""
    from g1_streams import g1_standing
    messages, com_height, _ = g1_standing(n)
    slot = {name: k for k, name in enumerate(G1.unitree_hg.variants[5].motors)}
    records = []
    for (_, joints), (_, imu) in zip(messages[0::2], messages[1::2]):
        k = len(records)
        q, dq, tau = np.zeros(MOTOR_SLOTS), np.zeros(MOTOR_SLOTS), np.zeros(MOTOR_SLOTS)
        index = [slot[name] for name in joints.names]
        q[index], dq[index], tau[index] = joints.position, joints.velocity, joints.effort
        x, y, z, w = imu.orientation_xyzw
        records.append((EPOCH_NS + k * 2_000_000 + 400_000, LowStateRecord(
            tick=1000 + 2 * k, mode_machine=5, mode_pr=0, imu_quat_wxyz=np.array([w, x, y, z]),
            gyro_rad_s=imu.angular_velocity, accel_m_s2=imu.linear_acceleration, q=q, dq=dq,
            tau_est=tau, motor_status=np.zeros(MOTOR_SLOTS, np.uint32))))
    return records, com_height


def estimates(records):
    from fall_predictor.monitor.sensor_pipeline import SensorPipeline
    layout = G1.sensor_layout()
    pipeline = SensorPipeline(layout.description(G1.urdf_xml()), layout.imu_frame, layout.force_sensors)
    converter = LowStateConverter(G1.unitree_hg, G1.imu_frame, G1.joint_names)
    out = []
    for receive_ns, r in records:
        sample = converter.convert(r, receive_ns)
        if sample is not None:
            out += pipeline.lowstate(sample)
    return out


def test_a_standing_g1s_lowstate_gives_its_known_com_height_and_each_fault_named():
    records, com_height = g1_standing_lowstate(60)
    good = estimates(records)
    assert len(good) == 60 and not any(e.fault for e in good[1:])
    assert good[-1].measurement.com[2] == pytest.approx(com_height, abs=0.005)
    faults = {
        # (new readings: the same ones again would be the same message twice, dropped)
        'repeated tick': (30, lambda r: replace(r, tick=records[29][1].tick, q=r.q + 1e-4),
                          'tick 1058 repeated'),
        'tick back': (30, lambda r: replace(r, tick=3), 'tick went back from 1058 to 3 ms'),
        'motor error': (30, lambda r: replace(r, motor_status=np.where(np.arange(MOTOR_SLOTS) == 9, 0x8, 0)
                                              .astype(np.uint32)), 'motor 9 (right_knee_joint) status 0x8'),
        'zero quaternion': (30, lambda r: replace(r, imu_quat_wxyz=np.zeros(4)), 'not a unit quaternion'),
        'mode_machine': (30, lambda r: replace(r, mode_machine=6), 'mode_machine 6'),
    }
    for name, (at, change, words) in faults.items():
        faulty = list(records)
        faulty[at] = (faulty[at][0], change(faulty[at][1]))
        if name == 'tick back':                 # the counter goes on from its new value
            faulty[at + 1:] = [(t, replace(r, tick=3 + 2 * (k + 1))) for k, (t, r) in enumerate(faulty[at + 1:])]
        out = estimates(faulty)
        refused = [e for e in out[1:] if e.fault]
        assert len(refused) == 1 and words in refused[0].fault, (name, [e.fault for e in refused])
        assert refused[0].measurement is None and out[-1].measurement is not None, name
