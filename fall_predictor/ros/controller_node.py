"""controller_node: the robot's walking controller (C_bal, or a team's learned walking policy) until
the predictor says falling, then C_fall (hold) for good (method §2).

``controller`` (default '': the robot profile's default controller) chooses the walking
controller; either way it runs in :class:`~fall_predictor.robot.control.ControllerSwitch` and the
node publishes the joint targets on ``fall_predictor/joint_commands`` (sensor_msgs/JointState,
position field, every joint of the robot in the profile's order), stamped with the time of the
sample they answer so that the lock-stepped simulator can match them.

**C_bal** answers every ``fall_predictor/measurement`` (with ``ground_truth``:
``fall_predictor/ground_truth``, the simulator's exact state beside its sensors, as C_bal reads it
in data generation), read reliably (it closes the simulator's lock-step loop). A measurement that
carries a fault (the estimator's sensors degraded) is answered with the last command.

**A learned policy** observes what the robot measures, never the simulator's state: the node
subscribes to the robot's ``joint_states`` and ``imu/data`` (reliably) and merges them as the state
estimator does (:mod:`fall_predictor.ros.policy_inputs`: one sensor sample per joint state stamp,
waiting for that stamp's IMU reading). It answers every joint state sample with the current
targets, stamped with that sample's stamp, and runs the policy every ``period_s`` of the samples'
time (its deploy config's), walking at the velocity command ``command_vx_m_s``,
``command_vy_m_s``, ``command_yaw_rate_rad_s`` (settable while running, within the robot
profile's command ranges; default: the deploy config's initial command). A sample whose sensors
are missing, stale or implausible is never taken as zero: the node holds the last command, counts
it and says why (``/diagnostics``, a throttled log line).

It listens to the trigger ``fall_predictor/falling`` (std_msgs/Bool, latched): ``true`` switches
to C_fall, which holds the walking controller's last targets (a policy's with its PD gains, which
the simulated drives keep). The switch is one-way until the monitor's reset (the RESET event on
``fall_predictor/fall_event``), which builds a fresh walking controller (a policy's network state
zeroed); nothing else undoes it (an old stamp, a ``false`` trigger, a new run).
``fall_predictor/controller_mode`` (latched) carries ``'balance'`` (the walking controller) or
``'fall'``. The switch takes effect from the next sample, so its delay is the pipeline latency
(measurement -> features -> trigger), as on a robot.

Sample order as in the monitor nodes (the time rule of :mod:`fall_predictor.monitor.timeline`):
a new world of the simulator (its clock restarting) is a new run; a restarted run with the walking
controller gets a fresh one, one in C_fall stays in C_fall. Malformed inputs and numeric failures
are logged (throttled), counted and dropped. The controller's clock is its inputs' stamps
(simulation time).
"""
from __future__ import annotations

import time
from dataclasses import replace
from typing import Optional

import numpy as np
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Bool, String

from fall_predictor.contract import messages
from fall_predictor.contract.topics import (CONTROLLER_MODE, FALL_EVENT, FALLING, GROUND_TRUTH, IMU,
                                            JOINT_COMMANDS, MEASUREMENT, SENSOR_JOINT_STATES)
from fall_predictor.contract.wire import LEVEL_OK, LEVEL_WARN
from fall_predictor.monitor.fall_monitor import EVENT_RESET
from fall_predictor.monitor.plausibility import bound_names, bound_text
from fall_predictor.monitor.timeline import Stamp, StampTimeline
from fall_predictor.msg import FallEvent, Measurement
from fall_predictor.robot.control import ControllerSwitch, JointCommand, Observation, PolicyControl
from fall_predictor.robot.controllers import BalanceController, controller_configs
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.controller_params import PARAMS, command_params, load_policy, policy_robot
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import (HANDLED_ERRORS, LOG_THROTTLE_S, Diagnostics, InputErrors,
                                       Report, guarded)
