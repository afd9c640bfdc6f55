"""state_estimator_node over DDS: the robot's sensor topics as its drivers publish them in, the
offline pipeline's measurements out; faults said in words, never a crash."""
from __future__ import annotations

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import String
from g1_streams import g1_standing
from test_nodes_support import ros_context, test_domain_id

from fall_predictor.contract import cdr, messages
from fall_predictor.contract.topics import (IMU, LEFT_FOOT_WRENCH, MEASUREMENT, RIGHT_FOOT_WRENCH,
                                            ROBOT_DESCRIPTION, SENSOR_JOINT_STATES)
from fall_predictor.monitor.records import PushSpec
from fall_predictor.monitor.sensor_pipeline import SensorPipeline
from fall_predictor.msg import Measurement
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.runner import spin_until
from fall_predictor.ros.state_estimator_node import StateEstimatorNode
from fall_predictor.sim.drivers import DriverTiming, driver_messages
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory

DOMAIN = test_domain_id(162)
N = 300
LEGS = tuple(f'{s}_{j}' for s in rm.SIDES for j in rm.LEG_JOINTS)
UPPER = tuple(n for n in rm.JOINT_NAMES if n not in LEGS)
BUILD = {'joints': messages.joint_state_msg, 'imu': messages.imu_msg,
         'l': messages.wrench_msg, 'r': messages.wrench_msg}


@pytest.fixture(scope='module')
def samples():
    run = run_trajectory(PushSpec(60.0, 0.0, 0.1, 0.2), 0.4, record_sensors=True)
    return apply_sensors(run.sensor_truths, SensorParams(), seed=2)[:N]


def offline(samples, timing: DriverTiming) -> dict[int, object]:
    """The pipeline run offline over the same messages: estimates by stamp."""
    layout = rm.PROFILE.sensor_layout()
    pipeline = SensorPipeline(layout.description(rm.URDF_PATH.read_text()), layout.imu_frame)
    out = []
    for stream, reading in driver_messages(samples, timing):
        out += (pipeline.joint_state(reading)[0] if stream == 'joints' else
                pipeline.imu(reading) if stream == 'imu' else pipeline.wrench(stream, reading))
    return {e.stamp_ns: e for e in out}


def _drive(messages_in, description: str, expected: int = 0, params=()):
    from rclpy.parameter import Parameter
    with ros_context(DOMAIN) as context:
        node = StateEstimatorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params])
        io = Node('estimator_test_io', context=context)
        got = []
        create_subscription(io, Measurement, MEASUREMENT,
                            lambda m: got.append(messages.measurement_from_msg(m)), lossless=True)
        pubs = {'joints': create_publisher(io, JointState, SENSOR_JOINT_STATES),
                'imu': create_publisher(io, Imu, IMU),
                'l': create_publisher(io, WrenchStamped, LEFT_FOOT_WRENCH),
                'r': create_publisher(io, WrenchStamped, RIGHT_FOOT_WRENCH)}
        desc = create_publisher(io, String, ROBOT_DESCRIPTION)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        executor.add_node(io)
        try:
            messages_in = list(messages_in)
            used = [pubs[stream] for stream in {stream for stream, _ in messages_in}]
            assert spin_until(executor, lambda: all(p.get_subscription_count() for p in used)
                              and desc.get_subscription_count() > 0, 10.0)
            desc.publish(String(data=description))
            spin_until(executor, lambda: node._pipeline is not None, 2.0)
            for stream, reading in messages_in:
                pubs[stream].publish(BUILD[stream](ros_qos.TYPES, reading))
                # The node reads its sensors best effort with shallow queues (REP 2003): let it
                # take each message before the next one is published.
                key = {'joints': 'joint_messages', 'imu': 'imu_messages'}.get(stream, 'wrench_messages')
                taken = node.counts[key]
                spin_until(executor, lambda: node.counts[key] > taken, 0.5)
            spin_until(executor, lambda: len(got) >= expected, 20.0 if expected else 1.0)
            return got, dict(node.counts), node
        finally:
            executor.shutdown()
            node.destroy_node()
            io.destroy_node()


