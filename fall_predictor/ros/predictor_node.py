"""predictor_node: features -> the monitor's state, the trigger, the fall events.

Loads a decision-list model (:func:`~fall_predictor.monitor.model_file.load_model`) and runs
:class:`~fall_predictor.monitor.fall_monitor.FallMonitor` on every ``fall_predictor/features``
sample; this node only converts messages. Outputs (the contract is in
:mod:`fall_predictor.contract.topics` and the README):

* ``fall_predictor/state`` (``fall_predictor/msg/FallState``): one per accepted input sample,
  stamped with the sample's own stamp: status (OK, DEGRADED, STALE, DISABLED, FALLEN) with the
  reason in words, falling, latched, contact mode, time to fall, fall direction, window in use;
* ``fall_predictor/fall_event`` (``fall_predictor/msg/FallEvent``, latched): FALLING (the trigger
  set, with direction and time to fall), FALLEN, STANDING, RESET;
* ``fall_predictor/falling`` (``std_msgs/Bool``, reliable, transient local, depth 1): the trigger
  for consumers that want common types: ``false`` at start-up, ``true`` from the first falling
  prediction until the reset; ``fall_predictor/fall_direction`` (``geometry_msgs/Vector3Stamped``,
  ``base_footprint``, latched) with each FALLING event.

Services: ``fall_predictor/reset`` (``std_srvs/Trigger``): the one reset of the whole monitor
(history, latch and trigger here; the other monitor nodes and the controller follow the RESET
event, published before ``falling`` turns false), the only way to undo a fall; ``fall_predictor/
enable`` (``std_srvs/SetBool``): false switches the trigger off (states say DISABLED; nothing new
triggers). The latch survives the trigger switched off and on, a lifecycle deactivate/activate and
a cleanup/configure (the model read again): ``falling`` never turns false without a RESET event.

Inputs follow the time rule of :mod:`fall_predictor.monitor.timeline` (dropped stamps counted; a
confirmed clock jump restarts the window, never the latch). A sample whose stamp differs from the
node's ROS clock by more than ``max_sample_age_s`` (system time on a robot, ``/clock`` under
``use_sim_time``) gets a STALE state, with the reason; a features message carrying a fault gets a
DEGRADED state with it; a wall-clock watchdog publishes a STALE state whenever no features arrived
for ``stale_timeout_s``. Health, counters and reasons go to ``/diagnostics``.

Parameters: ``model_path`` (default: the shipped model), ``tau_his_s`` (settable at run time
within its range; default: the model's recommended window, taken at configure), ``decision_threshold`` (boosted-trees models only;
settable at run time; default: the model's), ``stale_timeout_s``, ``max_sample_age_s``,
``robot_mass_kg``, and the fallen-detection heights of the robot (``robot``'s profile). A missing
or invalid model makes the node refuse to start with one FATAL line (exit code 1).
"""
from __future__ import annotations

import math
import time
from typing import Callable, Optional

from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, Trigger

from fall_predictor.contract import cdr, messages
from fall_predictor.contract.topics import (ENABLE_SERVICE, FALL_DIRECTION, FALL_EVENT, FALLING,
                                            FEATURES, HEADING_FRAME, MONITOR_RESET_SERVICE, STATE)
from fall_predictor.contract.wire import LEVEL_OK, LEVEL_STALE, LEVEL_WARN
from fall_predictor.monitor.decision_list import NO_DECISION_THRESHOLD
from fall_predictor.monitor.fall_monitor import (EVENT_FALLING, EVENT_NAMES, FallEvent, FallMonitor,
                                                 MonitorState)
from fall_predictor.monitor.records import N_FEATURES
from fall_predictor.monitor.timeline import Stamp, StampTimeline
from fall_predictor.msg import FallEvent as FallEventMsg
from fall_predictor.msg import FallState, Features
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher
from fall_predictor.ros.health import (MAX_SAMPLE_AGE, Diagnostics, FaultLog, InputErrors, Report,
                                       SampleAge, guarded, steady_clock)
from fall_predictor.ros.in_process import Output, connect_input
from fall_predictor.ros.lifecycle import AUTOSTART, MonitorLifecycleNode
from fall_predictor.ros.parameters import (FROM_MODEL, MAX_MODEL_BYTES, MODEL_PATH,
                                           NodeStartupError, ParamSpec, declare_parameters,
                                           feature_setting_params, load_model_for)
