"""controller_node under a learned policy, over DDS: Unitree's G1 policy fed a recorded stream of the
G1's sensor messages, published as its drivers publish them, answers each joint state with the
targets the offline policy computes on the same samples; a missing IMU holds the last command and
says why; C_fall holds the policy's targets after the trigger; the monitor's reset and a new run
(the clock set back) restart the policy. In ``simulated_robot`` the policy, on the sensors the
simulator publishes, walks the robot exactly as the offline loop does."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Optional

import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Bool
from test_nodes_support import ros_context, test_domain_id

from fall_predictor.contract import messages
from fall_predictor.contract.topics import FALL_EVENT, FALLING, IMU, JOINT_COMMANDS, SENSOR_JOINT_STATES
from fall_predictor.contract.wire import LEVEL_WARN
from fall_predictor.monitor.fall_monitor import EVENT_RESET
from fall_predictor.msg import FallEvent
from fall_predictor.profiles.profile import load_profile
from fall_predictor.robot.control import make_controller
from fall_predictor.robot.learned_policy import LearnedPolicy
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.controller_node import ControllerNode
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.runner import spin_until
from fall_predictor.ros.simulated_robot import robot_nodes
from fall_predictor.sim.drivers import driver_messages
from fall_predictor.sim.policy_runs import physics_dt_s
from fall_predictor.sim.sensors import SensorParams, SensorSuite
from fall_predictor.sim.trajectory import run_trajectory
from fall_predictor.sim.world import make_world

DOMAIN = test_domain_id(181)
ROBOT = 'g1_12dof'
PROFILE = load_profile(ROBOT)
POLICY = PROFILE.controller_profile()            # Unitree's policy: 2 ms physics, 20 ms period
N = 150                                          # 0.3 s of samples: 15 policy steps
COMMAND = (0.5, 0.0, 0.0)                        # the deploy config's initial command
BUILD = {'joints': messages.joint_state_msg, 'imu': messages.imu_msg}


@pytest.fixture(scope='module')
def readings() -> list:
    """The sensor readings of 0.3 s of the G1 walking under its policy in MuJoCo (noise on)."""
    world = make_world(PROFILE, None, physics_dt_s(POLICY))
    run = run_trajectory(None, N * world.dt_s, world=world,
                         controller=make_controller(PROFILE, None, COMMAND, dt_s=world.dt_s),
                         sensors=SensorSuite(SensorParams(), 7, world.dt_s, PROFILE),
                         stop_when_fallen=False)
    world.close()
    return run.sensor_readings[:N]


def offline(readings: Sequence, acts: Sequence[int], answered: Sequence[int],
            first_t_s: float = 0.0, commands: Optional[dict[int, tuple]] = None
            ) -> dict[int, np.ndarray]:
    """A fresh offline policy acting on ``readings`` at the indices ``acts`` (its clock from
    ``first_t_s``; walking at ``commands[i]`` from index i on), its targets held in between: the
    answer to each index of ``answered``."""
    policy = LearnedPolicy.from_yaml(POLICY.policy_path)
    assert policy.joint_names == PROFILE.joint_names      # the command's order is the policy's
    targets = np.array([policy.default_posture[n] for n in PROFILE.joint_names])
    out = {}
    commands = commands or {0: COMMAND}
    command = commands[0]
    for k in range(max(answered) + 1):
        command = commands.get(k, command)
        if k in acts:
            targets = policy.act(readings[k].t - first_t_s, readings[k], command)
        if k in answered:
            out[k] = targets.copy()
    return out


class Rig:
    """The controller node and a node that plays the robot's drivers and the monitor."""

    def __init__(self, context) -> None:
        self.node = ControllerNode(context=context, parameter_overrides=[
            Parameter('robot', value=ROBOT)])
        self.io = Node('policy_test_io', context=context)
        self.pubs = {'joints': create_publisher(self.io, JointState, SENSOR_JOINT_STATES),
                     'imu': create_publisher(self.io, Imu, IMU)}
        self.falling = create_publisher(self.io, Bool, FALLING)
        self.events = create_publisher(self.io, FallEvent, FALL_EVENT)
        #: The commands received: (stamp [ns], targets in the profile's joint order).
        self.commands: list[tuple[int, np.ndarray]] = []
        create_subscription(self.io, JointState, JOINT_COMMANDS, self._on_command, lossless=True)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.io)
        assert spin_until(self.executor, lambda: all(p.get_subscription_count() for p in (
            *self.pubs.values(), self.falling, self.events)) and self.node.output.publisher
            .get_subscription_count(), 10.0)

    def _on_command(self, msg: JointState) -> None:
        reading = messages.joint_state_reading(msg)
        assert reading.names == PROFILE.joint_names
        self.commands.append((reading.stamp_ns, reading.position.copy()))

    def play(self, readings: Sequence, skip_imu: range = range(0)) -> None:
        """Publish ``readings`` as the drivers do (each message taken before the next), without
        the IMU readings of the indices ``skip_imu``."""
        sync = self.node._input.sync
        for k, s in enumerate(readings):
            for stream, reading in driver_messages([s]):
                if stream == 'imu' and k in skip_imu:
                    continue
                key = 'joint_messages' if stream == 'joints' else 'imu_readings'
                taken = sync.counts[key]
                self.pubs[stream].publish(BUILD[stream](ros_qos.TYPES, reading))
                assert spin_until(self.executor, lambda: sync.counts[key] > taken, 5.0)

    def answers(self, count: int) -> dict[int, np.ndarray]:
        """The first ``count`` answers by sample index (stamps are k x 2 ms)."""
        assert spin_until(self.executor, lambda: len(self.commands) >= count, 10.0)
        return {round(stamp / 2_000_000): q for stamp, q in self.commands[:count]}

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.io.destroy_node()