@pytest.mark.parametrize('timing', [
    DriverTiming(),
    DriverTiming.robot(joint_rate_hz=500.0, joint_groups=(LEGS, UPPER)),
], ids=['simulator', 'robot_500hz_split_epoch'])
def test_the_node_publishes_what_the_offline_pipeline_computes(samples, timing):
    """Over DDS the node makes exactly the offline pipeline's estimates, each stamped with its
    driving message's own stamp (epoch stamps included), for simulator-timed and robot-timed
    streams."""
    expected = offline(samples, timing)
    params = [('driving_joints', list(LEGS))] if timing.joint_groups else []
    got, counts, _ = _drive(driver_messages(samples, timing), rm.URDF_PATH.read_text(),
                            expected=len(expected), params=params)
    assert sorted(g.stamp_ns for g in got) == sorted(expected)
    assert counts['measurements'] + counts['faults'] == len(got)
    assert counts['rclpy_decoded_messages'] == 0        # every sensor message read as CDR
    for g in got:
        ref = expected[g.stamp_ns]
        assert g.fault == ref.fault
        if ref.measurement is not None:
            assert np.allclose(g.measurement.com, ref.measurement.com, atol=1e-12)
            assert np.allclose(g.measurement.lin_mom, ref.measurement.lin_mom, atol=1e-12)
            assert np.allclose(g.measurement.left_contacts, ref.measurement.left_contacts,
                               atol=1e-12)
    assert sum(g.measurement is not None for g in got) >= len(got) - 5


def test_a_description_without_sole_frames_is_logged_not_fatal(samples):
    # Without sole frames the profile adds them on the foot links; without those either, the
    # description cannot serve.
    urdf = rm.urdf_xml(sole_frames=False).replace('"l_foot"', '"l_paw"')
    got, counts, node = _drive(driver_messages(samples[:20]), urdf)
    assert node._pipeline is None and got == [] and counts['measurements'] == 0
    assert 'needs both sole frames' in node._bad_inputs.last


def test_a_sensor_that_stops_gives_faults_in_words_not_zeros(samples):
    """The right foot's sensor stops after 100 ms: every later estimate is a fault naming it."""
    kept = [(s, r) for s, r in driver_messages(samples[:200])
            if not (s == 'r' and r.stamp_ns >= 100_000_000)]
    got, counts, node = _drive(kept, rm.URDF_PATH.read_text(), expected=200)
    late = [g for g in got if g.stamp_ns >= 110_000_000]
    assert late and all(g.measurement is None for g in late)
    assert all(g.fault.startswith('no /right_foot/wrench within 5 ms of /joint_states') for g in late)
    assert counts['faults'] >= len(late)
    assert 'no /right_foot/wrench within 5 ms of /joint_states' in node._faults.current()


def test_simulator_sensor_topics_through_the_estimator_track_the_ground_truth():
    from rclpy.parameter import Parameter

    from fall_predictor.contract.topics import GROUND_TRUTH
    from fall_predictor.ros.simulator_node import SimulatorNode

    with ros_context(DOMAIN) as context:
        sim = SimulatorNode(context=context, parameter_overrides=[
            Parameter('publish_sensors', value=True), Parameter('lockstep', value=False),
            Parameter('real_time_factor', value=1.0), Parameter('sensor_joint_rate_hz', value=500.0),
            Parameter('sensor_imu_offset_s', value=0.0003),
            Parameter('sensor_wrench_offset_s', value=0.0004),
            Parameter('sensor_split_joints', value=True)])
        est = StateEstimatorNode(context=context, parameter_overrides=[
            Parameter('driving_joints', value=list(LEGS))])
        io = Node('estimator_test_truth', context=context)
        truth, estimated = {}, {}

        def keep(store):
            def on(msg):
                decoded = messages.measurement_from_msg(msg)
                if decoded.measurement is not None:
                    store.setdefault(decoded.stamp_ns, decoded.measurement)
            return on
        create_subscription(io, Measurement, GROUND_TRUTH, keep(truth))
        create_subscription(io, Measurement, MEASUREMENT, keep(estimated))
        executor = SingleThreadedExecutor(context=context)
        for n in (sim, est, io):
            executor.add_node(n)
        try:
            assert spin_until(executor, lambda: len(estimated) >= 300, 30.0)
        finally:
            executor.shutdown()
            for n in (sim, est, io):
                n.destroy_node()
    common = sorted(set(truth) & set(estimated))
    assert len(common) >= 250
    # One estimate per 500 Hz joint state cycle, stamped with the joint states' stamps.
    assert set(np.diff(sorted(estimated))) == {2_000_000}
    # The estimator's world frame is the one the robot stood in when the estimator started (an
    # odometry frame, REP 105): its horizontal origin is aligned with the truth's at the first
    # common sample, as any comparison against motion capture does (heights need no alignment:
    # z = 0 is the ground). From there on, the estimate from the sensors alone stays within
    # millimetres of the truth.
    offset = truth[common[0]].com - estimated[common[0]].com
    offset[2] = 0.0
    errors = [np.linalg.norm(estimated[k].com + offset - truth[k].com) for k in common]
    assert np.percentile(errors, 99) < 0.01
    assert max(abs(estimated[k].com[2] - truth[k].com[2]) for k in common) < 0.01
    assert all(len(estimated[k].left_contacts) and len(estimated[k].right_contacts) for k in common[-50:])


