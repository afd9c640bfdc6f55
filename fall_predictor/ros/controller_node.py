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
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String

from fall_predictor.contract.topics import CONTROLLER_MODE, FALL_EVENT, FALLING, JOINT_COMMANDS
from fall_predictor.contract.wire import LEVEL_OK, LEVEL_WARN
from fall_predictor.monitor.fall_monitor import EVENT_RESET
from fall_predictor.monitor.plausibility import bound_text
from fall_predictor.msg import FallEvent
from fall_predictor.robot.control import ControllerSwitch, JointCommand, Observation
from fall_predictor.robot.balance_controller import controller_configs
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.controller_inputs import ControlStep, SensorInput, StateInput
from fall_predictor.ros.controller_params import PARAMS, command_params, policy_robot
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import (HANDLED_ERRORS, LOG_THROTTLE_S, Diagnostics, InputErrors,
                                       Report, guarded)
from fall_predictor.ros.in_process import Output
from fall_predictor.ros.parameters import declare_parameters
from fall_predictor.ros.robots import profile_for
from fall_predictor.ros.runner import run_node
from fall_predictor.ros.simulated_world import controller_choice, physics_step_s, walking_controller

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
        self._profile = profile = profile_for(str(p['robot']))
        self._choice = choice = controller_choice(profile, str(p['controller']), str(p['simulator']))
        # C_bal's settings (a learned policy has none of its own here): its step, walk and reflex.
        self._settings: dict = {} if choice.is_policy else {
            'dt_s': physics_step_s(profile, choice),
            'walk_duration_s': float(p['walk_duration_s']),
            'reflex': replace(controller_configs(profile)[1], enabled=bool(p['reflex_enabled']))}
        walking = walking_controller(profile, choice, **self._settings)
        command = declare_parameters(self, command_params(choice, walking))
        self._velocity = tuple(float(command[name]) for name in COMMAND_PARAMS)
        if choice.is_policy:
            self._settings['command'] = self._velocity
        self._fall_trigger_enabled = bool(p['fall_trigger_enabled'])
        self.add_post_set_parameters_callback(self._apply_parameters)

        #: The joint commands, published and handed to in-process consumers (the simulator).
        self.output = Output(create_publisher(self, JointState, JOINT_COMMANDS))
        self._mode_pub = create_publisher(self, String, CONTROLLER_MODE)
        self._bad_inputs = InputErrors(self)
        #: Counters by event name (reported in /diagnostics).
        self.counts = {'commands': 0, 'held': 0, 'modes': 0, 'resets': 0, 'triggers': 0,
                       'policy_steps': 0, 'new_runs': 0}
        # What the walking controller observes: C_bal the measurements, a policy the sensors
        # (over DDS even in simulated_robot: the simulator publishes each sample's sensors before
        # it awaits the answer).
        if choice.is_policy:
            self._input = SensorInput(self, self._answer, self._bad_inputs,
                                      policy_robot(profile, choice, walking), walking.period_s)
        else:
            self._input = StateInput(self, self._answer, self._bad_inputs, bool(p['ground_truth']),
                                     upstream)
        inputs = list(self._input.subscriptions)
        inputs.append(create_subscription(self, Bool, FALLING, self._on_falling))
        create_subscription(self, FallEvent, FALL_EVENT, self._on_fall_event)

        self._switch = self._new_switch(walking)
        #: The last command (answers a sample that cannot be used): the controller's starting
        #: posture until the first one.
        self._command = self._robot_targets(walking.hold_command(),
                                            np.zeros(len(profile.joint_names)))
        #: Why the controller last held its command (a sensor fault), and when that was logged.
        self._held_reason = ''
        self._held_logged = -float('inf')
        self._held_at_report = 0
        self._diagnostics = Diagnostics(self, self._report, lambda: self._input.timeline.last_ns or 0,
                                        inputs, self._bad_inputs)
        self.get_logger().info(
            f'controller ready: {choice.name} on robot {profile.name}'
            + (f' at {self._velocity} (vx [m/s], vy [m/s], yaw rate [rad/s])' if choice.is_policy else '')
            + f', fall_trigger_enabled={self._fall_trigger_enabled}')

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'fall_trigger_enabled':
                self._fall_trigger_enabled = bool(parameter.value)
            elif parameter.name in COMMAND_PARAMS:
                velocity = list(self._velocity)
                velocity[COMMAND_PARAMS.index(parameter.name)] = float(parameter.value)
                self._velocity = tuple(velocity)
                if 'command' in self._settings:       # a policy walks at the command
                    self._settings['command'] = self._velocity
                    self._switch.walking.velocity_command = self._velocity

    def _new_switch(self, walking=None) -> ControllerSwitch:
        """A fresh walking controller for a new run (a policy's state zeroed), and 'balance' on
        the mode topic."""
        self._publish_mode('balance')
        self._input.restart()
        if walking is None:
            walking = walking_controller(self._profile, self._choice, **self._settings)
        return ControllerSwitch(walking)

    def _publish_mode(self, mode: str) -> None:
        self._mode_pub.publish(ros_qos.controller_mode_msg(mode))
        self.counts['modes'] += 1

    def _robot_targets(self, command: JointCommand, held: np.ndarray) -> np.ndarray:
        """``command``'s targets on every joint of the robot, in the profile's order (a joint it
        does not command keeps ``held``)."""
        names = self._profile.joint_names
        if command.joint_names == names:        # C_bal's, every sample: nothing to fit
            return command.targets_rad
        return command.fit_onto(names, JointCommand(names, held)).targets_rad

    @guarded('fall event')
    def _on_fall_event(self, msg: FallEvent) -> None:
        if msg.event != EVENT_RESET:
            return
        self._input.reset()
        self._switch = self._new_switch()
        self.counts['resets'] += 1
        self.get_logger().info(f'monitor reset: fresh {self._choice.name}')

    # -- the inputs' steps (controller_inputs.py) -------------------------------------------------
    def _answer(self, steps: list[ControlStep]) -> None:
        for step in steps:
            if step.new_run:
                self.counts['new_runs'] += 1
                if self._switch.mode == 'balance':
                    self._switch = self._new_switch()   # C_fall stays until the reset (one-way)
            try:
                q = self._targets(step)
            except HANDLED_ERRORS as error:
                # A finite but implausible input can make the leg IK or the policy fail.
                self._bad_inputs.reject(f'sample at {step.stamp_ns} ns (controller)', error)
                continue
            self._command = q
            self.output.publish(ros_qos.joint_state_to_msg(step.stamp_ns, self._profile.joint_names, q))
            self.counts['commands'] += 1

    def _targets(self, step: ControlStep) -> np.ndarray:
        """The targets answering ``step``: C_fall's; the walking controller's when it is due and
        the input usable; else the last command (held, and said why when it was due)."""
        if self._switch.mode == 'fall':
            return self._robot_targets(self._switch.command(Observation(0.0)), self._command)
        if not step.due:
            return self._command
        if step.observation is None:
            self._hold(step)
            return self._command
        command = self._switch.command(step.observation)
        self._input.acted(step.stamp_ns)
        if self._choice.is_policy:
            self.counts['policy_steps'] += 1
        return self._robot_targets(command, self._command)

    def _hold(self, step: ControlStep) -> None:
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
        current_t = self._input.timeline.last_ns and self._input.timeline.last_ns / 1e9
        if not msg.data or not self._fall_trigger_enabled or self._switch.mode == 'fall':
            return
        self.counts['triggers'] += 1
        t_switch = current_t if current_t is not None else 0.0
        self._switch.trigger_fall(t_switch)
        self._publish_mode('fall')
        self.get_logger().info(f'C_fall from t = {t_switch:.3f} s')

    def _report(self) -> Report:
        values = {'controller': self._choice.name, 'mode': self._switch.mode,
                  't_switch_s': self._switch.t_switch, 'stamp_ns': self._input.timeline.last_ns,
                  'fall_trigger_enabled': self._fall_trigger_enabled,
                  'invalid_inputs': self._bad_inputs.count, 'last_error': self._bad_inputs.last,
                  **self._input.timeline.counters(), **self.counts, **self._input.report()}
        if self._choice.is_policy:
            values.update(command=list(self._velocity), held_reason=self._held_reason)
        held = self.counts['held'] - self._held_at_report
        self._held_at_report = self.counts['held']
        dropped = self._bad_inputs.new_since_last_call()
        if held and self._choice.is_policy:
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
