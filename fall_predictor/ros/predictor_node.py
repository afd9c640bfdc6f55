"""predictor_node: features -> the fall prediction on ``/fall_predictor/state`` (SPEC §5, §8).

Loads a decision-list model (:func:`~fall_predictor.monitor.model_file.load_model`) and runs
:class:`~fall_predictor.monitor.predictor.OnlinePredictor` on every ``/fall_predictor/features``
sample, publishing one state per sample (``ros_qos.state_to_msg``), stamped with the sample's
time: OK balanced, WARN falling, with the contact mode, the atomic and guard outputs, the
latch and the history window in use.

Parameters: ``model_path`` (default: ``models/default_model.json`` of the installed package
share directory, else of the source tree); ``tau_his_s``, the history window, settable at run
time (default: the model's recommended window, else 0); ``stale_timeout_s``.

A missing or invalid model file makes the node refuse to start: one FATAL log line naming the
file and the problem, exit code 1.

Degraded states (level STALE, ``stale: <reason>``): a features message that breaks the wire
contract gets a degraded state instead of a prediction; and a wall-clock watchdog publishes a
degraded state whenever no valid features arrived for ``stale_timeout_s`` (at start-up, when
the simulator stops, when the feature node dies), repeated every ``stale_timeout_s`` while it
lasts. ``/diagnostics`` reports the same. A new run (sample time going backwards, or a new
t = 0 sample) resets the predictor's history and latch.
"""
from __future__ import annotations

import time
from typing import Optional

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64MultiArray

from fall_predictor.data.topics import FEATURES, STATE
from fall_predictor.data.wire import LEVEL_OK, LEVEL_STALE, LEVEL_WARN, PredictorState
from fall_predictor.monitor.predictor import OnlinePredictor
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.common import (MODEL_PATH, Diagnostics, InputErrors, ParamSpec, Report,
                                       RunTracker, Sample, create_publisher, create_subscription,
                                       declare_parameters, feature_setting_params, load_model_for,
                                       run_node, steady_clock)

NODE_NAME = 'predictor_node'
#: Largest accepted history window [s]: beyond the longest oracle lead a window only hides falls.
MAX_TAU_HIS_S = 2.0
#: Period of the wall-clock staleness check [s].
_WATCHDOG_PERIOD_S = 0.05

STALE_TIMEOUT = ParamSpec(
    'stale_timeout_s', 0.5, 'wall time [s] without valid features after which a degraded '
    'STALE state is published (and repeated every stale_timeout_s)', 0.01, 60.0)
#: Feature settings this node uses, checked against the model's.
SETTINGS = ('sample_period_s', 'guard_com_height_m')


def tau_his_param(default_s: float) -> ParamSpec:
    """The run-time history window parameter with the model's default."""
    return ParamSpec('tau_his_s', default_s, 'history window [s]: falling only when every atomic '
                     'prediction of the last tau_his_s was falling (SPEC §8); settable at run '
                     'time', 0.0, MAX_TAU_HIS_S)