from fall_predictor.ros.robots import ROBOT_PARAM, fallen_config_for, profile_for
from fall_predictor.ros.runner import run_node

NODE_NAME = 'predictor_node'
#: Largest accepted history window [s]: beyond the longest oracle lead a window only hides falls.
MAX_TAU_HIS_S = 2.0
#: Period of the wall-clock staleness check [s].
_WATCHDOG_PERIOD_S = 0.05

STALE_TIMEOUT = ParamSpec(
    'stale_timeout_s', 0.5, 'wall time [s] without features after which a STALE state is '
    'published (and repeated every stale_timeout_s)', 0.01, 60.0)
#: Feature settings this node uses, checked against the model's.
SETTINGS = ('sample_period_s', 'guard_com_height_m')


ROBOT_MASS = ParamSpec('robot_mass_kg', FROM_MODEL, 'total robot mass [kg] (fall direction); '
                       '-1 = the robot profile\'s', 1.0, 1000.0, read_only=True,
                       unset=FROM_MODEL)
TAU_HIS = ParamSpec('tau_his_s', FROM_MODEL, 'history window [s]: falling only when every atomic '
                    'prediction of the last tau_his_s was falling (method §8); settable at run '
                    'time; -1 = the model\'s recommended window (set at configure)', 0.0,
                    MAX_TAU_HIS_S, unset=FROM_MODEL)
#: ``decision_threshold``'s "the model's own" value (a log-odds threshold may be any sign).
THRESHOLD_FROM_MODEL = -1000.0
DECISION_THRESHOLD = ParamSpec('decision_threshold', THRESHOLD_FROM_MODEL, 'boosted-trees models: '
                               'falling when the score [log-odds] exceeds it (method §8a); settable '
                               'at run time; -1000 = the model\'s (set at configure); refused for '
                               'decision lists', -50.0, 50.0, unset=THRESHOLD_FROM_MODEL)


