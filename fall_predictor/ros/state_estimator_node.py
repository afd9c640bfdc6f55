"""state_estimator_node: the robot's own sensor topics -> the measurement the monitor reads.

Subscribes to what a robot already publishes, as its drivers publish it (method §12):

* ``robot_description`` (``std_msgs/String``, transient local: the URDF; the sole frames come from
  it or from the robot profile, ``robot``);
* ``joint_states`` (``sensor_msgs/JointState``): any order, split over several messages or
  publishers, names the URDF does not know ignored (logged once), velocity optional, each
  publisher on its own clock and rate;
* ``imu/data`` (``sensor_msgs/Imu``): on any link of the URDF (its ``header.frame_id``);
* ``left_foot/wrench`` and ``right_foot/wrench`` (``geometry_msgs/WrenchStamped``), in any frame
  of the URDF, when the robot profile says the robot has foot force/torque sensors.

Each message of the driving topic (``driving_topic``: ``joint_states`` by default, or ``imu/data``)
is one estimate (:class:`~fall_predictor.monitor.sensor_pipeline.SensorPipeline`, the same code
the offline tools run over recordings): the newest IMU and wrench readings within
``sync_tolerance_s`` of its stamp, interpolated where they bracket it. It publishes
``fall_predictor/measurement`` (``fall_predictor/msg/Measurement``) stamped with the driving
message's own stamp, or, when a sensor is missing, stale, stuck or implausible, a measurement that
carries only the fault in words ("no /imu/data within 5 ms of /joint_states", "joint l_knee_pitch
never received"): the monitor then publishes a DEGRADED state, never a prediction from a sensor
taken as zero. The same reason goes to ``/diagnostics`` and to a throttled log line with how long
it has lasted.

The sensor messages are taken serialized and read straight from their CDR bytes
(:mod:`fall_predictor.contract.cdr`: a few µs a message instead of rclpy's ~30 µs message
objects); a message in another encoding is decoded by rclpy instead (counted as
``rclpy_decoded_messages``).

With ``input`` ``unitree_hg`` (a Unitree humanoid: ``fall_monitor --estimator --ros-args -p
input:=unitree_hg``, or ``monitor.launch.py input:=unitree_hg``) it subscribes to ``lowstate``
(``unitree_hg/msg/LowState``, 500 Hz) instead of ``joint_states`` and ``imu/data``: each message is
converted by :class:`~fall_predictor.monitor.lowstate.LowStateConverter` (the motors named from
the robot profile's table for the robot's ``mode_machine``, stamped from the receive time with the
tick's spacing, a motor's error bit or a ``mode_machine`` the profile does not describe a fault in
words) and is one estimate. The robot publishes no ``robot_description``: the node publishes its
profile's URDF there (latched) unless one arrives. Joints a policy holds (the waist and arms
under Unitree's 12-joint policy) off their targets give a warning (log, ``/diagnostics``).

Stamps follow the time rule of :mod:`fall_predictor.monitor.timeline` (ROS time; one stray stamp
is dropped; a confirmed step of the clock, back or forward, starts a new run: the readings of the
old timeline are dropped, the estimator starts again, the step is logged once, and the measurement
handed over in process says so, so that the monitor's nodes restart their windows at once, never
the latch). Each sensor stream's clock follows the same rule: one that steps alone gives DEGRADED
measurements that say the clocks differ. The RESET event on ``fall_predictor/fall_event`` (the
monitor's one reset) starts a new run too.
"""
from __future__ import annotations

import time
from functools import partial
from typing import Any, Callable, Optional

from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import Imu, JointState
from rclpy.serialization import deserialize_message
from std_msgs.msg import String

from fall_predictor.contract import cdr, messages, unitree_hg
from fall_predictor.contract.topics import (FALL_EVENT, IMU, LEFT_FOOT_WRENCH, MEASUREMENT,
                                            ODOM_FRAME, RIGHT_FOOT_WRENCH, ROBOT_DESCRIPTION,
                                            SENSOR_JOINT_STATES, WireFormatError)
