"""feature_node: measurements -> the 15 features, the contact mode and the base tilt (method §6, §7).

The features are computed as the model was trained: the node reads the model file
(``model_path``) for its feature settings (rate window, edge tolerance) and adopts them; a
parameter set to another value stops the node at start with one clear error. Rate windows are in
seconds, so a model runs at any measurement rate whose period is not longer than its rate window;
at a slower rate every features message says why (a DEGRADED state), once the rate is known.

For every ``fall_predictor/measurement`` (``fall_predictor/msg/Measurement``) whose stamp the time
rule accepts (:mod:`fall_predictor.monitor.timeline`: duplicates, out-of-order samples and stray
stamps are dropped and counted; a confirmed clock step, back or forward (in ``fall_monitor
--estimator`` the estimator's, handed over with its measurement), or the monitor's RESET event on
``fall_predictor/fall_event`` starts a new run, clearing the momentum history) it publishes
``fall_predictor/features`` (``fall_predictor/msg/Features``) with the measurement's own stamp
(in ``fall_monitor``, handed to the predictor node in process and published only while another
process subscribes, see ``ros/in_process.py``):
the features of :class:`~fall_predictor.monitor.features.FeatureExtractor`, or the fault that
prevented them (the measurement's own, or why the extractor refused it, e.g. a jump faster than
physics allows), so that every accepted sample gets a state downstream.

Bad input never stops the node: a message that breaks the contract or the plausibility bounds is
logged (throttled), counted and dropped. Health goes to ``/diagnostics``: OK; WARN when inputs were
dropped or samples missing in the last period; STALE when no measurement arrived for
``stale_timeout_s`` of wall time. The predictor node, not this one, owns ``fall_predictor/state``.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from functools import partial
from typing import Optional

import numpy as np
from rclpy.parameter import Parameter

from fall_predictor.contract import messages
from fall_predictor.contract.topics import FALL_EVENT, FEATURES, MEASUREMENT
from fall_predictor.contract.wire import LEVEL_OK, LEVEL_STALE, LEVEL_WARN
from fall_predictor.monitor.chain import base_tilt_rad
from fall_predictor.monitor.fall_monitor import EVENT_RESET
from fall_predictor.monitor.features import FeatureExtractor, FeatureSettings
from fall_predictor.monitor.timeline import Stamp, StampTimeline
from fall_predictor.msg import FallEvent, Features, Measurement
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import (HANDLED_ERRORS, Diagnostics, FaultLog, InputErrors, Report,
                                       guarded)
from fall_predictor.ros.in_process import Output, connect_input
from fall_predictor.ros.lifecycle import AUTOSTART, MonitorLifecycleNode
from fall_predictor.ros.parameters import (MAX_MODEL_BYTES, MODEL_PATH, ParamSpec,
                                           declare_parameters, feature_setting_params,
                                           load_model_for)
from fall_predictor.ros.runner import run_node
from fall_predictor.ros.robots import ROBOT_PARAM

NODE_NAME = 'feature_node'

#: Feature settings this node uses, checked against the model's.
SETTINGS = ('rate_window_s', 'edge_tolerance_m', 'sample_period_s')
PARAMS = (
    AUTOSTART, ROBOT_PARAM, MODEL_PATH, MAX_MODEL_BYTES,
    *feature_setting_params(SETTINGS),
    ParamSpec('stale_timeout_s', 0.5, 'wall time [s] without a measurement after which '
              '/diagnostics reports STALE', 0.01, 60.0),
)
#: Samples whose period is averaged before the rate is judged against the model.
_RATE_SAMPLES = 20


class FeatureNode(MonitorLifecycleNode):
    """Wraps :class:`~fall_predictor.monitor.features.FeatureExtractor`; see the module docs
    (a managed node: configure loads the model's feature settings, see ``ros/lifecycle.py``)."""

    def __init__(self, upstream: Optional[Output] = None, **kwargs: object) -> None:
        """``upstream``: take the measurements from this output of a node of the same process
        (``fall_monitor --estimator``) instead of subscribing; ``kwargs`` go to ``Node``."""
        super().__init__(NODE_NAME, **kwargs)
        p = self._params = declare_parameters(self, PARAMS)
        self._settings: Optional[FeatureSettings] = None
        self._extractor: Optional[FeatureExtractor] = None
        self._stale_timeout_s = float(p['stale_timeout_s'])
        self.add_post_set_parameters_callback(self._apply_parameters)

        #: The features, published and handed to in-process consumers (``fall_monitor``).
        self.output = Output(create_publisher(self, Features, FEATURES))
        inputs = connect_input(self, Measurement, MEASUREMENT, self._on_measurement, upstream,
                               take=self._take_measurement)
        create_subscription(self, FallEvent, FALL_EVENT, self._on_fall_event)
        self._timeline = StampTimeline()
        self._bad_inputs = InputErrors(self)
        self._faults = FaultLog(self)
        self._rate_problem: Optional[str] = None
        self._accepted = 0
        #: Counters by event name (reported in /diagnostics).
        self.counts = {'measurements': 0, 'features': 0, 'faults': 0, 'resets': 0}
        self._missing_at_report = 0
        self._last_input_wall: Optional[float] = None
        self._diagnostics = Diagnostics(self, self._report, lambda: self._timeline.last_ns or 0,
                                        inputs, self._bad_inputs)
        self.start(bool(p['autostart']))

    def _configure(self) -> None:
        p = self._params
        _, _, self._settings = load_model_for(self, str(p['model_path']), {k: p[k] for k in SETTINGS},
                                              int(p['max_model_bytes']), str(p['robot']))
        # Always with the base's attitude: the message carries it for a model that reads it (§8c).
        self._extractor = self._settings.extractor(attitude=True)
        self._timeline.reset()
        self._rate_problem = None
        self._accepted = 0
        self.get_logger().info('feature extractor ready')

    def _cleanup(self) -> None:
        self._settings = self._extractor = None

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'stale_timeout_s':
                self._stale_timeout_s = float(parameter.value)

    @guarded('fall event')
    def _on_fall_event(self, msg: FallEvent) -> None:
        if msg.event == EVENT_RESET and self._extractor is not None:
            self._timeline.reset()
            self._extractor.reset()
            self.counts['resets'] += 1

    @guarded('measurement')
    def _on_measurement(self, msg: Measurement) -> None:
        if self._received():
            self._process(messages.measurement_from_msg(msg))

    @guarded('measurement')
    def _take_measurement(self, decoded: messages.StampedMeasurement) -> None:
        """A measurement handed over in process (``fall_monitor --estimator``): already checked
        where it was made (the state estimator turns an implausible estimate into a fault,
        :class:`~fall_predictor.monitor.sensor_pipeline.SensorPipeline`), then the same path."""
        if self._received():
            self._process(decoded)

    def _received(self) -> bool:
        """Count a measurement; whether the node is active to process it."""
        if not self.active:
            return False
        self.counts['measurements'] += 1
        self._last_input_wall = time.monotonic()
        return True

    def _process(self, decoded: messages.StampedMeasurement) -> None:
        if decoded.new_run:                 # confirmed by the estimator of this process
            self._timeline.restart(decoded.stamp_ns)
            kind = Stamp.NEW_RUN
        else:
            kind = self._timeline.classify(decoded.stamp_ns)
        if not kind.accepted:
            return                          # duplicate, out of order, stray: counted
        new_run = kind is Stamp.NEW_RUN
        if new_run:
            self._extractor.reset()
        self._check_rate()
        own = self._rate_problem or ''      # this node's own fault, logged here (not the input's)
        x, mode, tilt = None, None, 0.0
        if not (decoded.fault or own):
            m = replace(decoded.measurement, t=self._timeline.run_time(decoded.stamp_ns))
            try:
                x, mode = self._extractor.update(m)
                tilt = base_tilt_rad(m.torso_rotation)
            except HANDLED_ERRORS as error:
                own = f'measurement refused: {error}'
        self._faults.update(own)
        fault = decoded.fault or own
        stamp_ns = decoded.stamp_ns
        if fault:
            features = messages.StampedFeatures(stamp_ns, fault, None, None, math.nan, new_run)
        else:
            features = messages.StampedFeatures(stamp_ns, '', np.asarray(x, dtype=float), mode, tilt,
                                                new_run)
        self.output.hand_off(features, partial(messages.features_msg, ros_qos.TYPES, stamp_ns,
                                               features.x, features.mode, tilt, fault))
        self.counts['faults' if fault else 'features'] += 1

    def _check_rate(self) -> None:
        """Once the measurement rate is known: can the model's rate window run at it?"""
        self._accepted += 1
        if self._accepted != _RATE_SAMPLES or self._timeline.period_s is None:
            return
        period_s = self._timeline.period_s
        window_s = self._settings.rate_window_s
        if period_s > window_s * 1.25:
            self._rate_problem = (
                f'measurements come every {period_s * 1e3:.1f} ms ({1 / period_s:.0f} Hz): the '
                f"model's {window_s * 1e3:.0f} ms momentum-rate window cannot be kept at this "
                'rate (retrain with rate_window_s >= the sample period)')
            self.get_logger().error(self._rate_problem)

    def _report(self) -> Report:
        values = {'stamp_ns': self._timeline.last_ns, 'invalid_measurements': self._bad_inputs.count,
                  'last_error': self._bad_inputs.last, 'period_s': self._timeline.period_s,
                  **self._timeline.counters(), **self.counts}
        dropped = self._bad_inputs.new_since_last_call()
        missing = self._timeline.missing - self._missing_at_report
        self._missing_at_report = self._timeline.missing
        if not self.active:
            return LEVEL_STALE, 'inactive (lifecycle)', values
        if self._last_input_wall is None:
            return LEVEL_STALE, 'no measurement received yet', values
        silent_s = time.monotonic() - self._last_input_wall
        if silent_s > self._stale_timeout_s:
            return LEVEL_STALE, f'no measurement for {silent_s:.1f} s', values
        if self._rate_problem:
            return LEVEL_WARN, self._rate_problem, values
        if dropped or missing:
            return (LEVEL_WARN, f'{dropped} invalid measurements dropped, {missing} samples '
                    'missing', values)
        return LEVEL_OK, 'running', values


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.feature_node --ros-args ...``."""
    return run_node(FeatureNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
