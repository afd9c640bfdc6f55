"""The state estimator's whole input path without ROS: sensor messages in, measurements out.

:class:`SensorPipeline` is what ``state_estimator_node`` runs and what the offline tools run over a
recording's messages (in the order they were received), so that both give the same estimates:

1. each joint state, IMU and foot wrench reading goes into :class:`~fall_predictor.monitor.
   sensor_sync.SensorSync`;
2. each message of the **driving** stream (``'joints'``: ``/joint_states``, the default; or
   ``'imu'``) is one estimate: its stamp goes through the time rule
   (:class:`~fall_predictor.monitor.timeline.StampTimeline`); a dropped stamp (duplicate, out of
   order, a stray) gets nothing and is counted. An accepted stamp waits until every stream has a
   reading at or after it (the IMU stamped a fraction of a millisecond after the encoders arrives
   after them), or until the next driving message, whichever comes first; then it gets the
   synchronised sample at that stamp (readings interpolated where they bracket it) and the state
   estimator's measurement, or the fault that prevented it (in words); a measurement outside the
   physical bounds (:func:`~fall_predictor.monitor.plausibility.check_measurement`) is such a
   fault. Joint states split over several messages (legs and arms from different controllers)
   drive only when they carry a joint of ``driving_joints`` (default: any joint of the
   description), and only once per stamp: the rest are taken as the joints' newest values.

A confirmed clock jump starts a new run: the estimator and the IMU/wrench buffers are reset.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from fall_predictor.monitor.estimator import EstimatorConfig, StateEstimator
from fall_predictor.monitor.plausibility import ImplausibleSample, check_measurement
from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.robot_description import SIDES, RobotDescription
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, WrenchReading
from fall_predictor.monitor.sensor_sync import SensorSync, SyncConfig
from fall_predictor.monitor.timeline import Stamp, StampTimeline, TimelineConfig

DRIVING_STREAMS = ('joints', 'imu')


@dataclass(frozen=True)
class Estimate:
    """The outcome of one accepted driving stamp: a measurement, or the fault that prevented it."""

    stamp_ns: int                       #: the driving message's own stamp (ROS time)
    t: float                            #: run time [s]
    measurement: Optional[Measurement]  #: None when ``fault`` says why
    fault: str = ''
    new_run: bool = False               #: this stamp started a new run (a confirmed clock jump)


@dataclass(frozen=True)
class PipelineConfig:
    driving: str = 'joints'
    #: Joint state messages drive only if they carry one of these joints (empty: any joint).
    driving_joints: tuple[str, ...] = ()
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    sync: SyncConfig = field(default_factory=SyncConfig)
    timeline: TimelineConfig = field(default_factory=TimelineConfig)

    def __post_init__(self) -> None:
        if self.driving not in DRIVING_STREAMS:
            raise ValueError(f'driving stream must be one of {DRIVING_STREAMS}, got {self.driving!r}')


class SensorPipeline:
    """Sensor readings in, :class:`Estimate` s out (module docstring).

    ``robot``: the description with its sole frames; ``imu_frame``: the IMU frame of readings that
    name none; ``force_sensors``: the sides with a foot force/torque sensor; ``topics``: topic names
    for the words of the faults.
    """

    def __init__(self, robot: RobotDescription, imu_frame: str = '',
                 force_sensors: tuple[str, ...] = ('l', 'r'),
                 config: PipelineConfig = PipelineConfig(),
                 topics: Optional[dict[str, str]] = None) -> None:
        self.config = config
        self.robot = robot
        # Feet without a force/torque sensor: their wrench from the joint efforts (or statics).
        self.estimator = StateEstimator(robot, config.estimator, imu_frame=imu_frame,
                                        effort_feet=tuple(s for s in SIDES if s not in force_sensors))
        weight_n = robot.total_mass_kg * 9.81
        self.sync = SensorSync(robot.joint_names, force_sensors, weight_n, config.sync,
                               robot.joint_bounds, topics)
        self.timeline = StampTimeline(config.timeline)
        self.counts = {'estimates': 0, 'measurements': 0, 'faults': 0}
        self._drivers = frozenset(config.driving_joints or robot.joint_names)
        #: An accepted driving stamp waiting for its readings: (stamp [ns], starts a new run).
        self._pending: Optional[tuple[int, bool]] = None

    def reset(self) -> None:
        """A new run: time, estimator and sensor buffers start over."""
        self.timeline.reset()
        self.estimator.reset()
        self.sync.reset()
        self._pending = None

    def joint_state(self, reading: JointStateReading) -> tuple[list[Estimate], list[str]]:
        """One joint state message: (the estimates it completes, joint names the robot
        description does not know, seen for the first time). ValueError if malformed."""
        unknown = self.sync.add_joint_state(reading)
        drives = (self.config.driving == 'joints' and not self._drivers.isdisjoint(reading.names)
                  and reading.stamp_ns != self.timeline.last_ns)      # not a part of a split message
        return self._after_reading(reading.stamp_ns if drives else None), unknown

    def imu(self, reading: ImuReading) -> list[Estimate]:
        self.sync.add_imu(reading)
        return self._after_reading(reading.stamp_ns if self.config.driving == 'imu' else None)

    def wrench(self, side: str, reading: WrenchReading) -> list[Estimate]:
        self.sync.add_wrench(side, reading)
        return self._after_reading(None)

    def add(self, stream: str, reading) -> list[Estimate]:
        """One message of ``stream`` ('joints', 'imu', 'l' or 'r': the drivers' stream names);
        the estimates it completes (joint names the description lacks are dropped: use
        :meth:`joint_state` to hear of them). ValueError if a joint state is malformed."""
        if stream == 'joints':
            return self.joint_state(reading)[0]
        if stream == 'imu':
            return self.imu(reading)
        return self.wrench(stream, reading)

    def flush(self) -> list[Estimate]:
        """The estimate of a driving stamp still waiting for readings (end of a recording)."""
        return self._estimate_pending()

    def _after_reading(self, driving_ns: Optional[int]) -> list[Estimate]:
        out = []
        if driving_ns is not None:
            out = self._estimate_pending()
            kind = self.timeline.classify(driving_ns)
            if kind.accepted:
                if kind is Stamp.NEW_RUN:
                    self.estimator.reset()
                self._pending = (driving_ns, kind is Stamp.NEW_RUN)
        if self._pending is not None and self.sync.complete_at(self._pending[0]):
            out.extend(self._estimate_pending())
        return out

    def _estimate_pending(self) -> list[Estimate]:
        if self._pending is None:
            return []
        stamp_ns, new_run = self._pending
        self._pending = None
        return [self._estimate(stamp_ns, new_run)]

    def _estimate(self, stamp_ns: int, new_run: bool) -> Estimate:
        t = self.timeline.run_time(stamp_ns)
        self.counts['estimates'] += 1
        sample, faults = self.sync.sample_at(stamp_ns, t, self.config.driving)
        measurement = None
        if sample is not None:
            measurement = self.estimator.update(sample)
            if measurement is None:
                faults = [self.estimator.last_issue or 'the estimator refused the sample']
            else:
                # An estimate no humanoid can be in (a CoM below the ground after a fall, with no
                # sole loaded to anchor the position) is a fault here, where it is made: every
                # consumer, live or offline, then says DEGRADED for it.
                try:
                    check_measurement(measurement)
                except ImplausibleSample as error:
                    measurement, faults = None, [f'implausible estimate: {error}']
        if measurement is None:
            self.counts['faults'] += 1
            return Estimate(stamp_ns, t, None, '; '.join(faults), new_run)
        self.counts['measurements'] += 1
        return Estimate(stamp_ns, t, measurement, '', new_run)
