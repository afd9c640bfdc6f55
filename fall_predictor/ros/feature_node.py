"""feature_node: measurements -> the 15 features and the contact mode (SPEC §6, §7).

The features are computed as the model was trained: the node reads the model file
(``model_path``) for its feature settings (rate window, edge tolerance, sample period) and
adopts them; a parameter set to another value stops the node at start with one clear error.

For every ``fall_predictor/measurement`` it runs
:class:`~fall_predictor.monitor.features.FeatureExtractor` and publishes ``fall_predictor/features``
(layout v1, stamped by the sample time in ``data[0]``).

Sample order (:class:`~fall_predictor.data.sample_order.SampleIntake`): duplicates and
out-of-order samples are dropped and counted, missing samples counted; ``~/reset``
(std_srvs/Trigger) starts a new run (clears the momentum history), and so does the restart
rule (several consecutive samples restarting near t = 0), never a single old stamp.

Bad input never stops the node: a measurement that breaks the wire contract or the
plausibility bounds, that the extractor rejects (a jump faster than physics allows), or whose
handling raises a numeric error (overflow, conversion) is logged (throttled), counted and
dropped. Health goes to ``/diagnostics``: OK; WARN when inputs were dropped or samples were
missing in the last period; STALE when no measurement arrived for ``stale_timeout_s`` of wall
time. The predictor node, not this one, owns ``fall_predictor/state``.
"""
from __future__ import annotations

import time
from typing import Optional

from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from fall_predictor.data.sample_order import Sample, SampleIntake
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.common import (HANDLED_ERRORS, MAX_MODEL_BYTES, MODEL_PATH,
                                       Diagnostics, InputErrors,
                                       ParamSpec, Report, create_publisher,
                                       declare_parameters, feature_setting_params, guarded,
                                       load_model_for, run_node)
from fall_predictor.ros.in_process import Output, connect_input
from fall_predictor.data.topics import FEATURES, MEASUREMENT
from fall_predictor.data.wire import LEVEL_OK, LEVEL_STALE, LEVEL_WARN

NODE_NAME = 'feature_node'

#: Feature settings this node uses, checked against the model's.
SETTINGS = ('rate_window_s', 'edge_tolerance_m', 'sample_period_s')
PARAMS = (
    MODEL_PATH, MAX_MODEL_BYTES,
    *feature_setting_params(SETTINGS),
    ParamSpec('stale_timeout_s', 0.5, 'wall time [s] without a measurement after which '
              '/diagnostics reports STALE', 0.01, 60.0),
)


class FeatureNode(Node):
    """Wraps :class:`~fall_predictor.monitor.features.FeatureExtractor`; see the module docs."""

    def __init__(self, upstream: Optional[Output] = None, **kwargs: object) -> None:
        """``upstream``: take the measurements from this output of a node of the same process
        (``fall_monitor --estimator``) instead of subscribing; ``kwargs`` go to ``Node``."""
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMS)
        _, _, settings = load_model_for(self, str(p['model_path']), {k: p[k] for k in SETTINGS},
                                        int(p['max_model_bytes']))
        self._extractor = settings.extractor()
        self._stale_timeout_s = float(p['stale_timeout_s'])
        self.add_post_set_parameters_callback(self._apply_parameters)

        #: The features, published and handed to in-process consumers (``fall_monitor``).
        self.output = Output(create_publisher(self, Float64MultiArray, FEATURES))
        inputs = connect_input(self, Float64MultiArray, MEASUREMENT, self._on_measurement, upstream)
        self._intake = SampleIntake(settings.sample_period_s)
        self._bad_inputs = InputErrors(self)
        #: Counters by event name (reported in /diagnostics).
        self.counts = {'measurements': 0, 'features': 0, 'resets': 0}
        self._missing_at_report = 0
        self._last_input_wall: Optional[float] = None
        self.create_service(Trigger, '~/reset', self._on_reset)
        self._diagnostics = Diagnostics(self, self._report, lambda: self._intake.last_t or 0.0,
                                        inputs, self._bad_inputs)
        self.get_logger().info('feature extractor ready')

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'stale_timeout_s':
                self._stale_timeout_s = float(parameter.value)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        self._intake.reset()
        self._extractor.reset()
        self.counts['resets'] += 1
        response.success, response.message = True, 'feature history cleared; next sample starts a run'
        return response

    @guarded('measurement')
    def _on_measurement(self, msg: Float64MultiArray) -> None:
        self.counts['measurements'] += 1
        self._last_input_wall = time.monotonic()
        m = ros_qos.measurement_from_msg(msg)
        kind = self._intake.classify(m.t)
        if kind is Sample.NEW_RUN:
            self._extractor.reset()
        elif kind is not Sample.NEXT:
            return                          # duplicate, out of order: counted by the intake
        try:
            x, mode = self._extractor.update(m)
            features = ros_qos.features_to_msg(m.t, x, mode)
        except HANDLED_ERRORS as error:
            self._bad_inputs.reject(f'measurement at t = {m.t} s', error)
            return
        self.output.publish(features)
        self.counts['features'] += 1

    def _report(self) -> Report:
        values = {'t_s': self._intake.last_t, 'invalid_measurements': self._bad_inputs.count,
                  'last_error': self._bad_inputs.last, **self._intake.counters(), **self.counts}
        dropped = self._bad_inputs.new_since_last_call()
        missing = self._intake.missing - self._missing_at_report
        self._missing_at_report = self._intake.missing
        if self._last_input_wall is None:
            return LEVEL_STALE, 'no measurement received yet', values
        silent_s = time.monotonic() - self._last_input_wall
        if silent_s > self._stale_timeout_s:
            return LEVEL_STALE, f'no measurement for {silent_s:.1f} s', values
        if dropped or missing:
            return (LEVEL_WARN, f'{dropped} invalid measurements dropped, {missing} samples '
                    'missing', values)
        return LEVEL_OK, 'running', values


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.feature_node --ros-args ...``."""
    return run_node(FeatureNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