def test_fall_monitor_runs_the_estimator_in_front_of_the_monitor(tmp_path):
    """``fall_monitor --estimator``: three nodes in one process, each reporting on
    /diagnostics (the estimator waits for a robot description: STALE, not dead)."""
    import sys

    from diagnostic_msgs.msg import DiagnosticArray

    from fall_predictor.ros.bringup import ros_environment, start_process, stop_nodes

    domain = test_domain_id(165)
    process = start_process('fall_monitor', [
        sys.executable, '-m', 'fall_predictor.ros.fall_monitor', '--estimator', '--ros-args',
        '-p', 'start_type_description_service:=false'], ros_environment(domain), tmp_path)
    statuses = {}
    try:
        with ros_context(domain) as context:
            node = Node('watcher', context=context)
            node.create_subscription(DiagnosticArray, '/diagnostics',
                                     lambda msg: statuses.update((s.name, s) for s in msg.status), 50)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            assert spin_until(executor, lambda: {'/state_estimator_node', '/feature_node',
                                                 '/predictor_node'} <= set(statuses), 60.0), (
                statuses, process.log_tail())
            node.destroy_node()
    finally:
        codes = stop_nodes({'fall_monitor': process})
    assert codes == {'fall_monitor': 0}
    estimator = statuses['/state_estimator_node']
    assert estimator.message == 'no usable robot description yet'


def test_a_g1_standing_on_its_topics_without_foot_sensors():
    """robot:=g1: the G1's description, joint states with efforts at 500 Hz in the driver's order,
    its pelvis IMU, no wrench topics: the node estimates every sample, on both feet, with the CoM
    height and the CoP the statics give (known answer, to the millimetre), stamped as received."""
    from fall_predictor.profiles.profile import load_profile
    sensor_messages, com_height, cop_offset = g1_standing(60)
    got, counts, node = _drive(sensor_messages, load_profile('g1').urdf_xml(), expected=55,
                               params=[('robot', 'g1')])
    assert node._pipeline is not None and counts['wrench_messages'] == 0
    stamps = {r.stamp_ns for s, r in sensor_messages if s == 'joints'}
    estimates = [g for g in got if g.measurement is not None]
    assert len(estimates) >= 55 and {g.stamp_ns for g in got} <= stamps
    for g in estimates:
        m = g.measurement
        assert len(m.left_contacts) == 4 and len(m.right_contacts) == 4
        assert m.com[2] == pytest.approx(com_height, abs=1e-3)
        # The world frame's origin lies between the soles: the CoP sits at the CoM's offset.
        assert m.cop[:2] == pytest.approx(cop_offset, abs=1e-3)
        assert np.linalg.norm(m.lin_mom) < 1e-3


def test_a_message_cdr_cannot_read_is_decoded_by_rclpy_and_garbage_is_refused():
    """The node reads its sensor messages as little-endian CDR; a big-endian one (built here by
    hand with ``struct``) goes to rclpy's deserialization, counted; bytes nothing reads raise the
    wire-format error the node's guard counts (never a crash)."""
    import struct
    from fall_predictor.contract.topics import WireFormatError
    frame = b'l_sole\x00'
    body = struct.pack('>iII', 12, 345, len(frame)) + frame
    body += b'\x00' * ((-len(body)) % 8) + struct.pack('>6d', 1.0, 2.0, 300.0, 4.0, 5.0, 6.0)
    big_endian = b'\x00\x00\x00\x00' + body
    with ros_context(DOMAIN) as context:
        node = StateEstimatorNode(context=context)
        try:
            reading = node._read(big_endian, cdr.wrench_reading, WrenchStamped,
                                 messages.wrench_reading)
            assert (reading.stamp_ns, reading.frame_id) == (12_000_000_345, 'l_sole')
            np.testing.assert_array_equal(reading.wrench, [1.0, 2.0, 300.0, 4.0, 5.0, 6.0])
            assert node.counts['rclpy_decoded_messages'] == 1
            with pytest.raises(WireFormatError):
                node._read(b'\x00\x00\x00\x00\x01', cdr.wrench_reading, WrenchStamped,
                           messages.wrench_reading)
        finally:
            node.destroy_node()
