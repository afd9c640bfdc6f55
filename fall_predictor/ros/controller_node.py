"""controller_node: C_bal (walking with the balance reflex) until the predictor says falling,
then C_fall (freeze) for good (method §2).

For every ``fall_predictor/measurement`` (with ``ground_truth``: ``fall_predictor/ground_truth``,
the simulator's exact state beside its sensors, as C_bal reads it in data generation) it runs
:class:`~fall_predictor.robot.controllers.ControllerSwitch` and publishes the joint targets on
``fall_predictor/joint_commands`` (sensor_msgs/JointState, position field, URDF joint order),
stamped with the measurement's time so that the lock-stepped simulator can match them. It
reads the measurements reliably (it closes the simulator's lock-step loop).

It listens to the trigger ``fall_predictor/falling`` (std_msgs/Bool, latched): ``true``
switches to C_fall. The switch is one-way until the monitor's reset (the RESET event on
``fall_predictor/fall_event``), which builds a fresh C_bal; nothing else undoes it (an old
stamp, a ``false`` trigger, a new run).
``fall_predictor/controller_mode`` (latched) carries ``'balance'`` or ``'fall'``. The switch
takes effect from the next measurement, so its delay is the pipeline latency (measurement ->
features -> trigger), as on a robot.

Sample order as in the monitor nodes (the time rule of :mod:`fall_predictor.monitor.timeline`):
a new world of the simulator (its clock restarting) is a new run; a restarted run in C_bal gets a
fresh C_bal, one in C_fall stays in C_fall. A measurement that carries a fault (the estimator's
sensors degraded) is answered with the last command. Malformed inputs and numeric failures are
logged (throttled), counted and dropped. The controller's clock is the measurements' stamps
(simulation time).
"""
from __future__ import annotations

from dataclasses import replace


from typing import Optional

from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String

from fall_predictor.ros import conversions as ros_qos
from fall_predictor.robot.control import ControllerSwitch
from fall_predictor.robot.controllers import BalanceController, controller_configs
from fall_predictor.ros.robots import ROBOT_PARAM, profile_for
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import HANDLED_ERRORS, Diagnostics, InputErrors, Report, guarded
from fall_predictor.ros.parameters import ParamSpec, declare_parameters
from fall_predictor.ros.runner import run_node
from fall_predictor.ros.in_process import Output, connect_input
from fall_predictor.contract import messages
from fall_predictor.contract.topics import (CONTROLLER_MODE, FALL_EVENT, FALLING, GROUND_TRUTH,
                                            JOINT_COMMANDS, MEASUREMENT)
from fall_predictor.contract.wire import LEVEL_OK, LEVEL_WARN
from fall_predictor.monitor.fall_monitor import EVENT_RESET
from fall_predictor.monitor.timeline import Stamp, StampTimeline
from fall_predictor.msg import FallEvent, Measurement
from fall_predictor.sim.simulator import DT_S

NODE_NAME = 'controller_node'

PARAMS = (
    ROBOT_PARAM,
    ParamSpec('walk_duration_s', 300.0, 'length of the planned walk [s] of simulation time, '
              'from the start of a run; the robot stands afterwards', 1.0, 86400.0,
              read_only=True),
    ParamSpec('reflex_enabled', True, "C_bal's stepping reflex on large momentum (method §2)",
              read_only=True),
    ParamSpec('fall_trigger_enabled', True, 'switch to C_fall when the trigger says falling; '
              'false: C_bal throughout (as in data generation)'),
    ParamSpec('ground_truth', False, 'read the simulator\'s exact state (fall_predictor/ground_truth, '
              'published with its sensors) instead of fall_predictor/measurement: the simulated '
              'robot\'s own controller then does not depend on the monitor\'s estimator',
              read_only=True),
)


class ControllerNode(Node):
    """Wraps :class:`~fall_predictor.robot.controllers.ControllerSwitch`; see the module docs."""

    def __init__(self, upstream: Optional[Output] = None, **kwargs: object) -> None:
        """``upstream``: take the measurements from this output of a node of the same process
        (``simulated_robot``) instead of subscribing; ``kwargs`` go to ``Node``."""
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMS)
        self._walk_duration_s = float(p['walk_duration_s'])
        self._profile = profile_for(str(p['robot']))
        gait, reflex, stabilizer = controller_configs(self._profile)
        self._gait, self._stabilizer = gait, stabilizer
        self._reflex = replace(reflex, enabled=bool(p['reflex_enabled']))
        self._fall_trigger_enabled = bool(p['fall_trigger_enabled'])
        self.add_post_set_parameters_callback(self._apply_parameters)

        #: The joint commands, published and handed to in-process consumers (the simulator).
        self.output = Output(create_publisher(self, JointState, JOINT_COMMANDS))
        self._mode_pub = create_publisher(self, String, CONTROLLER_MODE)
        source = GROUND_TRUTH if p['ground_truth'] else MEASUREMENT
        inputs = [*connect_input(self, Measurement, source, self._on_measurement,
                                 upstream, lossless=True, take=self._take_measurement),
                  create_subscription(self, Bool, FALLING, self._on_falling)]
        create_subscription(self, FallEvent, FALL_EVENT, self._on_fall_event)

        self._timeline = StampTimeline()
        self._bad_inputs = InputErrors(self)
        #: Counters by event name (reported in /diagnostics).
        self.counts = {'commands': 0, 'held': 0, 'modes': 0, 'resets': 0, 'triggers': 0}
        self._switch = self._new_switch()
        #: The last command (answers a measurement that carries a fault): the initial posture
        #: until the first one.
        self._command = self._switch.balance.initial_posture()[0]
        self._diagnostics = Diagnostics(self, self._report, lambda: self._timeline.last_ns or 0,
                                        inputs, self._bad_inputs)
        self.get_logger().info(
            f'controller ready: fall_trigger_enabled={self._fall_trigger_enabled}')

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'fall_trigger_enabled':
                self._fall_trigger_enabled = bool(parameter.value)

    def _new_switch(self) -> ControllerSwitch:
        """A fresh C_bal for a new run, and 'balance' on the mode topic."""
        self._publish_mode('balance')
        balance = BalanceController(self._gait, self._reflex, DT_S, self._walk_duration_s,
                                    stabilizer=self._stabilizer, profile=self._profile)
        return ControllerSwitch(balance)

    def _publish_mode(self, mode: str) -> None:
        self._mode_pub.publish(ros_qos.controller_mode_msg(mode))
        self.counts['modes'] += 1

    @guarded('fall event')
    def _on_fall_event(self, msg: FallEvent) -> None:
        if msg.event != EVENT_RESET:
            return
        self._timeline.reset()
        self._switch = self._new_switch()
        self.counts['resets'] += 1
        self.get_logger().info('monitor reset: fresh C_bal')

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
        self._command = q
        self.output.publish(ros_qos.joint_state_to_msg(decoded.stamp_ns, self._profile.joint_names, q))
        self.counts['commands'] += 1

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
        values = {'mode': self._switch.mode, 't_switch_s': self._switch.t_switch,
                  'stamp_ns': self._timeline.last_ns,
                  'fall_trigger_enabled': self._fall_trigger_enabled,
                  'invalid_inputs': self._bad_inputs.count, 'last_error': self._bad_inputs.last,
                  **self._timeline.counters(), **self.counts}
        dropped = self._bad_inputs.new_since_last_call()
        if dropped:
            return LEVEL_WARN, f'{self._switch.mode}; {dropped} invalid inputs dropped', values
        return LEVEL_OK, self._switch.mode, values


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.controller_node --ros-args ...``."""
    return run_node(ControllerNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
