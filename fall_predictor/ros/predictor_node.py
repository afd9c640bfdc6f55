"""predictor_node: features -> the fall prediction, the trigger and the fall direction.

Loads a decision-list model (:func:`~fall_predictor.monitor.model_file.load_model`) and runs
:class:`~fall_predictor.monitor.predictor.OnlinePredictor` on every ``fall_predictor/features``
sample. Outputs (the contract is in :mod:`fall_predictor.data.topics` and the README):

* ``fall_predictor/state`` (``std_msgs/Float64MultiArray``, layout ``fall_predictor/state/v2``):
  one per sample, stamped with the sample's time in slot 0; slots are read by index (status,
  falling, latch, contact mode, window, time to fall, direction), no strings to parse.
* ``fall_predictor/falling`` (``std_msgs/Bool``, reliable, transient local, depth 1): the
  trigger. ``false`` at start-up; ``true`` from the first falling prediction until ``~/reset``
  (or until the monitor is disabled). A node that starts late still gets the current value.
* ``fall_predictor/fall_direction`` (``geometry_msgs/Vector3Stamped``, frame
  ``base_footprint``, latched): with each falling event, the predicted direction of the fall
  (the horizontal linear momentum's direction, :mod:`fall_predictor.monitor.fall_direction`:
  10 deg median error against 34 for the capture point at development scale).

Services: ``~/reset`` (std_srvs/Trigger) clears the history, the latch and the trigger;
``~/enable`` (std_srvs/SetBool) switches the trigger off (false: no trigger, the states say
``disabled``; the history restarts when enabled again).

Inputs are ordered by :class:`~fall_predictor.data.sample_order.SampleIntake` (duplicates and
out-of-order samples dropped and counted; a new run by ``~/reset`` or the restart rule, which
clears the history but never the latch). A sample older than ``max_sample_age_s`` when it
arrives (:class:`~fall_predictor.ros.common.SampleAge`) is counted and answered with a stale
state instead of a prediction. A features message that breaks the wire contract gets a stale
state too; a wall-clock watchdog publishes a stale state whenever no valid features arrived for
``stale_timeout_s`` (repeated every ``stale_timeout_s``). Stale states keep the latch. Health,
counters and reasons go to ``/diagnostics``.

Parameters: ``model_path`` (default: the shipped model), ``tau_his_s`` (settable at run time;
default: the model's recommended window), ``stale_timeout_s``, ``max_sample_age_s``,
``robot_mass_kg`` (for the fall direction; default: the model's). With each falling state the
time left until fallen comes from the model's regressor when the model has one (NaN otherwise). A missing or invalid model file makes the node
refuse to start with one FATAL line (exit code 1).
"""
from __future__ import annotations

import math
import time
from typing import Optional

from geometry_msgs.msg import Vector3Stamped
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Bool, Float64MultiArray
from std_srvs.srv import SetBool, Trigger

from fall_predictor.data.sample_order import Sample, SampleIntake
from fall_predictor.data.topics import FALL_DIRECTION, FALLING, FEATURES, STATE
from fall_predictor.data.wire import LEVEL_OK, LEVEL_STALE, LEVEL_WARN, FeatureSample, PredictorState
from fall_predictor.monitor.fall_direction import momentum_direction
from fall_predictor.monitor.predictor import OnlinePredictor
from fall_predictor.robot.model import TOTAL_MASS_KG
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.common import (MAX_MODEL_BYTES, MAX_SAMPLE_AGE, MODEL_PATH,
                                       Diagnostics, InputErrors,
                                       ParamSpec, Report, SampleAge,
                                       create_publisher, declare_parameters,
                                       feature_setting_params, guarded, load_model_for, run_node,
                                       steady_clock)
from fall_predictor.ros.in_process import Output, connect_input

NODE_NAME = 'predictor_node'
#: Largest accepted history window [s]: beyond the longest oracle lead a window only hides falls.
MAX_TAU_HIS_S = 2.0
#: Period of the wall-clock staleness check [s].
_WATCHDOG_PERIOD_S = 0.05

STALE_TIMEOUT = ParamSpec(
    'stale_timeout_s', 0.5, 'wall time [s] without valid features after which a degraded '
    'STALE state is published (and repeated every stale_timeout_s)', 0.01, 60.0)
def robot_mass_param(default_kg: float) -> ParamSpec:
    """The robot mass parameter, defaulting to the model's (else the simulated robot's)."""
    return ParamSpec('robot_mass_kg', default_kg, 'total robot mass [kg]: turns the momentum '
                     'feature into a CoM velocity for the fall direction; default: the model\'s',
                     1.0, 1000.0, read_only=True)
#: Feature settings this node uses, checked against the model's.
SETTINGS = ('sample_period_s', 'guard_com_height_m')


def tau_his_param(default_s: float) -> ParamSpec:
    """The run-time history window parameter with the model's default."""
    return ParamSpec('tau_his_s', default_s, 'history window [s]: falling only when every atomic '
                     'prediction of the last tau_his_s was falling (SPEC §8); settable at run '
                     'time', 0.0, MAX_TAU_HIS_S)


