"""The whole onboard monitor without ROS: a robot's sensor messages in, the monitor's states out.

:class:`OnboardChain` composes what ``fall_monitor --estimator`` runs, node by node and in the same
order: :class:`~fall_predictor.monitor.sensor_pipeline.SensorPipeline` (the state estimator node),
:class:`~fall_predictor.monitor.features.FeatureExtractor` (the feature node) and
:class:`~fall_predictor.monitor.fall_monitor.FallMonitor` (the predictor node), with a sample that
carries a fault turned into a DEGRADED state as the nodes do. Offline replays, experiments and
tests run a recording through it to get what the live monitor would have said (without the
sample-age check, which needs a live clock).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional, Union

from fall_predictor.monitor.fall_monitor import FallEvent, FallMonitor, MonitorState
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.lowstate import LowStateSample
from fall_predictor.monitor.plausibility import ImplausibleSample
from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.sensor_pipeline import Estimate, SensorPipeline
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading

Reading = Union[JointStateReading, ImuReading, WrenchReading, LowStateSample]


def base_tilt_rad(rotation) -> float:
    """Angle [rad] between the floating base's z axis and the vertical (0: upright)."""
    return math.acos(min(1.0, max(-1.0, float(rotation[2, 2]))))


@dataclass(frozen=True)
class ChainOutput:
    """The monitor's output for one estimate: its state, and the event it raised, if any."""

    stamp_ns: int
    state: MonitorState
    event: Optional[FallEvent] = None
    measurement: Optional[Measurement] = None   #: the estimate the state was made from


class OnboardChain:
    """Sensor readings in (:meth:`add`), one :class:`ChainOutput` per estimate out."""

    def __init__(self, pipeline: SensorPipeline, settings: FeatureSettings,
                 monitor: FallMonitor) -> None:
        self.pipeline = pipeline
        # The base's attitude after the features when the model reads it (method §8c).
        self.extractor = settings.extractor(attitude=monitor.predictor.lists.reads_attitude)
        self.monitor = monitor

    def add(self, stream: str, reading: Reading) -> list[ChainOutput]:
        """One sensor message: stream 'joints', 'imu', 'l' or 'r' (or 'lowstate': a Unitree
        LowState converted by :class:`~fall_predictor.monitor.lowstate.LowStateConverter`)."""
        return [self._decide(e) for e in self.pipeline.add(stream, reading)]

    def flush(self) -> list[ChainOutput]:
        return [self._decide(e) for e in self.pipeline.flush()]

    def _decide(self, e: Estimate) -> ChainOutput:
        if e.new_run:
            self.extractor.reset()
            self.monitor.new_run()
        if e.measurement is None:
            return ChainOutput(e.stamp_ns, self.monitor.unusable(e.fault))
        m = replace(e.measurement, t=e.t)
        try:
            x, mode = self.extractor.update(m)
        except (ValueError, ImplausibleSample) as error:
            return ChainOutput(e.stamp_ns, self.monitor.unusable(f'measurement refused: {error}'))
        state, event = self.monitor.step(e.t, x, mode, base_tilt_rad(m.torso_rotation))
        return ChainOutput(e.stamp_ns, state, event, e.measurement)