from fall_predictor.ros.in_process import Output, connect_input
from fall_predictor.ros.parameters import declare_parameters
from fall_predictor.ros.policy_inputs import PolicyInputs, PolicySchedule, PolicyStep
from fall_predictor.ros.robots import profile_for
from fall_predictor.ros.runner import run_node
from fall_predictor.ros.simulated_world import controller_choice, physics_step_s

NODE_NAME = 'controller_node'
#: The velocity command parameters, in the order of a command (vx, vy, yaw rate).
COMMAND_PARAMS = ('command_vx_m_s', 'command_vy_m_s', 'command_yaw_rate_rad_s')


class ControllerNode(Node):
    """Wraps :class:`~fall_predictor.robot.control.ControllerSwitch`; see the module docs."""

    def __init__(self, upstream: Optional[Output] = None, **kwargs: object) -> None:
        """``upstream``: take the measurements (C_bal's input) from this output of a node of the
        same process (``simulated_robot``) instead of subscribing; ``kwargs`` go to ``Node``."""
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMS)
        self._walk_duration_s = float(p['walk_duration_s'])
        self._profile = profile = profile_for(str(p['robot']))
        self._choice = choice = controller_choice(profile, str(p['controller']), str(p['simulator']))
        self._policy = load_policy(choice)
        command = declare_parameters(self, command_params(choice, self._policy))
        self._velocity = tuple(float(command[name]) for name in COMMAND_PARAMS)
        gait, reflex, stabilizer = controller_configs(profile)
        self._gait, self._stabilizer = gait, stabilizer
        self._reflex = replace(reflex, enabled=bool(p['reflex_enabled']))
        self._dt_s = physics_step_s(profile, choice) if self._policy is None else 0.0
        self._fall_trigger_enabled = bool(p['fall_trigger_enabled'])
        self.add_post_set_parameters_callback(self._apply_parameters)

        #: The joint commands, published and handed to in-process consumers (the simulator).
        self.output = Output(create_publisher(self, JointState, JOINT_COMMANDS))
        self._mode_pub = create_publisher(self, String, CONTROLLER_MODE)
        self._bad_inputs = InputErrors(self)
        #: Counters by event name (reported in /diagnostics).
        self.counts = {'commands': 0, 'held': 0, 'modes': 0, 'resets': 0, 'triggers': 0,
                       'policy_steps': 0, 'new_runs': 0}
        if self._policy is None:
            source = GROUND_TRUTH if p['ground_truth'] else MEASUREMENT
            inputs = connect_input(self, Measurement, source, self._on_measurement, upstream,
                                   lossless=True, take=self._take_measurement)
            self._timeline = StampTimeline()
        else:
            # A policy reads the robot's sensors (over DDS even in simulated_robot: the
            # simulator publishes each sample's sensors before it awaits the answer).
            topics = {'joints': self.resolve_topic_name(SENSOR_JOINT_STATES.ros_name),
                      'imu': self.resolve_topic_name(IMU.ros_name)}
            robot = policy_robot(profile, choice, self._policy)
            self._inputs = PolicyInputs(robot.joint_names, robot.joint_bounds, topics=topics)
            self._timeline = self._inputs.timeline
            self._schedule = PolicySchedule(self._policy.period_s)
            inputs = [create_subscription(self, JointState, SENSOR_JOINT_STATES,
                                          self._on_joint_state, lossless=True),
                      create_subscription(self, Imu, IMU, self._on_imu, lossless=True)]
        inputs.append(create_subscription(self, Bool, FALLING, self._on_falling))
        create_subscription(self, FallEvent, FALL_EVENT, self._on_fall_event)

        self._switch = self._new_switch()
        #: The last command (answers a sample that carries a fault): the starting posture until
        #: the first one.
        posture = self._switch.walking.initial_posture().joint_angles
        self._command = np.array([posture.get(n, 0.0) for n in profile.joint_names])
        self._joint_index = {name: k for k, name in enumerate(profile.joint_names)}
        #: Why the policy last held its command (a sensor fault), and when that was logged.
        self._held_reason = ''
        self._held_logged = -float('inf')
        self._held_at_report = 0
        self._diagnostics = Diagnostics(self, self._report, lambda: self._timeline.last_ns or 0,
                                        inputs, self._bad_inputs)
        self.get_logger().info(
            f'controller ready: {choice.name} on robot {profile.name}'
            + (f' at {self._velocity} (vx [m/s], vy [m/s], yaw rate [rad/s])' if self._policy else '')
            + f', fall_trigger_enabled={self._fall_trigger_enabled}')

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'fall_trigger_enabled':
                self._fall_trigger_enabled = bool(parameter.value)
            elif parameter.name in COMMAND_PARAMS:
                velocity = list(self._velocity)
                velocity[COMMAND_PARAMS.index(parameter.name)] = float(parameter.value)
                self._velocity = tuple(velocity)
                if isinstance(self._switch.walking, PolicyControl):
                    self._switch.walking.velocity_command = self._velocity

    def _new_switch(self) -> ControllerSwitch:
        """A fresh walking controller for a new run (a policy's state zeroed), and 'balance' on
        the mode topic."""
        self._publish_mode('balance')
        if self._policy is not None:
            self._schedule.restart()
            return ControllerSwitch(PolicyControl(self._policy, self._velocity, self._choice.name))
        balance = BalanceController(self._gait, self._reflex, self._dt_s, self._walk_duration_s,
                                    stabilizer=self._stabilizer, profile=self._profile)
        return ControllerSwitch(balance)

    def _publish_mode(self, mode: str) -> None:
        self._mode_pub.publish(ros_qos.controller_mode_msg(mode))
        self.counts['modes'] += 1

    def _publish_command(self, stamp_ns: int, q: np.ndarray) -> None:
        self._command = q
        self.output.publish(ros_qos.joint_state_to_msg(stamp_ns, self._profile.joint_names, q))
        self.counts['commands'] += 1

    @guarded('fall event')
    def _on_fall_event(self, msg: FallEvent) -> None:
        if msg.event != EVENT_RESET:
            return
        if self._policy is None:
            self._timeline.reset()
        else:
            self._inputs.reset()
        self._switch = self._new_switch()
        self.counts['resets'] += 1
        self.get_logger().info(f'monitor reset: fresh {self._choice.name}')

    # -- C_bal: the exact state (or the estimated measurement) ----------------------------------
    @guarded('measurement')
    def _on_measurement(self, msg: Measurement) -> None:
        self._control(messages.measurement_from_msg(msg))

    @guarded('measurement')
    def _take_measurement(self, decoded: messages.StampedMeasurement) -> None:
        """A measurement handed over in process (``simulated_robot``): the checks a decoded
        message passes, then the same path."""
        if decoded.measurement is not None:
            messages.check_measurement(decoded.measurement)
        self._control(decoded)

    def _control(self, decoded: messages.StampedMeasurement) -> None:
        kind = self._timeline.classify(decoded.stamp_ns)
        if kind is Stamp.NEW_RUN and self._switch.mode == 'balance':
            self._switch = self._new_switch()   # C_fall stays until the reset (one-way)
        elif not kind.accepted:
            return                              # duplicate, out of order, stray: counted
        if decoded.measurement is None:         # the estimator's sensors failed: hold
            q = self._command
            self.counts['held'] += 1
        else:
            try:
                q = self._switch.update(decoded.measurement)
            except HANDLED_ERRORS as error:
                # A finite but implausible measurement can make the leg IK fail.
                self._bad_inputs.reject(f'measurement at {decoded.stamp_ns} ns (controller)', error)
                return
        self._publish_command(decoded.stamp_ns, q)

    # -- a learned policy: the robot's sensors ------------------------------------------------
    @guarded('joint state')
    def _on_joint_state(self, msg: JointState) -> None:
        steps, unknown = self._inputs.joint_state(messages.joint_state_reading(msg))
        if unknown:
            self.get_logger().info(f'ignoring joints robot {self._profile.name} does not have: '
                                   f'{bound_names(unknown)}')
        self._answer(steps)

    @guarded('IMU reading')
    def _on_imu(self, msg: Imu) -> None:
        self._answer(self._inputs.imu(messages.imu_reading(msg)))

    def _answer(self, steps: list[PolicyStep]) -> None:
        for step in steps:
            if step.new_run:
                self.counts['new_runs'] += 1
                if self._switch.mode == 'balance':
                    self._switch = self._new_switch()   # C_fall stays until the reset
            try:
                q = self._policy_targets(step)
            except HANDLED_ERRORS as error:
                self._bad_inputs.reject(f'sensor sample at {step.stamp_ns} ns (policy)', error)
                continue
            self._publish_command(step.stamp_ns, q)

    def _policy_targets(self, step: PolicyStep) -> np.ndarray:
        """The targets answering ``step``: C_fall's, the policy's when it is due and the sample
        usable, else the last command (held, and said why when the policy was due)."""
        if self._switch.mode == 'fall':
            return self._targets(self._switch.command(Observation(step.t_s)))
        if not self._schedule.due(step.stamp_ns):
            return self._command
        if step.sample is None:
            self._hold(step)
            return self._command
        command = self._switch.command(Observation(step.t_s, None, step.sample))
        self._schedule.acted(step.stamp_ns)
        self.counts['policy_steps'] += 1
        return self._targets(command)

    def _targets(self, command: JointCommand) -> np.ndarray:
        """``command``'s targets on every joint of the robot (others: the last command's)."""
        q = self._command.copy()
        for name, target in zip(command.joint_names, command.targets_rad):
            q[self._joint_index[name]] = target
        return q

    def _hold(self, step: PolicyStep) -> None:
        self.counts['held'] += 1
        self._held_reason = bound_text(f'{step.fault} at {step.stamp_ns / 1e9:.3f} s')
        now = time.monotonic()
        if now - self._held_logged >= LOG_THROTTLE_S:
            self._held_logged = now
            self.get_logger().warning(f'holding the last command: {self._held_reason} '
                                      f'({self.counts["held"]} held so far)')

    # -- the trigger and health -----------------------------------------------------------------
    @guarded('trigger')
    def _on_falling(self, msg: Bool) -> None:
        current_t = self._timeline.last_ns and self._timeline.last_ns / 1e9
        if not msg.data or not self._fall_trigger_enabled or self._switch.mode == 'fall':
            return
        self.counts['triggers'] += 1
        t_switch = current_t if current_t is not None else 0.0
        self._switch.trigger_fall(t_switch)
        self._publish_mode('fall')
        self.get_logger().info(f'C_fall from t = {t_switch:.3f} s')

    def _report(self) -> Report:
        values = {'controller': self._choice.name, 'mode': self._switch.mode,
                  't_switch_s': self._switch.t_switch, 'stamp_ns': self._timeline.last_ns,
                  'fall_trigger_enabled': self._fall_trigger_enabled,
                  'invalid_inputs': self._bad_inputs.count, 'last_error': self._bad_inputs.last,
                  **self._timeline.counters(), **self.counts}
        if self._policy is not None:
            values.update(command=list(self._velocity), held_reason=self._held_reason,
                          sensor_faults=self._inputs.counts['faults'])
        held = self.counts['held'] - self._held_at_report
        self._held_at_report = self.counts['held']
        dropped = self._bad_inputs.new_since_last_call()
        if held and self._policy is not None:
            return (LEVEL_WARN, f'{self._switch.mode}; the last command held on {held} samples the '
                                f'policy could not use: {self._held_reason}', values)
        if dropped:
            return LEVEL_WARN, f'{self._switch.mode}; {dropped} invalid inputs dropped', values
        return LEVEL_OK, self._switch.mode, values


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.controller_node --ros-args ...``."""
    return run_node(ControllerNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
