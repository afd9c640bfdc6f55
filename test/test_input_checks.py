"""Readings that feed the estimate are checked like the others (refused, counted, a reason), and
text from the wire is bounded: a G1 standing still on its own topics (no foot F/T: its contacts
come from the leg efforts), with a known answer (:func:`g1_streams.g1_standing`)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from g1_streams import g1_standing

from fall_predictor.contract import messages
from fall_predictor.monitor.fall_monitor import STATUS_DEGRADED, FallenConfig, FallMonitor
from fall_predictor.monitor.plausibility import MAX_TEXT_CHARS, bound_names, bound_text
from fall_predictor.monitor.sensor_pipeline import SensorPipeline
from fall_predictor.monitor.sensor_records import JointStateReading
from fall_predictor.profiles.profile import load_profile
from fall_predictor.ros import conversions as ros_qos

G1 = load_profile('g1')
#: Samples 20-29 of the stream carry the bad values.
BAD = range(20, 30)


def pipeline() -> SensorPipeline:
    layout = G1.sensor_layout()
    return SensorPipeline(layout.description(G1.urdf_xml()), layout.imu_frame, layout.force_sensors)


def run(change) -> tuple[list, SensorPipeline]:
    stream, _, _ = g1_standing(50)
    p = pipeline()
    out = []
    k = 0
    for name, reading in stream:
        if name == 'joints':
            reading = change(k, reading)
            k += 1
        out += p.add(name, reading)
    return out + p.flush(), p


def with_effort(joint: str, value: float):
    def change(k: int, r: JointStateReading) -> JointStateReading:
        if k not in BAD:
            return r
        effort = r.effort.copy()
        effort[r.names.index(joint)] = value
        return replace(r, effort=effort)
    return change


@pytest.mark.parametrize('value', [np.nan, np.inf, -np.inf, 1e6])
def test_a_leg_effort_that_is_not_finite_or_impossible_is_refused_with_a_reason(value) -> None:
    """The left knee's effort feeds the left sole's wrench: the samples that carry a bad one are
    not estimated (a DEGRADED state downstream), say why, and are counted; the others are exact."""
    clean, _ = run(lambda k, r: r)
    got, p = run(with_effort('left_knee_joint', value))
    faulted = [e for e in got if e.measurement is None]
    assert [got.index(e) for e in faulted] == list(BAD)
    assert all(e.fault.startswith(f'joint efforts refused: left_knee_joint {value:.4g} (the feet '
                                  'without force sensors take their contact from the leg efforts)')
               for e in faulted), faulted[0].fault
    assert p.sync.counts['refused_efforts'] == len(BAD)
    # Every other sample is the clean stream's estimate (the CoM to the nanometre).
    for a, b in zip(got, clean):
        if a.measurement is not None:
            assert np.allclose(a.measurement.com, b.measurement.com, atol=1e-9)


def test_an_arm_effort_that_is_not_finite_does_not_touch_the_estimate() -> None:
    """An arm's effort feeds nothing (the legs carry the feet): refused and counted, the samples
    still estimated as without it -- where a NaN anywhere used to switch the feet to statics and
    move the CoM."""
    clean, _ = run(lambda k, r: r)
    got, p = run(with_effort('left_elbow_joint', np.nan))
    assert all(e.measurement is not None for e in got)
    assert p.sync.counts['refused_efforts'] == len(BAD)
    com = np.array([e.measurement.com for e in got])
    assert np.abs(com - np.array([e.measurement.com for e in clean])).max() < 1e-9


def test_a_driver_that_stops_reporting_efforts_is_a_fault_one_that_never_did_is_statics() -> None:
    dropped, _ = run(lambda k, r: replace(r, effort=np.zeros(0)) if k in BAD else r)
    faulted = [e for e in dropped if e.measurement is None]
    assert len(faulted) == len(BAD) and 'left_hip_pitch_joint not reported' in faulted[0].fault
    never, p = run(lambda k, r: replace(r, effort=np.zeros(0)))
    assert all(e.measurement is not None for e in never)          # statics, as documented
    assert p.estimator.foot_wrenches.source == 'statics'


@pytest.mark.parametrize('names, words', [
    ((), '/joint_states message with no joints (empty names)'),
    (('gripper_left', 'gripper_right'), '/joint_states names only joints the robot description '
     "lacks (gripper_left, gripper_right): is the robot_description this robot's?"),
])
def test_joint_states_without_the_robots_joints_say_why(names, words) -> None:
    """A driver that publishes messages without the robot's joints: each is a sample with a fault
    in words (not a silent missing sample); the same message from a second publisher while the
    robot's joints arrive is ignored."""
    stream, _, _ = g1_standing(10)
    p = pipeline()
    for name, reading in stream:
        p.add(name, reading)
    # The robot's driver goes silent; the other one goes on, 2 ms apart, past the joint timeout.
    stamp0 = stream[-2][1].stamp_ns
    faults = []
    for k in range(1, 40):
        faults += p.add('joints', JointStateReading(stamp0 + k * 2_000_000, names,
                                                    np.zeros(len(names))))
    faults += p.flush()
    worded = [e for e in faults if e.fault == words]
    # Words from the first message past the joint timeout (50 ms: k = 26); before it the robot may still speak.
    assert len(worded) == 39 - 25 and all(e.measurement is None for e in faults)
    assert p.counts['joint_messages_unused'] == len(worded)
    # With the robot's own joints arriving, another publisher's message changes nothing.
    q = pipeline()
    for name, reading in stream:
        assert not [e for e in q.add(name, reading) if e.fault]
        if name == 'joints':
            assert not q.add('joints', JointStateReading(reading.stamp_ns + 1_000_000, names,
                                                         np.zeros(len(names))))


def test_text_from_the_wire_is_bounded_in_states_and_messages() -> None:
    """A 1 MB fault string in a features message: decoded bounded, and the state's reason is
    bounded too (it is copied into every state and log line)."""
    huge = 'x' * 1_000_000
    msg = messages.features_msg(ros_qos.TYPES, 5_000_000_000, None, None, 0.0, fault=huge)
    decoded = messages.features_from_msg(msg)
    assert len(decoded.fault) < MAX_TEXT_CHARS + 40
    assert decoded.fault.endswith('(1000000 characters, cut)')
    from fall_predictor.monitor.decision_list import DecisionList, PerModeDecisionLists
    from fall_predictor.monitor.records import N_CONTACT_MODES
    monitor = FallMonitor(PerModeDecisionLists(tuple(DecisionList(()) for _ in range(N_CONTACT_MODES))),
                          0.0, FallenConfig(0.3, 0.5))
    state = monitor.unusable(huge)
    assert state.status == STATUS_DEGRADED and len(state.reason) <= MAX_TEXT_CHARS + 40
    assert bound_text('short') == 'short'
    assert bound_names(['a' * 1000, 'b', 'c', 'd', 'e', 'f', 'g', 'h']).endswith('f and 2 more')


def test_a_joint_name_of_a_megabyte_is_refused_not_remembered() -> None:
    p = pipeline()
    with pytest.raises(ValueError, match='a joint name of 1000000 characters'):
        p.add('joints', JointStateReading(1, ('j' * 1_000_000,), np.zeros(1)))
    assert not p.sync.joints.unknown
    # Unknown names are remembered up to a bound, then only counted.
    for k in range(300):
        p.add('joints', JointStateReading(2 + k, (f'other_{k}',), np.zeros(1)))
    assert len(p.sync.joints.unknown) == 200 and p.sync.joints.unknown_beyond_bound == 100
