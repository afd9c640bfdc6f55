"""state_estimator_node over DDS: the same measurements as the offline estimator (stream ==
batch), and no crash on a bad description or bad samples."""
from __future__ import annotations

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray, String
from test_nodes_support import ros_context, test_domain_id

from fall_predictor.data.topics import (IMU, LEFT_FOOT_WRENCH, MEASUREMENT, RIGHT_FOOT_WRENCH, ROBOT_DESCRIPTION,
                                        SENSOR_JOINT_STATES)
from fall_predictor.monitor.estimator import StateEstimator
from fall_predictor.monitor.records import PushSpec
from fall_predictor.robot import model as rm
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.common import create_publisher, create_subscription, spin_until
from fall_predictor.ros.sensor_conversions import reading_to_msgs
from fall_predictor.ros.state_estimator_node import StateEstimatorNode
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import run_trajectory

DOMAIN = test_domain_id(162)
N = 300


@pytest.fixture(scope='module')
def readings():
    run = run_trajectory(PushSpec(60.0, 0.0, 0.1, 0.2), 0.4, record_sensors=True)
    return apply_sensors(run.sensor_truths, SensorParams(), seed=2)[:N]


def _drive(readings, description: str, expected: int = 0):
    with ros_context(DOMAIN) as context:
        node = StateEstimatorNode(context=context)
        io = Node('estimator_test_io', context=context)
        got = []
        create_subscription(io, Float64MultiArray, MEASUREMENT,
                            lambda m: got.append(ros_qos.measurement_from_msg(m)), lossless=True)
        pubs = [create_publisher(io, JointState, SENSOR_JOINT_STATES), create_publisher(io, Imu, IMU),
                create_publisher(io, WrenchStamped, LEFT_FOOT_WRENCH),
                create_publisher(io, WrenchStamped, RIGHT_FOOT_WRENCH)]
        desc = create_publisher(io, String, ROBOT_DESCRIPTION)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        executor.add_node(io)
        try:
            assert spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs)
                              and desc.get_subscription_count() > 0, 10.0)
            desc.publish(String(data=description))
            spin_until(executor, lambda: node._estimator is not None, 2.0)
            for r in readings:
                for pub, msg in zip(pubs, reading_to_msgs(r)):
                    pub.publish(msg)
                # The node reads its sensors best effort with shallow queues (REP 2003): let it
                # take each sample's four messages before the next ones are published.
                taken = node.counts['samples'] + node.counts['incomplete']
                spin_until(executor, lambda: node.counts['samples'] + node.counts['incomplete']
                           > taken or node._estimator is None, 0.5)
            spin_until(executor, lambda: len(got) >= expected, 20.0 if expected else 1.0)
            return got, dict(node.counts), node._estimator
        finally:
            executor.shutdown()
            node.destroy_node()
            io.destroy_node()


def test_the_node_publishes_what_the_offline_estimator_computes(readings):
    offline = [m for m in StateEstimator(rm.URDF_PATH.read_text()).run(readings) if m is not None]
    got, counts, estimator = _drive(readings, rm.URDF_PATH.read_text(), expected=len(offline))
    assert len(got) == len(offline) and counts['measurements'] == len(got) and counts['rejected'] == 0
    by_t = {round(m.t * 1000): m for m in offline}
    for m in got:
        ref = by_t[round(m.t * 1000)]
        assert np.allclose(m.com, ref.com, atol=1e-12) and np.allclose(m.lin_mom, ref.lin_mom, atol=1e-12)
        assert np.allclose(m.left_contacts, ref.left_contacts, atol=1e-12)


def test_a_description_without_sole_frames_is_logged_not_fatal(readings):
    got, counts, estimator = _drive(readings[:20], rm.urdf_xml(sole_frames=False))
    assert estimator is None and got == [] and counts['samples'] == 0


def test_simulator_sensor_topics_through_the_estimator_track_the_ground_truth():
    from rclpy.parameter import Parameter

    from fall_predictor.data.topics import GROUND_TRUTH
    from fall_predictor.ros.simulator_node import SimulatorNode

    with ros_context(DOMAIN) as context:
        sim = SimulatorNode(context=context, parameter_overrides=[
            Parameter('publish_sensors', value=True), Parameter('lockstep', value=False),
            Parameter('real_time_factor', value=1.0)])
        est = StateEstimatorNode(context=context)
        io = Node('estimator_test_truth', context=context)
        truth, estimated = {}, {}
        create_subscription(io, Float64MultiArray, GROUND_TRUTH,
                            lambda m: truth.setdefault(round(ros_qos.measurement_from_msg(m).t * 1000),
                                                       ros_qos.measurement_from_msg(m)))
        create_subscription(io, Float64MultiArray, MEASUREMENT,
                            lambda m: estimated.setdefault(round(ros_qos.measurement_from_msg(m).t * 1000),
                                                           ros_qos.measurement_from_msg(m)))
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
    # The simulator publishes the ground truth on its own topic. The estimator's world frame is
    # the one the robot stood in when the estimator started (an odometry frame, REP 105): its
    # horizontal origin is aligned with the truth's at the first common sample, as any
    # comparison against motion capture does (heights need no alignment: z = 0 is the ground).
    # From there on, the estimate from the sensors alone stays within millimetres of the truth.
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
    names = set()
    try:
        with ros_context(domain) as context:
            node = Node('watcher', context=context)
            node.create_subscription(DiagnosticArray, '/diagnostics',
                                     lambda msg: names.update(s.name for s in msg.status), 50)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            assert spin_until(executor, lambda: {'/state_estimator_node', '/feature_node',
                                                 '/predictor_node'} <= names, 60.0), (
                names, process.log_tail())
            node.destroy_node()
    finally:
        codes = stop_nodes({'fall_monitor': process})
    assert codes == {'fall_monitor': 0}
