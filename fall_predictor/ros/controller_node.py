"""controller_node: C_bal (walking with the balance reflex) until the predictor says falling,
then C_fall (freeze) for good (SPEC §2).

For every ``/fall_predictor/measurement`` it runs
:class:`~fall_predictor.robot.controllers.ControllerSwitch` and publishes the joint targets on
``/fall_predictor/joint_commands`` (sensor_msgs/JointState, position field, URDF joint order),
stamped with the measurement's time so that the lock-stepped simulator can match them.

It listens to ``/fall_predictor/state``: the first state of the current run that says falling
(or latched), and is not degraded, switches to C_fall; the switch is one-way until the run
ends. ``/fall_predictor/controller_mode`` (latched) carries ``'balance'`` or ``'fall'``.
The switch takes effect from the next measurement, so its delay is the pipeline latency
(measurement -> features -> state), as on a robot.

A new run (measurement time going backwards, or a new t = 0 sample) builds a fresh C_bal and
publishes ``'balance'`` again. Malformed inputs are logged (throttled), counted and dropped.
"""
from __future__ import annotations

from typing import Optional

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String

from fall_predictor.robot import model as rm
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.robot.controllers import BalanceController, ControllerSwitch, GaitConfig, ReflexConfig
from fall_predictor.ros.common import (SAMPLE_PERIOD_S, Diagnostics, InputErrors, ParamSpec,
                                         Report, RunTracker, Sample, create_publisher,
                                         create_subscription, declare_parameters, run_node)
from fall_predictor.data.topics import CONTROLLER_MODE, JOINT_COMMANDS, MEASUREMENT, STATE
from fall_predictor.data.wire import LEVEL_OK, LEVEL_WARN

NODE_NAME = 'controller_node'

PARAMS = (
    ParamSpec('walk_duration_s', 300.0, 'length of the planned walk [s] of simulation time, '
              'from the start of a run; the robot stands afterwards', 1.0, 86400.0,
              read_only=True),
    ParamSpec('reflex_enabled', True, "C_bal's stepping reflex on large momentum (SPEC §2)",
              read_only=True),
    ParamSpec('fall_trigger_enabled', True, 'switch to C_fall on the first falling state; '
              'false: C_bal throughout (as in data generation)'),
)


class ControllerNode(Node):
    """Wraps :class:`~fall_predictor.robot.controllers.ControllerSwitch`; see the module docs."""

    def __init__(self, **kwargs: object) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMS)
        self._walk_duration_s = float(p['walk_duration_s'])
        self._reflex = ReflexConfig(enabled=bool(p['reflex_enabled']))
        self._fall_trigger_enabled = bool(p['fall_trigger_enabled'])
        self.add_post_set_parameters_callback(self._apply_parameters)

        self._command_pub = create_publisher(self, JointState, JOINT_COMMANDS)
        self._mode_pub = create_publisher(self, String, CONTROLLER_MODE)
        inputs = [create_subscription(self, Float64MultiArray, MEASUREMENT, self._on_measurement),
                  create_subscription(self, DiagnosticArray, STATE, self._on_state)]

        self._runs = RunTracker()
        self._bad_measurements = InputErrors(self)
        self._bad_states = InputErrors(self)
        #: Counters by event name (reported in /diagnostics).
        self.counts = {'commands': 0, 'modes': 0, 'duplicates': 0, 'runs': 0}
        self._switch = self._new_switch()
        self._diagnostics = Diagnostics(self, self._report, lambda: self._runs.last_t or 0.0,
                                        inputs)
        self.get_logger().info(
            f'controller ready: fall_trigger_enabled={self._fall_trigger_enabled}')

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'fall_trigger_enabled':
                self._fall_trigger_enabled = bool(parameter.value)

    def _new_switch(self) -> ControllerSwitch:
        """A fresh C_bal for a new run, and 'balance' on the mode topic."""
        self._publish_mode('balance')
        balance = BalanceController(GaitConfig(), self._reflex, SAMPLE_PERIOD_S,
                                    self._walk_duration_s)
        return ControllerSwitch(balance)

    def _publish_mode(self, mode: str) -> None:
        self._mode_pub.publish(ros_qos.controller_mode_msg(mode))
        self.counts['modes'] += 1

    def _on_measurement(self, msg: Float64MultiArray) -> None:
        try:
            m = ros_qos.measurement_from_msg(msg)
        except ValueError as error:
            self._bad_measurements.reject('measurement', error)
            return
        kind = self._runs.classify(m.t)
        if kind is Sample.REPEAT:
            self.counts['duplicates'] += 1
            return
        if kind is Sample.NEW_RUN:
            self.counts['runs'] += 1
            self._switch = self._new_switch()
        try:
            q = self._switch.update(m)
            command = ros_qos.joint_state_to_msg(m.t, rm.JOINT_NAMES, q)
        except ValueError as error:
            # A finite but implausible measurement can make the leg IK fail.
            self._bad_measurements.reject(f'measurement at t = {m.t} s (controller)', error)
            return
        self._command_pub.publish(command)
        self.counts['commands'] += 1

    def _on_state(self, msg: DiagnosticArray) -> None:
        try:
            state = ros_qos.state_from_msg(msg)
        except ValueError as error:
            self._bad_states.reject('state', error)
            return
        current_t = self._runs.last_t
        if (not self._fall_trigger_enabled or self._switch.mode == 'fall'
                or state.stale_reason is not None or not (state.falling or state.latched)
                or current_t is None or state.t > current_t):
            # state.t > current_t: a state from before the last reset, still in flight.
            return
        self._switch.trigger_fall(current_t)
        self._publish_mode('fall')
        self.get_logger().info(
            f'C_fall from t = {current_t:.3f} s (falling state at t = {state.t:.3f} s)')

    def _report(self) -> Report:
        values = {'mode': self._switch.mode, 't_switch_s': self._switch.t_switch,
                  't_s': self._runs.last_t, 'fall_trigger_enabled': self._fall_trigger_enabled,
                  'invalid_measurements': self._bad_measurements.count,
                  'invalid_states': self._bad_states.count,
                  'last_error': self._bad_measurements.last or self._bad_states.last,
                  **self.counts}
        dropped = (self._bad_measurements.new_since_last_call()
                   + self._bad_states.new_since_last_call())
        if dropped:
            return LEVEL_WARN, f'{self._switch.mode}; {dropped} invalid inputs dropped', values
        return LEVEL_OK, self._switch.mode, values


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.controller_node --ros-args ...``."""
    return run_node(ControllerNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