from fall_predictor.contract.wire import LEVEL_ERROR, LEVEL_OK, LEVEL_STALE, LEVEL_WARN
from fall_predictor.monitor.estimator import EstimatorConfig
from fall_predictor.monitor.fall_monitor import EVENT_RESET
from fall_predictor.monitor.lowstate import LowStateConverter
from fall_predictor.monitor.plausibility import MAX_DESCRIPTION_CHARS, bound_names
from fall_predictor.monitor.robot_description import DescriptionError, SensorLayout
from fall_predictor.monitor.sensor_pipeline import Estimate, PipelineConfig, SensorPipeline
from fall_predictor.monitor.sensor_sync import SyncConfig
from fall_predictor.monitor.timeline import TimelineConfig
from fall_predictor.msg import FallEvent
from fall_predictor.msg import Measurement as MeasurementMsg
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import (HANDLED_ERRORS, Diagnostics, FaultLog, InputErrors, Report,
                                       guarded)
from fall_predictor.ros.in_process import Output
from fall_predictor.ros.lifecycle import AUTOSTART, MonitorLifecycleNode
from fall_predictor.ros.parameters import NodeStartupError, ParamSpec, declare_parameters
from fall_predictor.ros.robots import ROBOT_PARAM, profile_for
from fall_predictor.ros.runner import run_node

NODE_NAME = 'state_estimator_node'
_DEFAULT_SYNC = SyncConfig()
PARAMS = (
    AUTOSTART, ROBOT_PARAM,
    ParamSpec('input', 'sensor_msgs', "the robot's sensor topics: 'sensor_msgs' (joint_states, "
              "imu/data, foot wrenches) or 'unitree_hg' (a Unitree humanoid's lowstate)",
              read_only=True),
    ParamSpec('driving_topic', 'joint_states', "the topic whose messages drive the estimates: "
              "'joint_states' or 'imu/data'", read_only=True),
    ParamSpec('driving_joints', [''], 'joint state messages drive an estimate only if they carry '
              'one of these joints (split messages: the legs); empty: any joint', read_only=True),
    ParamSpec('sync_tolerance_s', _DEFAULT_SYNC.tolerance_s, 'IMU and wrench readings are used '
              'within this of the driving stamp [s]', 1e-4, 0.1, read_only=True),
    ParamSpec('joint_timeout_s', _DEFAULT_SYNC.joint_timeout_s, 'a joint not updated for this '
              'long [s] before the driving stamp is missing (a degraded state)', 1e-3, 1.0,
              read_only=True),
    ParamSpec('max_step_s', TimelineConfig().max_step_s, 'time rule: the largest step between '
              'samples of one run [s]; a longer one is a clock jump if confirmed', 0.01, 60.0,
              read_only=True),
    ParamSpec('contact_force_n', 10.0, 'foot normal force above which a foot is loaded [N]',
              0.0, 10000.0, read_only=True),
    ParamSpec('stale_timeout_s', 0.5, 'wall time [s] without a sensor message after which '
              '/diagnostics reports STALE', 0.01, 60.0),
)
_DRIVING = {'joint_states': 'joints', 'imu/data': 'imu'}
INPUTS = ('sensor_msgs', 'unitree_hg')
#: A held joint's warning is logged at most this often [s].
_WARNING_THROTTLE_S = 5.0


