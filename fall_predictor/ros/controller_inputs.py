"""What the controller node's walking controller observes, one handler per kind of controller
(robot/control.py ``Controller.observes``): :class:`StateInput` takes the measurements C_bal reads
(the simulator's exact state, or the estimator's measurement); :class:`SensorInput` takes the
robot's ``joint_states`` and ``imu/data`` a learned policy reads, and says when the policy is due.

Each handler subscribes to its topics (a message it cannot read counted by the node's
:class:`~fall_predictor.ros.health.InputErrors`), keeps the time rule of its stream (its
:class:`~fall_predictor.monitor.timeline.StampTimeline`), and turns each input into
:class:`ControlStep` s: a stamp, a new run or not, and what the controller observes at it (None:
hold the last command, the reason said). The node runs the controller on them
(:mod:`fall_predictor.ros.controller_node`); nothing here knows which controller that is beyond
what it observes.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

from sensor_msgs.msg import Imu, JointState

from fall_predictor.contract import messages
from fall_predictor.contract.topics import GROUND_TRUTH, IMU, MEASUREMENT, SENSOR_JOINT_STATES
from fall_predictor.monitor.plausibility import bound_names
from fall_predictor.monitor.timeline import Stamp, StampTimeline
from fall_predictor.msg import Measurement
from fall_predictor.robot.control import Observation
from fall_predictor.ros.endpoints import create_subscription
from fall_predictor.ros.health import InputErrors, guarded
from fall_predictor.ros.in_process import Output, connect_input
from fall_predictor.ros.policy_inputs import PolicyInputs, PolicySchedule


@dataclass(frozen=True)
class ControlStep:
    """One input the controller answers: its stamp [ns], whether it starts a new run, what the
    controller observes (None: it cannot: hold the last command), whether the controller is due
    (a policy acts every period; C_bal every sample), and why it was held."""

    stamp_ns: int
    new_run: bool
    observation: Optional[Observation]
    due: bool = True
    fault: str = ''


class StateInput:
    """C_bal's input: every ``fall_predictor/measurement`` (or ``fall_predictor/ground_truth``),
    read reliably (it closes the simulator's lock-step loop), or handed over in process. A
    measurement that carries a fault (the estimator's sensors degraded) is held."""

    def __init__(self, node, answer: Callable[[list[ControlStep]], None], bad_inputs: InputErrors,
                 ground_truth: bool, upstream: Optional[Output]) -> None:
        self._answer = answer
        self._bad_inputs = bad_inputs           # the node's: what it cannot read is counted there
        self.timeline = StampTimeline()
        source = GROUND_TRUTH if ground_truth else MEASUREMENT
        self.subscriptions = connect_input(node, Measurement, source, self._on_measurement,
                                           upstream, lossless=True, take=self._take_measurement)

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
        kind = self.timeline.classify(decoded.stamp_ns)
        if not kind.accepted:
            return                              # duplicate, out of order, stray: counted
        m = decoded.measurement
        observation = None if m is None else Observation(m.t, m)
        self._answer([ControlStep(decoded.stamp_ns, kind is Stamp.NEW_RUN, observation,
                                  fault='' if m is not None else 'the measurement carries a fault')])

    def acted(self, stamp_ns: int) -> None:
        """C_bal answered the sample of ``stamp_ns`` (it answers every one)."""

    def restart(self) -> None:
        """A fresh walking controller: nothing of the input's own to restart."""

    def reset(self) -> None:
        """The monitor's reset: the stream's time rule starts again."""
        self.timeline.reset()

    def report(self) -> dict:
        return {}


class SensorInput:
    """A learned policy's input: the robot's ``joint_states`` and ``imu/data`` (reliably), merged
    as the state estimator merges them (:class:`~fall_predictor.ros.policy_inputs.PolicyInputs`:
    one sensor sample per joint state stamp); every sample is answered, the policy acting every
    ``period_s`` of the samples' time (:class:`~fall_predictor.ros.policy_inputs.PolicySchedule`).
    A sample whose sensors are missing, stale or implausible is held, never taken as zero."""

    def __init__(self, node, answer: Callable[[list[ControlStep]], None], bad_inputs: InputErrors,
                 robot, period_s: float) -> None:
        """``robot``: the robot description whose joint states the policy reads
        (monitor/robot_description.py)."""
        self._node = node
        self._answer = answer
        self._bad_inputs = bad_inputs           # the node's: what it cannot read is counted there
        topics = {'joints': node.resolve_topic_name(SENSOR_JOINT_STATES.ros_name),
                  'imu': node.resolve_topic_name(IMU.ros_name)}
        self._inputs = PolicyInputs(robot.joint_names, robot.joint_bounds, topics=topics)
        self.timeline = self._inputs.timeline
        #: The merge of the two streams (its counters say what was taken).
        self.sync = self._inputs.sync
        self._schedule = PolicySchedule(period_s)
        self.subscriptions = [
            create_subscription(node, JointState, SENSOR_JOINT_STATES, self._on_joint_state,
                                lossless=True),
            create_subscription(node, Imu, IMU, self._on_imu, lossless=True)]

    @guarded('joint state')
    def _on_joint_state(self, msg: JointState) -> None:
        steps, unknown = self._inputs.joint_state(messages.joint_state_reading(msg))
        if unknown:
            self._node.get_logger().info(f'ignoring joints the robot does not have: '
                                         f'{bound_names(unknown)}')
        self._control(steps)

    @guarded('IMU reading')
    def _on_imu(self, msg: Imu) -> None:
        self._control(self._inputs.imu(messages.imu_reading(msg)))

    def _control(self, steps) -> None:
        out = []
        for step in steps:
            if step.new_run:
                self._schedule.restart()
            due = self._schedule.due(step.stamp_ns)
            observation = None if step.sample is None else Observation(step.t_s, None, step.sample)
            out.append(ControlStep(step.stamp_ns, step.new_run, observation, due,
                                   '' if step.sample is not None else str(step.fault)))
        self._answer(out)

    def acted(self, stamp_ns: int) -> None:
        """The policy acted on the sample of ``stamp_ns``: the next is due a period later."""
        self._schedule.acted(stamp_ns)

    def restart(self) -> None:
        """A fresh walking controller: it acts on the next usable sample."""
        self._schedule.restart()

    def reset(self) -> None:
        """The monitor's reset: the streams' time rule starts again."""
        self._inputs.reset()

    def report(self) -> dict:
        return {'sensor_faults': self._inputs.counts['faults']}
