"""A G1 on its own topic over DDS: ``fall_monitor --estimator`` with ``input:=unitree_hg`` and the
profile ``g1_12dof`` (Unitree's policy on the 29-joint robot) reads ``lowstate`` as a G1's board
publishes it (500 Hz, serialized ``unitree_hg/msg/LowState``, no stamp, in real time), publishes the
profile's ``robot_description`` itself, and calls the fall of a simulated run with the lead of the
same run replayed offline through the same chain (within 0.05 s); a survived run raises no alarm."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

from fall_predictor.contract.topics import FALL_EVENT, ROBOT_DESCRIPTION
from fall_predictor.contract.unitree_hg import LOWSTATE, lowstate_cdr
from fall_predictor.data.onboard_replay import lowstate_messages, onboard_chain, replay
from fall_predictor.monitor.fall_monitor import EVENT_FALLING
from fall_predictor.monitor.lowstate import LowStateConverter
from fall_predictor.monitor.records import PushSpec
from fall_predictor.profiles.profile import load_profile
from fall_predictor.ros.bringup import ros_environment, start_process, stop_nodes
from fall_predictor.sim.lowstate_driver import lowstate_records
from test_nodes_support import ros_context, test_domain_id

unitree_hg_msg = pytest.importorskip('unitree_hg.msg', reason='scripts/build_interfaces.sh builds it')

PROFILE = load_profile('g1_12dof')
MODEL = Path(__file__).resolve().parents[1] / 'models' / PROFILE.model_for()   # as the monitor loads it
PUSH_AT_S = 2.5
RUNS = {'fall': (900.0, 0.0, 0.3), 'survived': (250.0, 0.0, 0.3)}


@pytest.fixture(scope='module')
def runs():
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.policy_runs import physics_dt_s
    from fall_predictor.sim.sensors import SensorParams, SensorSuite
    from fall_predictor.sim.trajectory import run_trajectory
    from fall_predictor.sim.world import make_world
    out = {}
    for k, (name, (force, angle, vx)) in enumerate(RUNS.items()):
        world = make_world(PROFILE, None, physics_dt_s(PROFILE.controller_profile()))
        out[name] = run_trajectory(PushSpec(force, angle, 0.1, PUSH_AT_S), 4.0, world=world,
                                   controller=make_controller(PROFILE, None, (vx, 0.0, 0.0),
                                                              dt_s=world.dt_s),
                                   sensors=SensorSuite(SensorParams(), k, world.dt_s, PROFILE))
        world.close()
    assert out['fall'].fallen and not out['survived'].fallen
    return out


def offline_alarm_s(readings) -> float:
    records = list(lowstate_records(readings, PROFILE.unitree_hg, 5))
    converter = LowStateConverter(PROFILE.unitree_hg, PROFILE.imu_frame, PROFILE.joint_names)
    messages, index = lowstate_messages(records, converter)
    result = replay(onboard_chain(PROFILE, MODEL), messages, index)
    return readings[result.alarm_index].t


def test_lowstate_over_dds_gives_the_offline_alarm(runs, tmp_path):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import String
    from fall_predictor.msg import FallEvent
    from fall_predictor.ros.endpoints import create_publisher, create_subscription
    from fall_predictor.ros.runner import spin_until
    from std_srvs.srv import Trigger
    from fall_predictor.contract.topics import MONITOR_RESET_SERVICE

    domain = test_domain_id(190)
    monitor = start_process('fall_monitor', [
        sys.executable, '-m', 'fall_predictor.ros.fall_monitor', '--estimator', '--ros-args',
        '-p', 'input:=unitree_hg', '-p', 'robot:=g1_12dof',
        '-p', 'start_type_description_service:=false'], ros_environment(domain), tmp_path)
    alarms: dict[str, list[float]] = {}
    try:
        with ros_context(domain) as context:
            node = Node('g1_board', context=context)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            board = create_publisher(node, unitree_hg_msg.LowState, LOWSTATE)
            descriptions, events = [], []
            create_subscription(node, String, ROBOT_DESCRIPTION, lambda m: descriptions.append(m.data))
            create_subscription(node, FallEvent, FALL_EVENT,
                                lambda m: events.append((m.header.stamp.sec * 10**9
                                                         + m.header.stamp.nanosec, m.event)))
            assert spin_until(executor, lambda: board.get_subscription_count() > 0 and descriptions,
                              60.0), monitor.log_tail()
            assert descriptions[-1] == PROFILE.urdf_xml()        # the profile's, published by the monitor
            reset = node.create_client(Trigger, MONITOR_RESET_SERVICE)
            assert reset.wait_for_service(timeout_sec=20.0), monitor.log_tail()
            for name, run in runs.items():
                future = reset.call_async(Trigger.Request())
                assert spin_until(executor, future.done, 10.0)
                events.clear()
                records = list(lowstate_records(run.sensor_readings, PROFILE.unitree_hg, 5))
                start_ns = time.time_ns() + 100_000_000
                t0 = run.sensor_readings[0].t
                for reading, (_, record) in zip(run.sensor_readings, records):
                    due = start_ns + round((reading.t - t0) * 1e9)
                    while time.time_ns() < due:
                        executor.spin_once(timeout_sec=0.0)
                    board.publish(lowstate_cdr(record))      # serialized, as DDS delivers it
                spin_until(executor, lambda: False, 1.0)
                alarms[name] = [t0 + (stamp - start_ns) / 1e9 for stamp, kind in events
                                if kind == EVENT_FALLING]
            node.destroy_node()
    finally:
        codes = stop_nodes({'fall_monitor': monitor})
    assert codes == {'fall_monitor': 0}, monitor.log_tail(40)
    fall = runs['fall']
    reference = offline_alarm_s(fall.sensor_readings)
    assert alarms['fall'], (alarms, monitor.log_tail(40))
    assert PUSH_AT_S <= alarms['fall'][0] < fall.t_fallen
    assert abs(alarms['fall'][0] - reference) <= 0.05, (alarms, reference)
    assert alarms['survived'] == [], alarms


def test_a_profile_without_a_motor_table_refuses_to_start_in_words(tmp_path):
    """input:=unitree_hg with a robot whose profile names no motors: exit code 1, one FATAL line
    saying so, no traceback."""
    import subprocess
    process = subprocess.run(
        [sys.executable, '-m', 'fall_predictor.ros.state_estimator_node', '--ros-args',
         '-p', 'input:=unitree_hg', '-p', 'robot:=asimo_like'],
        capture_output=True, text=True, timeout=60, env=ros_environment(test_domain_id(191)))
    output = process.stdout + process.stderr
    assert process.returncode == 1 and 'Traceback' not in output, output
    fatal = [line for line in output.splitlines() if '[FATAL]' in line]
    assert len(fatal) == 1 and 'asimo_like has no unitree_hg section' in fatal[0], output