class PredictorNode(MonitorLifecycleNode):
    """Wraps :class:`~fall_predictor.monitor.fall_monitor.FallMonitor`; see the module docs (a
    managed node: configure loads the model, activate starts the trigger; ``ros/lifecycle.py``)."""

    def __init__(self, upstream: Optional[Output] = None, **kwargs: object) -> None:
        """``upstream``: take the features from this output of a node of the same process
        (``fall_monitor``) instead of subscribing; ``kwargs`` go to ``Node``."""
        super().__init__(NODE_NAME, **kwargs)
        p = self._params = declare_parameters(
            self, (AUTOSTART, MODEL_PATH, MAX_MODEL_BYTES, STALE_TIMEOUT, MAX_SAMPLE_AGE, ROBOT_PARAM,
                   TAU_HIS, DECISION_THRESHOLD, ROBOT_MASS, *feature_setting_params(SETTINGS)))
        # A model of decision lists has no decision threshold, and the model's window is taken at
        # configure only: setting either is refused, in words.
        self.add_on_set_parameters_callback(self._check_parameters)
        self._stale_timeout_s = float(p['stale_timeout_s'])
        self._max_sample_age_s = float(p['max_sample_age_s'])
        self._monitor: Optional[FallMonitor] = None
        #: The latch and fallen state of a monitor cleaned up, carried to the next configure.
        self._kept_latch = (False, False)
        self._model_description = ''
        self.add_post_set_parameters_callback(self._apply_parameters)

        self._state_pub = create_publisher(self, FallState, STATE)
        self._event_pub = create_publisher(self, FallEventMsg, FALL_EVENT)
        self._falling_pub = create_publisher(self, Bool, FALLING)
        self._direction_pub = create_publisher(self, Vector3Stamped, FALL_DIRECTION)
        inputs = connect_input(self, Features, FEATURES, self._on_features, upstream,
                               take=self._take_features)
        self._timeline = StampTimeline()
        self._age = SampleAge(self)
        self._bad_inputs = InputErrors(self)
        self._faults = FaultLog(self)
        #: Counters by event name (reported in /diagnostics).
        self.counts = {'features': 0, 'states': 0, 'falling_states': 0, 'degraded_states': 0,
                       'stale_states': 0, 'fallen_states': 0, 'events': 0, 'resets': 0,
                       'trigger_messages': 0, 'direction_messages': 0}
        self._missing_at_report = 0
        self._last_valid_wall = time.monotonic()
        self._last_stale_wall = -math.inf
        self._stale_reason: Optional[str] = None
        self._trigger = False
        self.create_service(Trigger, MONITOR_RESET_SERVICE, self._on_reset)
        self.create_service(SetBool, ENABLE_SERVICE, self._on_enable)
        self.create_timer(_WATCHDOG_PERIOD_S, self._on_watchdog, clock=steady_clock())
        self._diagnostics = Diagnostics(self, self._report, lambda: self._timeline.last_ns or 0,
                                        inputs, self._bad_inputs)
        self.start(bool(p['autostart']))

    def _configure(self) -> None:
        p = self._params
        lists, metadata, settings = load_model_for(self, str(p['model_path']),
                                                   {k: p[k] for k in SETTINGS},
                                                   int(p['max_model_bytes']), str(p['robot']))
        robot = str(p['robot'])
        tau_his_s = self.get_parameter('tau_his_s').value
        if tau_his_s == FROM_MODEL:         # the model's recommended window, shown as the value
            tau_his_s = min(metadata.recommended_tau_his_s or 0.0, MAX_TAU_HIS_S)
            self.set_parameters([Parameter('tau_his_s', value=float(tau_his_s))])
        threshold = self.get_parameter('decision_threshold').value
        if threshold != THRESHOLD_FROM_MODEL:
            try:
                lists = lists.with_decision_threshold(float(threshold))
            except ValueError as error:
                raise NodeStartupError(f'decision_threshold is set, but {error}') from error
        elif lists.decision_threshold is not None:     # the model's threshold, shown as the value
            self.set_parameters([Parameter('decision_threshold',
                                           value=float(lists.decision_threshold))])
        profile = profile_for(robot)
        mass_kg = ROBOT_MASS.value_or_none(p['robot_mass_kg']) or profile.total_mass_kg
        model_mass_kg = getattr(metadata, 'robot_mass_kg', None)
        if model_mass_kg and abs(model_mass_kg - profile.total_mass_kg) > 0.05 * profile.total_mass_kg:
            self.get_logger().warning(
                f'the model was trained on a robot of {model_mass_kg:.1f} kg; robot {profile.name!r} '
                f'weighs {profile.total_mass_kg:.1f} kg: its alarms are those of another robot')
        self._monitor = FallMonitor(lists, float(tau_his_s), fallen_config_for(robot),
                                    settings.sample_period_s, settings.guard_com_height_m,
                                    float(mass_kg), getattr(metadata, 'time_to_fall', None),
                                    fall_direction=getattr(metadata, 'fall_direction', None))
        self._monitor.take_over(*self._kept_latch)      # a cleanup undoes no fall
        self._timeline.reset()
        reads = '' if lists.n_inputs == N_FEATURES else ", reads the base's attitude"
        self._model_description = (f'{p["model_path"] or "the shipped model"} (mean rule size '
                                   f'{lists.mean_rule_size:.1f}, tau_plus {metadata.tau_plus_s} s'
                                   f'{reads})')
        self.get_logger().info(f'predictor ready: model {self._model_description}, '
                               f'tau_his_s={tau_his_s}, robot mass {mass_kg:.1f} kg')

    def _activate(self) -> None:
        self._last_valid_wall = time.monotonic()
        self._publish_trigger(self._monitor.latched)    # false at start; a latched fall stays true

    def _deactivate(self) -> None:
        pass                                # the trigger stays as it is: only the reset undoes it

    def _cleanup(self) -> None:
        if self._monitor is not None:
            self._kept_latch = (self._monitor.latched, self._monitor.fallen)
        self._monitor = None

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'tau_his_s' and self._monitor is not None:
                if parameter.value == FROM_MODEL:
                    continue
                self._monitor.tau_his_s = float(parameter.value)
                self.get_logger().info(f'tau_his_s = {parameter.value} s')
            elif (parameter.name == 'decision_threshold' and self._monitor is not None
                  and parameter.value != THRESHOLD_FROM_MODEL):
                self._monitor.decision_threshold = float(parameter.value)
                self.get_logger().info(f'decision_threshold = {parameter.value}')
            elif parameter.name == 'stale_timeout_s':
                self._stale_timeout_s = float(parameter.value)
            elif parameter.name == 'max_sample_age_s':
                self._max_sample_age_s = float(parameter.value)

    def _check_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if (parameter.name == 'decision_threshold' and self._monitor is not None
                    and parameter.value != THRESHOLD_FROM_MODEL
                    and not self._monitor.predictor.lists.boosted):
                return SetParametersResult(successful=False, reason=NO_DECISION_THRESHOLD)
            if (parameter.name == 'tau_his_s' and self._monitor is not None
                    and parameter.value == FROM_MODEL):
                return SetParametersResult(successful=False, reason=(
                    f'tau_his_s {FROM_MODEL:g} (the model\'s recommended window) is taken at '
                    f'configure only; while running give a window in [0, {MAX_TAU_HIS_S:g}] s '
                    f'(in use: {self._monitor.tau_his_s:g} s)'))
        return SetParametersResult(successful=True)

    # -- services --------------------------------------------------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if self._monitor is None:
            response.success, response.message = False, 'not configured (lifecycle)'
            return response
        # Stamped with the last sample's stamp (the time the monitor had reached), or, before any
        # sample, with the node's clock.
        stamp_ns = self._timeline.last_ns or self.get_clock().now().nanoseconds
        event = self._monitor.reset()
        self._kept_latch = (False, False)
        self._timeline.reset()
        self._publish_event(stamp_ns, event)
        self._publish_trigger(False)        # after the RESET event: never false without one
        self.counts['resets'] += 1
        self.get_logger().info('reset: history, latch and trigger cleared')
        response.success, response.message = True, 'monitor reset: history, latch and trigger cleared'
        return response

    def _on_enable(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        if self._monitor is None:
            response.success, response.message = False, 'not configured (lifecycle)'
            return response
        enabled = bool(request.data)
        if enabled != self._monitor.enabled:
            self._monitor.enable(enabled)
            self.get_logger().info(f'fall trigger {"enabled" if enabled else "disabled"}')
        response.success = True
        response.message = 'enabled' if enabled else 'disabled: no new trigger'
        if self._monitor.latched:
            response.message += ('; the fall already latched stays until '
                                 f'{self.resolve_service_name(MONITOR_RESET_SERVICE)}')
        return response

    # -- samples ---------------------------------------------------------------------------
    @guarded('features')
    def _on_features(self, msg: Features) -> None:
        self._receive(lambda: messages.features_from_msg(msg))

    @guarded('features')
    def _take_features(self, decoded: messages.StampedFeatures) -> None:
        """Features handed over in process (``fall_monitor``): the checks a decoded message
        passes, then the same path."""
        def checked() -> messages.StampedFeatures:
            messages.check_features(decoded)
            return decoded
        self._receive(checked)

    def _receive(self, decode: Callable[[], messages.StampedFeatures]) -> None:
        """Count a features sample, decode or check it (``decode``), then step the monitor; an
        invalid one is refused with an unusable state."""
        if not self.active:
            return
        self.counts['features'] += 1
        try:
            decoded = decode()
        except ValueError as error:
            self._bad_inputs.reject('features', error)
            self._publish_unusable(self._timeline.last_ns or 0, f'invalid features: {error}', True)
            return
        self._step(decoded)

    def _step(self, decoded: messages.StampedFeatures) -> None:
        if decoded.new_run:                 # confirmed upstream, in this process
            self._timeline.restart(decoded.stamp_ns)
            kind = Stamp.NEW_RUN
        else:
            kind = self._timeline.classify(decoded.stamp_ns)
        if not kind.accepted:
            return                          # duplicate, out of order, stray: counted
        if kind is Stamp.NEW_RUN:
            self._monitor.new_run()         # the window restarts; the latch stays
            if self._timeline.last_step_s < 0.0:
                self._age.input_stepped_back()
        self._last_valid_wall = time.monotonic()
        self._stale_reason = None
        late = SampleAge.problem(self._age.age_s(decoded.stamp_ns), self._max_sample_age_s)
        if late is not None:
            self._publish_unusable(decoded.stamp_ns, late, stale=True)
            return
        if decoded.fault:
            self._publish_unusable(decoded.stamp_ns, decoded.fault, stale=False)
            return
        state, event = self._monitor.step(self._timeline.run_time(decoded.stamp_ns), decoded.x,
                                          decoded.mode, decoded.base_tilt_rad)
        self._faults.update('')
        if event is not None:
            self._publish_event(decoded.stamp_ns, event)
        self._publish_state(decoded.stamp_ns, state)

    def _publish_unusable(self, stamp_ns: int, reason: str, stale: bool,
                          logged_as: Optional[str] = None) -> None:
        """A DEGRADED (or STALE) state with ``reason``; logged as ``logged_as`` (a reason that
        does not change while the fault lasts), else as ``reason``."""
        self._faults.update(logged_as or reason)
        self._publish_state(stamp_ns, self._monitor.unusable(reason, stale))

    def _publish_state(self, stamp_ns: int, state: MonitorState) -> None:
        # Serialized here, not built as a message object (contract/cdr.py: ~20 µs a sample less).
        self._state_pub.publish(cdr.fall_state_cdr(stamp_ns, HEADING_FRAME, state))
        self.counts['states'] += 1
        key = {1: 'degraded_states', 2: 'stale_states', 4: 'fallen_states'}.get(state.status)
        if key:
            self.counts[key] += 1
        elif state.falling:
            self.counts['falling_states'] += 1

    def _publish_event(self, stamp_ns: int, event: FallEvent) -> None:
        self._event_pub.publish(messages.fall_event_msg(
            ros_qos.TYPES, stamp_ns, HEADING_FRAME, event.kind, event.direction,
            event.time_to_fall_s, event.contact_mode))
        self.counts['events'] += 1
        if event.kind == EVENT_FALLING:
            if math.isfinite(event.direction[0]):
                self._direction_pub.publish(ros_qos.fall_direction_msg(stamp_ns, event.direction))
                self.counts['direction_messages'] += 1
            self._publish_trigger(True)
        self.get_logger().info(f'{EVENT_NAMES[event.kind]} at stamp {stamp_ns / 1e9:.3f} s'
                               + (f', direction ({event.direction[0]:.2f}, {event.direction[1]:.2f})'
                                  if event.kind == EVENT_FALLING else ''))

    def _publish_trigger(self, falling: bool) -> None:
        if falling != self._trigger or falling is False:
            self._falling_pub.publish(ros_qos.falling_msg(falling))
            self.counts['trigger_messages'] += 1
        self._trigger = falling

    def _on_watchdog(self) -> None:
        if not self.active:
            return
        now = time.monotonic()
        silent_s = now - self._last_valid_wall
        if silent_s > self._stale_timeout_s and now - self._last_stale_wall > self._stale_timeout_s:
            self._last_stale_wall = now
            what = 'no features received' if self._timeline.last_ns is None else 'no features'
            self._stale_reason = f'{what} for {silent_s:.2f} s'
            self._publish_unusable(self._timeline.last_ns or 0, self._stale_reason, stale=True,
                                   logged_as=what)

    def _report(self) -> Report:
        monitor = self._monitor
        if monitor is None or not self.active:
            return (LEVEL_STALE, 'not configured (lifecycle)' if monitor is None
                    else 'inactive (lifecycle)', {'stamp_ns': self._timeline.last_ns})
        values = {'stamp_ns': self._timeline.last_ns, 'tau_his_s': monitor.tau_his_s,
                  'enabled': monitor.enabled, 'latched': monitor.latched,
                  'fallen': monitor.fallen, 'model': self._model_description,
                  'invalid_features': self._bad_inputs.count, 'last_error': self._bad_inputs.last,
                  **self._timeline.counters(), **self.counts}
        dropped = self._bad_inputs.new_since_last_call()
        missing = self._timeline.missing - self._missing_at_report
        self._missing_at_report = self._timeline.missing
        if self._stale_reason is not None:
            return LEVEL_STALE, self._stale_reason, values
        fault = self._faults.current()
        if fault:
            return LEVEL_WARN, fault, values
        if dropped or missing:
            return (LEVEL_WARN, f'{dropped} invalid features messages, {missing} samples '
                    'missing', values)
        if not self._monitor.enabled:
            return LEVEL_WARN, 'disabled: no fall trigger', values
        if self._monitor.fallen:
            return LEVEL_OK, 'the robot is down', values
        return LEVEL_OK, 'falling (latched)' if self._monitor.latched else 'balanced', values


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.predictor_node --ros-args ...``."""
    return run_node(PredictorNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