class StateEstimatorNode(MonitorLifecycleNode):
    """Wraps :class:`~fall_predictor.monitor.sensor_pipeline.SensorPipeline`; see the module docs
    (a managed node: configure reads the robot profile and builds the robot model from
    ``robot_description`` when it is there; ``ros/lifecycle.py``)."""

    def __init__(self, **kwargs: object) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = self._params = declare_parameters(self, PARAMS, _check_driving)
        self._layout: Optional[SensorLayout] = None
        self._description: Optional[str] = None
        sync = SyncConfig(tolerance_s=float(p['sync_tolerance_s']),
                          joint_timeout_s=float(p['joint_timeout_s']))
        self._config = PipelineConfig(
            driving=_DRIVING[str(p['driving_topic'])],
            driving_joints=tuple(n for n in p['driving_joints'] if n), sync=sync,
            estimator=EstimatorConfig(contact_force_n=float(p['contact_force_n'])),
            timeline=TimelineConfig(max_step_s=float(p['max_step_s'])))
        self._stale_timeout_s = float(p['stale_timeout_s'])
        self._bad_inputs = InputErrors(self)
        self._faults = FaultLog(self)
        self.counts = {'joint_messages': 0, 'imu_messages': 0, 'wrench_messages': 0,
                       'measurements': 0, 'faults': 0, 'resets': 0, 'rclpy_decoded_messages': 0}
        self._joint_states = cdr.JointStateDecoder()
        self._last_input_wall: Optional[float] = None
        #: The measurements, published and handed to in-process consumers (``fall_monitor``).
        self.output = Output(create_publisher(self, MeasurementMsg, MEASUREMENT))
        self._topics = {'joints': self.resolve_topic_name(SENSOR_JOINT_STATES.ros_name),
                        'imu': self.resolve_topic_name(IMU.ros_name),
                        'l': self.resolve_topic_name(LEFT_FOOT_WRENCH.ros_name),
                        'r': self.resolve_topic_name(RIGHT_FOOT_WRENCH.ros_name)}
        self._unitree = str(p['input']) == 'unitree_hg'
        self._inputs = [create_subscription(self, String, ROBOT_DESCRIPTION, self._on_description)]
        self._converter: Optional[LowStateConverter] = None
        self._warning, self._warned_at = '', -float('inf')
        self._description_out = None
        if self._unitree:
            # Unitree's message package (unitree_ros2's unitree_hg) only where it is asked for.
            try:
                from unitree_hg.msg import LowState
            except ImportError as error:
                raise NodeStartupError(
                    f"input unitree_hg needs Unitree's unitree_hg messages ({error}): source the "
                    'workspace where unitree_ros2 is built') from None
            self._lowstate_msg = LowState
            self._topics['joints'] = self._topics['imu'] = self.resolve_topic_name(
                unitree_hg.LOWSTATE.ros_name)
            self.counts.update(lowstate_messages=0)
            self._inputs.append(create_subscription(self, LowState, unitree_hg.LOWSTATE,
                                                    self._on_lowstate, raw=True))
            self._description_out = create_publisher(self, String, ROBOT_DESCRIPTION)
        else:
            self._inputs += [
                create_subscription(self, JointState, SENSOR_JOINT_STATES, self._on_joint_state,
                                    raw=True),
                create_subscription(self, Imu, IMU, self._on_imu, raw=True)]
        self._wrench_subscriptions: list = []
        create_subscription(self, FallEvent, FALL_EVENT, self._on_fall_event)
        self._pipeline: Optional[SensorPipeline] = None
        self._diagnostics = Diagnostics(self, self._report, self._last_stamp, self._inputs,
                                        self._bad_inputs)
        self.start(bool(p['autostart']))

    def _configure(self) -> None:
        profile = profile_for(str(self._params['robot']))
        self._layout = profile.sensor_layout()
        if self._unitree:
            if profile.unitree_hg is None:
                raise NodeStartupError(f'input unitree_hg: robot profile {profile.name} has no '
                                       'unitree_hg section (its motor table): use one that has '
                                       '(g1, g1_12dof) or add it')
            self._converter = LowStateConverter(
                profile.unitree_hg, self._layout.imu_frame, profile.joint_names,
                self._topics['joints'], f'robot profile {profile.name}')
            if self._description is None:
                # The robot publishes none: its profile's, for the estimator and for others.
                self._description = profile.urdf_xml()
                self._description_out.publish(String(data=self._description))
        # The foot sensors the robot has (its profile's).
        for side, spec in (('l', LEFT_FOOT_WRENCH), ('r', RIGHT_FOOT_WRENCH)):
            if side in self._layout.force_sensors:
                sub = create_subscription(self, WrenchStamped, spec,
                                          lambda data, side=side: self._on_wrench(side, data),
                                          raw=True)
                self._wrench_subscriptions.append(sub)
                self._inputs.append(sub)
        if self._description is not None:
            self._build(self._description)
        else:
            self.get_logger().info('state estimator waiting for '
                                   f'{self.resolve_topic_name(ROBOT_DESCRIPTION.ros_name)}')

    def _cleanup(self) -> None:
        self._layout = self._pipeline = self._converter = None
        for sub in self._wrench_subscriptions:
            self._inputs.remove(sub)
            self.destroy_subscription(sub)
        self._wrench_subscriptions.clear()

    def _last_stamp(self) -> int:
        return 0 if self._pipeline is None else self._pipeline.timeline.last_ns or 0

    # -- inputs ----------------------------------------------------------------------------
    @guarded('robot description')
    def _on_description(self, msg: String) -> None:
        if len(msg.data) > MAX_DESCRIPTION_CHARS:
            raise WireFormatError(f'a robot description of {len(msg.data)} characters (at most '
                                  f'{MAX_DESCRIPTION_CHARS} are read)')
        if msg.data == self._description:
            return                      # (the profile's URDF this node published)
        self._description = msg.data
        if self._layout is not None:
            self._build(msg.data)

    def _build(self, urdf: str) -> None:
        """The estimator's robot model of ``urdf`` (a description it cannot use is logged)."""
        assert self._layout is not None
        try:
            robot = self._layout.description(urdf)
        except DescriptionError as error:
            self._bad_inputs.reject('robot description', error)
            return
        self._pipeline = SensorPipeline(robot, self._layout.imu_frame, self._layout.force_sensors,
                                        self._config, self._topics)
        self.get_logger().info(f'robot description: {robot.total_mass_kg:.2f} kg, '
                               f'{len(robot.joint_names)} joints; estimates driven by '
                               f'{self._topics[self._config.driving]}')

    def _read(self, data: bytes, read_cdr: Callable[[bytes], Any], msg_type: type,
              from_msg: Callable[[Any], Any]) -> Any:
        """A sensor message's reading from its serialized bytes: read as CDR, or, in an encoding
        that does not read so, deserialized by rclpy (WireFormatError if that fails too)."""
        try:
            return read_cdr(data)
        except cdr.CdrError:
            pass
        self.counts['rclpy_decoded_messages'] += 1
        try:
            msg = deserialize_message(data, msg_type)
        except Exception as error:      # rclpy raises several types for bytes it cannot read
            raise WireFormatError(f'{msg_type.__name__} message does not deserialize: {error}'
                                  ) from None
        return from_msg(msg)

    @guarded('joint state')
    def _on_joint_state(self, data: bytes) -> None:
        self._touch('joint_messages')
        if not self._ready:
            return
        reading = self._read(data, self._joint_states, JointState, messages.joint_state_reading)
        estimates, unknown = self._pipeline.joint_state(reading)
        if unknown:
            self.get_logger().info(f'ignoring joints the robot description does not have: '
                                   f'{bound_names(unknown)}')
        self._publish(estimates)

    @guarded('IMU reading')
    def _on_imu(self, data: bytes) -> None:
        self._touch('imu_messages')
        if self._ready:
            reading = self._read(data, cdr.imu_reading, Imu, messages.imu_reading)
            self._publish(self._pipeline.imu(reading))

    @guarded('foot wrench')
    def _on_wrench(self, side: str, data: bytes) -> None:
        self._touch('wrench_messages')
        if self._ready:
            reading = self._read(data, cdr.wrench_reading, WrenchStamped, messages.wrench_reading)
            self._publish(self._pipeline.wrench(side, reading))

    @guarded('low state')
    def _on_lowstate(self, data: bytes) -> None:
        self._touch('lowstate_messages')
        if not self._ready or self._converter is None:
            return
        receive_ns = self.get_clock().now().nanoseconds
        try:
            record = unitree_hg.lowstate_record(data)
        except WireFormatError:
            # Another encoding: rclpy's message object (~0.7 ms for 35 nested motors, against
            # 6 us for the CDR read).
            self.counts['rclpy_decoded_messages'] += 1
            try:
                msg = deserialize_message(data, self._lowstate_msg)
            except Exception as error:  # rclpy raises several types for bytes it cannot read
                raise WireFormatError(f'LowState message does not deserialize: {error}') from None
            record = unitree_hg.lowstate_from_msg(msg)
        sample = self._converter.convert(record, receive_ns)
        for notice in self._converter.take_notices():
            self.get_logger().info(notice)         # the variant; a tick wrap or restart, once
        if sample is None:
            return                      # the same message twice (counted)
        if sample.warning:
            self._warning = sample.warning
            now = time.monotonic()
            if now - self._warned_at >= _WARNING_THROTTLE_S:
                self._warned_at = now
                self.get_logger().warning(sample.warning)
        self._publish(self._pipeline.lowstate(sample))

    @guarded('fall event')
    def _on_fall_event(self, msg: FallEvent) -> None:
        if msg.event == EVENT_RESET and self._pipeline is not None:
            self._pipeline.reset()
            if self._converter is not None:
                self._converter.reset()
            self.counts['resets'] += 1

    def _touch(self, what: str) -> None:
        self.counts[what] += 1
        self._last_input_wall = time.monotonic()

    @property
    def _ready(self) -> bool:
        """Active, with a robot model: sensor messages are estimated."""
        return self.active and self._pipeline is not None

    def _publish(self, estimates: list[Estimate]) -> None:
        for notice in self._pipeline.take_notices():
            self.get_logger().warning(notice)      # each clock step once, in words
        for e in estimates:
            self._faults.update(e.fault)
            self.counts['faults' if e.fault else 'measurements'] += 1
            sample = messages.StampedMeasurement(e.stamp_ns, ODOM_FRAME, e.fault, e.measurement,
                                                 e.new_run)
            try:
                self.output.hand_off(sample, partial(messages.measurement_msg, ros_qos.TYPES,
                                                     e.stamp_ns, ODOM_FRAME, e.measurement, e.fault))
            except HANDLED_ERRORS as error:
                self._bad_inputs.reject(f'estimate at {e.stamp_ns} ns', error)

    # -- health ----------------------------------------------------------------------------
    def _report(self) -> Report:
        values: dict[str, object] = {'invalid_inputs': self._bad_inputs.count,
                                     'last_error': self._bad_inputs.last, **self.counts}
        pipeline = self._pipeline
        if pipeline is not None:
            period = pipeline.timeline.period_s
            values.update(pipeline.timeline.counters())
            values.update(pipeline.sync.counts)
            # Samples kept but past a joint's limit or rated speed (monitor/plausibility.py).
            values['flagged'] = pipeline.counts['flagged']
            values['last_flag'] = pipeline.last_flags
            values['driving_rate_hz'] = None if not period else round(1.0 / period, 1)
            values['joints_never_received'] = ' '.join(pipeline.sync.joints.never_received())
        if self._converter is not None:
            values.update(self._converter.counts)
        if not self.active:
            return LEVEL_STALE, 'inactive (lifecycle)', values
        if pipeline is None:
            return LEVEL_STALE, 'no usable robot description yet', values
        if self._last_input_wall is None:
            return LEVEL_STALE, 'no sensor message received yet', values
        silent_s = time.monotonic() - self._last_input_wall
        if silent_s > self._stale_timeout_s:
            return LEVEL_STALE, f'no sensor message for {silent_s:.1f} s', values
        fault = self._faults.current()
        if fault:
            return LEVEL_ERROR, fault, values
        dropped = self._bad_inputs.new_since_last_call()
        if dropped:
            return LEVEL_WARN, f'{dropped} invalid sensor messages dropped', values
        warning, self._warning = self._warning, ''
        if warning:
            return LEVEL_WARN, warning, values
        return LEVEL_OK, 'estimating', values


def _check_driving(values) -> Optional[str]:
    if values['input'] not in INPUTS:
        return f"input must be one of {list(INPUTS)}, got {values['input']!r}"
    if values['driving_topic'] not in _DRIVING:
        return f"driving_topic must be one of {sorted(_DRIVING)}, got {values['driving_topic']!r}"
    return None


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.state_estimator_node --ros-args ...``."""
    return run_node(StateEstimatorNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