@pytest.fixture
def rig():
    with ros_context(DOMAIN) as context:
        made = Rig(context)
        try:
            yield made
        finally:
            made.close()


def _assert_answers(got: dict[int, np.ndarray], expected: dict[int, np.ndarray]) -> None:
    assert sorted(got) == sorted(expected)
    for k, q in expected.items():
        np.testing.assert_allclose(got[k], q, rtol=0.0, atol=1e-9, err_msg=f'sample {k}')


def test_each_joint_state_is_answered_with_the_offline_policy_targets_at_its_stamp(rig, readings):
    rig.play(readings)
    got = rig.answers(N)
    rig.executor.spin_once(timeout_sec=0.2)
    # Every sample answered once, in order, stamped with its joint states' stamp.
    assert [stamp for stamp, _ in rig.commands] == [round(s.t * 1e9) for s in readings]
    _assert_answers(got, offline(readings, range(0, N, 10), range(N)))
    assert rig.node.counts['policy_steps'] == 15 and rig.node.counts['held'] == 0


def test_the_velocity_command_is_settable_while_running_within_the_profile_range(rig, readings):
    rig.play(readings[:50])
    rig.answers(50)
    turn = (0.3, -0.1, 0.4)
    results = rig.node.set_parameters([
        Parameter(name, value=value) for name, value in zip(
            ('command_vx_m_s', 'command_vy_m_s', 'command_yaw_rate_rad_s'), turn)])
    assert all(r.successful for r in results)
    refused = rig.node.set_parameters([Parameter('command_vx_m_s', value=0.9)])[0]
    assert not refused.successful and '0.6' in refused.reason     # the profile's vx range
    rig.play(readings[50:])
    _assert_answers(rig.answers(N), offline(readings, range(0, N, 10), range(N),
                                            commands={0: COMMAND, 50: turn}))
    assert rig.node._report()[2]['command'] == list(turn)


def test_a_missing_imu_holds_the_last_command_and_says_why(rig, readings):
    # No IMU from sample 55 to 74 (110 to 148 ms): from sample 57 (114 ms) none lies within 5 ms,
    # so the policy, due at 120 ms, finds no usable sample until the IMU is back at 150 ms and
    # holds the command of 100 ms meanwhile (15 samples); it acts at 150 ms (late), then at
    # 160 ms on its grid again. Each sample is answered, the faulty ones when the next joint
    # state shows that their IMU reading is not coming.
    rig.play(readings[:100], skip_imu=range(55, 75))
    got = rig.answers(100)
    acts = [0, 10, 20, 30, 40, 50, 75, 80, 90]
    _assert_answers(got, offline(readings, acts, range(100)))
    assert rig.node.counts['held'] == 15 and rig.node.counts['policy_steps'] == len(acts)
    level, message, values = rig.node._report()
    assert level == LEVEL_WARN
    assert message.startswith('balance; the last command held on 15 samples the policy could not '
                              'use: no /imu/data within 5 ms of /joint_states')
    assert values['held'] == 15 and values['sensor_faults'] == 18