class PredictorNode(Node):
    """Wraps :class:`~fall_predictor.monitor.predictor.OnlinePredictor`; see the module docs."""

    def __init__(self, **kwargs: object) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, (MODEL_PATH, STALE_TIMEOUT, *feature_setting_params(SETTINGS)))
        lists, metadata, settings = load_model_for(self, str(p['model_path']),
                                                   {k: p[k] for k in SETTINGS})
        # Declared once the model is known: its recommended window is the default.
        recommended_s = min(metadata.recommended_tau_his_s or 0.0, MAX_TAU_HIS_S)
        tau_his_s = float(declare_parameters(self, (tau_his_param(recommended_s),))['tau_his_s'])
        self._stale_timeout_s = float(p['stale_timeout_s'])
        self._predictor = OnlinePredictor(lists, tau_his_s, settings.sample_period_s,
                                          settings.guard_com_height_m)
        self.add_post_set_parameters_callback(self._apply_parameters)

        self._state_pub = create_publisher(self, DiagnosticArray, STATE)
        inputs = [create_subscription(self, Float64MultiArray, FEATURES, self._on_features)]
        self._runs = RunTracker()
        self._bad_inputs = InputErrors(self)
        #: Counters by event name (reported in /diagnostics).
        self.counts = {'features': 0, 'states': 0, 'falling_states': 0, 'stale_states': 0,
                       'duplicates': 0, 'runs': 0}
        self._last_valid_wall = time.monotonic()
        self._last_stale_wall = -float('inf')
        self._stale_reason: Optional[str] = None
        self.create_timer(_WATCHDOG_PERIOD_S, self._on_watchdog, clock=steady_clock())
        self._diagnostics = Diagnostics(self, self._report, lambda: self._runs.last_t or 0.0,
                                        inputs)
        self._model_description = (f'{p["model_path"] or "the shipped model"} (mean rule size {lists.mean_rule_size:.1f}, '
                                   f'tau_plus {metadata.tau_plus_s} s)')
        self.get_logger().info(f'predictor ready: model {self._model_description}, '
                               f'tau_his_s={tau_his_s}')

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'tau_his_s':
                self._predictor.tau_his_s = float(parameter.value)
                self.get_logger().info(f'tau_his_s = {parameter.value} s')
            elif parameter.name == 'stale_timeout_s':
                self._stale_timeout_s = float(parameter.value)

    # -- samples ---------------------------------------------------------------------------
    def _on_features(self, msg: Float64MultiArray) -> None:
        self.counts['features'] += 1
        try:
            sample = ros_qos.features_from_msg(msg)
        except ValueError as error:
            self._bad_inputs.reject('features', error)
            self._publish_degraded(f'invalid features: {error}')
            return
        kind = self._runs.classify(sample.t)
        if kind is Sample.REPEAT:
            self.counts['duplicates'] += 1
            return
        if kind is Sample.NEW_RUN:
            self.counts['runs'] += 1
            self._predictor.reset()
        out = self._predictor.step(sample.t, sample.x, sample.mode)
        self._last_valid_wall = time.monotonic()
        self._stale_reason = None
        self._publish(PredictorState(t=out.t, falling=out.falling, atomic=out.atomic,
                                     guard=out.guard, latched=out.latched,
                                     contact_mode=sample.mode,
                                     tau_his_s=self._predictor.tau_his_s))
        if out.falling:
            self.counts['falling_states'] += 1

    def _publish(self, state: PredictorState) -> None:
        self._state_pub.publish(ros_qos.state_to_msg(state))
        self.counts['states'] += 1

    def _publish_degraded(self, reason: str) -> None:
        """A STALE state at the latest valid sample time, keeping the latch."""
        self._publish(PredictorState(t=self._runs.last_t or 0.0, falling=False, atomic=False,
                                     guard=False, latched=self._predictor.latched,
                                     contact_mode=None, tau_his_s=self._predictor.tau_his_s,
                                     stale_reason=reason))
        self.counts['stale_states'] += 1

    def _on_watchdog(self) -> None:
        now = time.monotonic()
        silent_s = now - self._last_valid_wall
        if silent_s > self._stale_timeout_s and now - self._last_stale_wall > self._stale_timeout_s:
            self._last_stale_wall = now
            what = 'no features received' if self._runs.last_t is None else 'no valid features'
            self._stale_reason = f'{what} for {silent_s:.2f} s'
            self._publish_degraded(self._stale_reason)

    def _report(self) -> Report:
        values = {'t_s': self._runs.last_t, 'tau_his_s': self._predictor.tau_his_s,
                  'latched': self._predictor.latched, 'model': self._model_description,
                  'invalid_features': self._bad_inputs.count, 'last_error': self._bad_inputs.last,
                  **self.counts}
        dropped = self._bad_inputs.new_since_last_call()
        if self._stale_reason is not None:
            return LEVEL_STALE, self._stale_reason, values
        if dropped:
            return LEVEL_WARN, f'{dropped} invalid features messages', values
        return LEVEL_OK, 'falling (latched)' if self._predictor.latched else 'balanced', values


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.predictor_node --ros-args ...``."""
    return run_node(PredictorNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