class PredictorNode(Node):
    """Wraps :class:`~fall_predictor.monitor.predictor.OnlinePredictor`; see the module docs."""

    def __init__(self, upstream: Optional[Output] = None, **kwargs: object) -> None:
        """``upstream``: take the features from this output of a node of the same process
        (``fall_monitor``) instead of subscribing; ``kwargs`` go to ``Node``."""
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, (MODEL_PATH, MAX_MODEL_BYTES, STALE_TIMEOUT, MAX_SAMPLE_AGE,
                                      *feature_setting_params(SETTINGS)))
        lists, metadata, settings = load_model_for(self, str(p['model_path']),
                                                   {k: p[k] for k in SETTINGS},
                                                   int(p['max_model_bytes']))
        # Declared once the model is known: its recommended window is the default.
        recommended_s = min(metadata.recommended_tau_his_s or 0.0, MAX_TAU_HIS_S)
        model_mass_kg = getattr(metadata, 'robot_mass_kg', None) or float(TOTAL_MASS_KG)
        q = declare_parameters(self, (tau_his_param(recommended_s), robot_mass_param(model_mass_kg)))
        tau_his_s = float(q['tau_his_s'])
        self._stale_timeout_s = float(p['stale_timeout_s'])
        self._max_sample_age_s = float(p['max_sample_age_s'])
        self._mass_kg = float(q['robot_mass_kg'])
        #: Time left until fallen, from the model when it has a regressor (None otherwise).
        self._time_to_fall = getattr(metadata, 'time_to_fall', None)
        self._predictor = OnlinePredictor(lists, tau_his_s, settings.sample_period_s,
                                          settings.guard_com_height_m)
        self.add_post_set_parameters_callback(self._apply_parameters)

        self._state_pub = create_publisher(self, Float64MultiArray, STATE)
        self._falling_pub = create_publisher(self, Bool, FALLING)
        self._direction_pub = create_publisher(self, Vector3Stamped, FALL_DIRECTION)
        inputs = connect_input(self, Float64MultiArray, FEATURES, self._on_features, upstream)
        self._intake = SampleIntake(settings.sample_period_s)
        self._age = SampleAge(self)
        self._bad_inputs = InputErrors(self)
        self._enabled = True
        self._trigger = False               # value last published on fall_predictor/falling
        #: Counters by event name (reported in /diagnostics).
        self.counts = {'features': 0, 'states': 0, 'falling_states': 0, 'stale_states': 0,
                       'stale_samples': 0, 'falling_events': 0, 'resets': 0,
                       'trigger_messages': 0, 'direction_messages': 0}
        self._missing_at_report = 0
        self._last_valid_wall = time.monotonic()
        self._last_stale_wall = -math.inf
        self._stale_reason: Optional[str] = None
        self._publish_trigger(False)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(SetBool, '~/enable', self._on_enable)
        self.create_timer(_WATCHDOG_PERIOD_S, self._on_watchdog, clock=steady_clock())
        self._diagnostics = Diagnostics(self, self._report, lambda: self._intake.last_t or 0.0,
                                        inputs, self._bad_inputs)
        self._model_description = (f'{p["model_path"] or "the shipped model"} (mean rule size '
                                   f'{lists.mean_rule_size:.1f}, tau_plus {metadata.tau_plus_s} s)')
        self.get_logger().info(f'predictor ready: model {self._model_description}, '
                               f'tau_his_s={tau_his_s}')

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'tau_his_s':
                self._predictor.tau_his_s = float(parameter.value)
                self.get_logger().info(f'tau_his_s = {parameter.value} s')
            elif parameter.name == 'stale_timeout_s':
                self._stale_timeout_s = float(parameter.value)
            elif parameter.name == 'max_sample_age_s':
                self._max_sample_age_s = float(parameter.value)

    # -- services --------------------------------------------------------------------------
    def _clear(self) -> None:
        self._predictor.reset()
        self._intake.reset()
        self._age.reset()
        self._publish_trigger(False)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        self._clear()
        self.counts['resets'] += 1
        self.get_logger().info('reset: history, latch and trigger cleared')
        response.success, response.message = True, 'history, latch and trigger cleared'
        return response

    def _on_enable(self, request: SetBool.Request, response: SetBool.Response
                   ) -> SetBool.Response:
        if bool(request.data) != self._enabled:
            self._enabled = bool(request.data)
            self._predictor.reset()         # a fresh window either way; no trigger while off
            if not self._enabled:
                self._publish_trigger(False)
            self.get_logger().info(f'fall trigger {"enabled" if self._enabled else "disabled"}')
        response.success = True
        response.message = 'enabled' if self._enabled else 'disabled: no trigger'
        return response

    # -- samples ---------------------------------------------------------------------------
    @guarded('features')
    def _on_features(self, msg: Float64MultiArray) -> None:
        self.counts['features'] += 1
        try:
            sample = ros_qos.features_from_msg(msg)
        except ValueError as error:
            self._bad_inputs.reject('features', error)
            self._publish_degraded(f'invalid features: {error}')
            return
        kind = self._intake.classify(sample.t)
        if kind is Sample.NEW_RUN:
            self._predictor.reset()         # the window restarts; the latch is kept (one-way)
            self._age.reset()
        elif kind is not Sample.NEXT:
            return                          # duplicate, out of order: counted by the intake
        self._last_valid_wall = time.monotonic()
        self._stale_reason = None
        age_s = self._age.age_s(sample.t)
        if self._max_sample_age_s > 0.0 and age_s > self._max_sample_age_s:
            self.counts['stale_samples'] += 1
            self._publish_degraded(f'sample at t = {sample.t:.3f} s arrived {age_s:.3f} s late',
                                   sample.t)
            return
        if not self._enabled:
            self._publish(PredictorState(t=sample.t, falling=False, atomic=False, guard=False,
                                         latched=False, contact_mode=sample.mode,
                                         tau_his_s=self._predictor.tau_his_s, enabled=False))
            return
        self._predict(sample)

    def _predict(self, sample: FeatureSample) -> None:
        was_latched = self._predictor.latched or self._trigger
        out = self._predictor.step(sample.t, sample.x, sample.mode)
        direction = (math.nan, math.nan)
        time_to_fall_s = math.nan
        if out.falling:
            self.counts['falling_states'] += 1
            d = momentum_direction(sample.x, self._mass_kg)
            direction = (float(d[0]), float(d[1]))
            if self._time_to_fall is not None:
                time_to_fall_s = min(max(float(self._time_to_fall.predict_one(
                    sample.x.tolist(), sample.mode)), 0.0), 1e3)
            if not was_latched:
                self.counts['falling_events'] += 1
                if math.isfinite(direction[0]):
                    self._direction_pub.publish(ros_qos.fall_direction_msg(sample.t, direction))
                    self.counts['direction_messages'] += 1
                self._publish_trigger(True)
                self.get_logger().info(f'falling at t = {sample.t:.3f} s, direction '
                                       f'({direction[0]:.2f}, {direction[1]:.2f})')
        self._publish(PredictorState(t=out.t, falling=out.falling, atomic=out.atomic,
                                     guard=out.guard, latched=out.latched or self._trigger,
                                     contact_mode=sample.mode,
                                     tau_his_s=self._predictor.tau_his_s,
                                     time_to_fall_s=time_to_fall_s, fall_direction=direction))

    def _publish_trigger(self, falling: bool) -> None:
        if falling != self._trigger or falling is False:
            self._falling_pub.publish(ros_qos.falling_msg(falling))
            self.counts['trigger_messages'] += 1
        self._trigger = falling

    def _publish(self, state: PredictorState) -> None:
        self._state_pub.publish(ros_qos.state_to_msg(state))
        self.counts['states'] += 1

    def _publish_degraded(self, reason: str, t: Optional[float] = None) -> None:
        """A STALE state (at ``t``, else the latest valid sample time), keeping the latch."""
        self._publish(PredictorState(t=self._intake.last_t or 0.0 if t is None else t,
                                     falling=False, atomic=False, guard=False,
                                     latched=self._predictor.latched or self._trigger,
                                     contact_mode=None, tau_his_s=self._predictor.tau_his_s,
                                     stale_reason=reason, enabled=self._enabled))
        self.counts['stale_states'] += 1

    def _on_watchdog(self) -> None:
        now = time.monotonic()
        silent_s = now - self._last_valid_wall
        if silent_s > self._stale_timeout_s and now - self._last_stale_wall > self._stale_timeout_s:
            self._last_stale_wall = now
            what = 'no features received' if self._intake.last_t is None else 'no valid features'
            self._stale_reason = f'{what} for {silent_s:.2f} s'
            self._publish_degraded(self._stale_reason)

    def _report(self) -> Report:
        values = {'t_s': self._intake.last_t, 'tau_his_s': self._predictor.tau_his_s,
                  'enabled': self._enabled, 'latched': self._predictor.latched or self._trigger,
                  'model': self._model_description, 'invalid_features': self._bad_inputs.count,
                  'last_error': self._bad_inputs.last, **self._intake.counters(), **self.counts}
        dropped = self._bad_inputs.new_since_last_call()
        missing = self._intake.missing - self._missing_at_report
        self._missing_at_report = self._intake.missing
        if self._stale_reason is not None:
            return LEVEL_STALE, self._stale_reason, values
        if dropped or missing:
            return (LEVEL_WARN, f'{dropped} invalid features messages, {missing} samples '
                    'missing', values)
        if not self._enabled:
            return LEVEL_WARN, 'disabled: no fall trigger', values
        return LEVEL_OK, 'falling (latched)' if values['latched'] else 'balanced', values


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.predictor_node --ros-args ...``."""
    return run_node(PredictorNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
