"""recorder_node on a robot's clock: the monitor's outputs stamped in ROS time (seconds since
1970, as a robot's drivers stamp the samples they come from) are recorded at those stamps, gaps
counted (not from a staleness report stamped 0), and read back by the package's reader; the
robot's own ``/joint_states``, stamped by its drivers on the same clock, likewise, and those of a
robot that measures no joint efforts, as Fast DDS sends them (4 bytes after the message). Fed in
process, through the subscriptions' own callbacks (the raw bytes DDS hands them), so no DDS
discovery is involved."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message

from fall_predictor.contract import messages
from fall_predictor.contract.topics import FALL_DIRECTION, JOINT_STATES, MEASUREMENT, STATE
from fall_predictor.data.bagio import iter_messages, read_trajectory
from fall_predictor.monitor.fall_monitor import MonitorState
from fall_predictor.monitor.sensor_records import JointStateReading
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.recorder_node import RecorderNode
from test_nodes_support import ros_context, test_domain_id
from test_recorder_crash import measurement

#: 2026-11-27 08:00:00 UTC: a robot's stamp, far beyond the simulation-time range.
ROBOT_EPOCH_NS = 1_795_852_800 * 1_000_000_000
SKIPPED = {40, 41, 42}


def test_monitor_outputs_stamped_in_ros_time_are_recorded_at_their_stamps(tmp_path: Path) -> None:
    bags = tmp_path / 'bags'
    stamps = [ROBOT_EPOCH_NS + 1_000_000 * k for k in range(200) if k not in SKIPPED]
    with ros_context(test_domain_id(175)) as context:
        node = RecorderNode(context=context, parameter_overrides=[Parameter('bag_path', value=str(bags))])
        try:
            on_measurement = node._queue_callback(MEASUREMENT.name)
            on_state = node._queue_callback(STATE.name)
            on_direction = node._queue_callback(FALL_DIRECTION.name)
            on_joints = node._queue_callback(JOINT_STATES.name)     # the robot's own drivers
            # The predictor's staleness report before its first input is stamped 0.
            stale = MonitorState(2, reason='no features received for 1.00 s')
            on_state(serialize_message(messages.fall_state_msg(ros_qos.TYPES, 0, 'base_footprint', stale)))
            for k, ns in enumerate(stamps):
                m = measurement(0.0)
                on_measurement(serialize_message(messages.measurement_msg(ros_qos.TYPES, ns, 'odom', m)))
                state = MonitorState(0, contact_mode=0, tau_his_s=0.2)
                on_state(serialize_message(messages.fall_state_msg(ros_qos.TYPES, ns, 'base_footprint', state)))
                if k == 100:
                    on_direction(serialize_message(ros_qos.fall_direction_msg(ns, (1.0, 0.0))))
                if k % 10 == 0:
                    joints = JointStateReading(ns, ('knee', 'hip'), np.array([0.3, -0.1]),
                                               np.array([0.01, 0.0]), np.array([12.0, -3.5]))
                    on_joints(serialize_message(messages.joint_state_msg(ros_qos.TYPES, joints)))
        finally:
            node.destroy_node()                 # drains the queue, closes the bags
        summary = node.summary()
    assert summary['rejected'][MEASUREMENT.name] == 0 and summary['write_errors'] == 0, summary
    run = bags / 'run_000'
    recorded = read_trajectory(run)
    # Read back as float seconds: at 1.8e9 s a float resolves 0.24 us, so compare milliseconds.
    assert [round(m.t * 1e3) for m in recorded.measurements] == [ns // 1_000_000 for ns in stamps]
    record = json.loads((run / 'fall_predictor.json').read_text())
    assert record['written'][MEASUREMENT.name] == len(stamps)
    assert record['missing_samples'][MEASUREMENT.name] == len(SKIPPED)
    assert record['missing_samples'][STATE.name] == len(SKIPPED)
    assert record['written'][STATE.name] == len(stamps) + 1
    logged = {m.topic: m.t_ns for m in iter_messages(run, [FALL_DIRECTION.name, STATE.name])}
    assert logged[FALL_DIRECTION.name] == stamps[100]       # at the latest measurement's stamp
    assert logged[STATE.name] == stamps[-1]
    assert summary['rejected'][JOINT_STATES.name] == 0
    assert [m.t_ns for m in iter_messages(run, [JOINT_STATES.name])] == stamps[::10]
    assert np.isclose(recorded.measurements[0].com[2], 0.59)


def test_joint_states_of_a_robot_without_effort_sensing_are_recorded(tmp_path: Path) -> None:
    """Fast DDS sends a ``JointState`` whose ``effort`` is empty with 4 bytes after its last member,
    which rosbags' own decoding refuses: the recorder rejected every such message before."""
    bags = tmp_path / 'bags'
    stamps = [ROBOT_EPOCH_NS + 2_000_000 * k for k in range(50)]
    with ros_context(test_domain_id(176)) as context:
        node = RecorderNode(context=context, parameter_overrides=[Parameter('bag_path', value=str(bags))])
        try:
            on_joints = node._queue_callback(JOINT_STATES.name)
            for ns in stamps:
                joints = JointStateReading(ns, ('knee', 'hip'), np.array([0.3, -0.1]),
                                           np.array([0.01, 0.0]), np.array([0.0, 0.0]))
                msg = messages.joint_state_msg(ros_qos.TYPES, joints)
                msg.effort = []                 # the robot measures no joint efforts
                on_joints(serialize_message(msg))
        finally:
            node.destroy_node()
        summary = node.summary()
    assert summary['rejected'][JOINT_STATES.name] == 0 and summary['written'][JOINT_STATES.name] == 50
    recorded = list(iter_messages(bags / 'run_000', [JOINT_STATES.name]))
    assert [m.t_ns for m in recorded] == stamps
    assert all(len(m.msg.effort) == 0 and m.msg.position.tolist() == [0.3, -0.1] for m in recorded)