def test_c_fall_holds_the_policy_targets_after_the_trigger(rig, readings):
    rig.play(readings[:100])
    rig.answers(100)
    rig.falling.publish(Bool(data=True))
    assert spin_until(rig.executor, lambda: rig.node._switch.mode == 'fall', 5.0)
    rig.play(readings[100:])
    got = rig.answers(N)
    held = offline(readings, range(0, 100, 10), [99])[99]      # the policy's step at 180 ms
    assert all(np.array_equal(got[k], held) for k in range(100, N))
    hold = rig.node._switch.fall.held                          # with the policy's own gains
    policy = LearnedPolicy.from_yaml(POLICY.policy_path)
    assert np.array_equal(hold.kp, policy.kp) and np.array_equal(hold.kd, policy.kd)
    assert rig.node.counts['policy_steps'] == 10 and rig.node.counts['triggers'] == 1


def test_the_monitor_reset_restarts_the_policy(rig, readings):
    rig.play(readings[:60])
    rig.answers(60)
    event = FallEvent()
    event.event = EVENT_RESET
    rig.events.publish(event)
    assert spin_until(rig.executor, lambda: rig.node.counts['resets'] == 1, 5.0)
    rig.commands.clear()
    rig.play(readings[:60])          # a fresh world: the same samples again, from t = 0
    # A fresh policy (network state, last action and gait clock zeroed) answers as the first.
    _assert_answers(rig.answers(60), offline(readings, range(0, 60, 10), range(60)))


def test_a_new_run_restarts_the_policy(rig, readings):
    rig.play(readings[:60])
    rig.answers(60)
    rig.commands.clear()
    rig.play(readings[:60])          # the clock set back without a reset
    # The time rule confirms the step at its 5th sample (8 ms): a fresh policy starts there,
    # its clock from that sample; the 4 samples before are dropped, unanswered.
    got = rig.answers(56)
    _assert_answers(got, offline(readings, range(4, 60, 10), range(4, 60), first_t_s=0.008))
    assert rig.node.counts['new_runs'] == 1 and rig.node._input.timeline.jumps == 1


def test_simulated_robot_walks_the_policy_on_its_sensors_as_the_offline_loop_does() -> None:
    """Simulator and controller in one process: each sample's sensors go out over DDS before its
    command is awaited, the policy answers every one (no missed or late command) and the robot
    walks exactly as in the offline loop with the same sensor noise."""
    duration_s = 0.4
    world = make_world(PROFILE, None, physics_dt_s(POLICY))
    offline_run = run_trajectory(None, duration_s + 0.05, world=world,
                                 controller=make_controller(PROFILE, None, dt_s=world.dt_s),
                                 sensors=SensorSuite(SensorParams(), 100003 * 0 + 1, world.dt_s,
                                                     PROFILE),
                                 stop_when_fallen=False)
    world.close()
    by_step = {round(m.t / world.dt_s): m for m in offline_run.measurements}
    with ros_context(DOMAIN) as context:
        simulator, controller = [make() for make in robot_nodes(context=context, parameter_overrides=[
            Parameter('robot', value=ROBOT), Parameter('publish_sensors', value=True),
            Parameter('real_time_factor', value=0.0)])]
        executor = SingleThreadedExecutor(context=context)
        for node in (simulator, controller):
            executor.add_node(node)
        try:
            steps = round(duration_s / simulator.dt_s)
            assert spin_until(executor, lambda: simulator.counts['steps'] >= steps, 60.0)
            m, counts = simulator._m, dict(simulator.counts)
        finally:
            executor.shutdown()
            for node in (controller, simulator):
                node.destroy_node()
    assert simulator.dt_s == 0.002
    assert counts['missed_commands'] == 0 and counts['late_commands'] == 0
    assert np.array_equal(m.com, by_step[round(m.t / 0.002)].com)
