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
   fault. A joint past its limits or rated speed but within the possible does not stop the
   estimate: the estimate carries it in words (``flags``) and it is counted
   (``counts['flagged']``). Joint states split over several messages (legs and arms from
   different controllers) drive only when they carry a joint of ``driving_joints`` (default: any
   joint of the description), and only once per stamp: the rest are taken as the joints' newest
   values.

A confirmed step of the driving stream's clock, back or forward (an NTP or PTP step on the robot, a
simulator reset, a recording that loops, a sensor that paused for more than ``max_step_s``), starts
a new run: the estimator starts again, every other stream starts again from its readings on the new
timeline (:meth:`~fall_predictor.monitor.sensor_sync.SensorSync.follow`), and the estimate says so
(``new_run``, with the step) so that the monitor restarts its windows, never its latch. Each
stream's own clock follows the same rule: a stream that steps alone starts its readings again, and
the samples then say that the clocks differ. :meth:`SensorPipeline.take_notices` gives each such
event once, in words, for the log.

A joint state message that carries none of the description's joints (empty, or naming only joints
the description lacks) while none of the robot's joints arrive either is a fault in words, not a
silent missing sample.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from fall_predictor.monitor.effort_wrench import leg_joint_ids
from fall_predictor.monitor.estimator import EstimatorConfig, StateEstimator
from fall_predictor.monitor.lowstate import LowStateSample
from fall_predictor.monitor.plausibility import ImplausibleSample, bound_names, check_measurement
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
    new_run: bool = False               #: this stamp started a new run (a confirmed clock step)
    #: With ``new_run``: the step [s] from the previous accepted stamp (negative: back).
    clock_step_s: float = 0.0
    #: With a measurement: what is unusual but possible in its sample, in words (a joint past
    #: its limit or rated speed: kept, counted, said in the diagnostics); '' when nothing is.
    flags: str = ''


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
        effort_joints = [robot.model.names[j] for side in self.estimator.effort_feet
                         for j in leg_joint_ids(robot, side)]
        self.sync = SensorSync(robot.joint_names, force_sensors, weight_n, config.sync,
                               robot.joint_bounds, topics, config.timeline, effort_joints)
        self.timeline = StampTimeline(config.timeline)
        self.counts = {'estimates': 0, 'measurements': 0, 'faults': 0, 'joint_messages_unused': 0,
                       'flagged': 0}
        #: The flags of the latest flagged estimate ('' before any).
        self.last_flags = ''
        self._drivers = frozenset(config.driving_joints or robot.joint_names)
        self._known = frozenset(robot.joint_names)
        self._topics = self.sync.topics
        #: An accepted driving stamp waiting for its readings: (stamp [ns], starts a new run, the
        #: fault it has already, if any).
        self._pending: Optional[tuple[int, bool, str]] = None
        self._notices: list[str] = []
        #: Steps of other streams' clocks not told yet: (stream, step [s], estimates then). A
        #: step of the driving stream's clock soon after tells them with its own.
        self._stream_steps: list[tuple[str, float, int]] = []

    def reset(self) -> None:
        """A new run: time, estimator and sensor buffers start over."""
        self.timeline.reset()
        self.estimator.reset()
        self.sync.reset()
        self._pending = None

    def take_notices(self) -> list[str]:
        """What happened to the streams' clocks since the last call, in words, each once (for a
        log line): a step of the driving stream's clock (with the streams that stepped with it),
        or of another stream's alone (told once the driving stream has gone on without it)."""
        estimates = self.counts['estimates']
        self._stream_steps += [(stream, step_s, estimates) for stream, step_s in self.sync.take_steps()]
        alone = [(stream, step_s) for stream, step_s, then in self._stream_steps
                 if estimates - then > self.config.timeline.jump_samples]
        self._stream_steps = [s for s in self._stream_steps
                              if estimates - s[2] <= self.config.timeline.jump_samples]
        driving = self._topics[self.config.driving]
        out = self._notices + [
            f'{self._topics[stream]} stamps stepped {_direction(step_s)} {abs(step_s):.3f} s alone: its '
            f'readings start again from its new timeline, which {driving} does not share (the '
            'samples say so until the clocks agree)' for stream, step_s in alone]
        self._notices = []
        return out

    def joint_state(self, reading: JointStateReading) -> tuple[list[Estimate], list[str]]:
        """One joint state message: (the estimates it completes, joint names the robot
        description does not know, seen for the first time). ValueError if malformed."""
        unknown = self.sync.add_joint_state(reading)
        joints = self.config.driving == 'joints'
        drives = (joints and not self._drivers.isdisjoint(reading.names)
                  and reading.stamp_ns != self.timeline.last_ns)      # not a part of a split message
        if drives:
            return self._after_reading(reading.stamp_ns), unknown
        if joints and self._known.isdisjoint(reading.names) and self._robot_silent(reading.stamp_ns):
            self.counts['joint_messages_unused'] += 1
            return self._after_reading(reading.stamp_ns, self._unusable_joint_state(reading)), unknown
        return self._after_reading(None), unknown

    def _robot_silent(self, stamp_ns: int) -> bool:
        """Whether none of the robot's joints arrived within the joint timeout before
        ``stamp_ns`` (a message of other joints is then not a second publisher's: it is all
        there is)."""
        newest = self.sync.joints.newest_stamp_ns
        timeout_ns = round(self.config.sync.joint_timeout_s * 1e9)
        return not self.sync.joints.received.any() or stamp_ns - newest > timeout_ns

    def _unusable_joint_state(self, reading: JointStateReading) -> str:
        topic = self._topics['joints']
        if not reading.names:
            return f'{topic} message with no joints (empty names)'
        names = bound_names(reading.names)
        return (f'{topic} names only joints the robot description lacks ({names}): is the '
                'robot_description this robot\'s?')

    def imu(self, reading: ImuReading) -> list[Estimate]:
        self.sync.add_imu(reading)
        return self._after_reading(reading.stamp_ns if self.config.driving == 'imu' else None)

    def wrench(self, side: str, reading: WrenchReading) -> list[Estimate]:
        self.sync.add_wrench(side, reading)
        return self._after_reading(None)

    def lowstate(self, sample: LowStateSample) -> list[Estimate]:
        """One Unitree LowState (:mod:`~fall_predictor.monitor.lowstate`): its IMU and joints at
        one stamp, which drives an estimate; one with a fault gives that fault at once."""
        if sample.imu is not None:
            self.sync.add_imu(sample.imu)
        if sample.joints is not None:
            self.sync.add_joint_state(sample.joints)
        out = self._after_reading(sample.stamp_ns, sample.fault)
        if sample.fault:
            out.extend(self._estimate_pending())
        return out

    def add(self, stream: str, reading) -> list[Estimate]:
        """One message of ``stream`` ('joints', 'imu', 'l' or 'r': the drivers' stream names;
        'lowstate': a :class:`~fall_predictor.monitor.lowstate.LowStateSample`); the estimates it
        completes (joint names the description lacks are dropped: use :meth:`joint_state` to hear
        of them). ValueError if a joint state is malformed."""
        if stream == 'joints':
            return self.joint_state(reading)[0]
        if stream == 'imu':
            return self.imu(reading)
        if stream == 'lowstate':
            return self.lowstate(reading)
        return self.wrench(stream, reading)

    def flush(self) -> list[Estimate]:
        """The estimate of a driving stamp still waiting for readings (end of a recording)."""
        return self._estimate_pending()

    def _after_reading(self, driving_ns: Optional[int], fault: str = '') -> list[Estimate]:
        out = []
        if driving_ns is not None:
            out = self._estimate_pending()
            kind = self.timeline.classify(driving_ns)
            if kind.accepted:
                if kind is Stamp.NEW_RUN:
                    self._new_run(driving_ns)
                self._pending = (driving_ns, kind is Stamp.NEW_RUN, fault)
        if (self._pending is not None and not self._pending[2]
                and self.sync.complete_at(self._pending[0])):
            out.extend(self._estimate_pending())
        return out

    def _new_run(self, anchor_ns: int) -> None:
        """The driving stream's clock stepped: the estimator and the other streams start again."""
        self.estimator.reset()
        with_it = self.sync.follow(anchor_ns)
        step_s = self.timeline.last_step_s
        max_step_s = self.config.timeline.max_step_s
        self._stream_steps += [(stream, s, 0) for stream, s in self.sync.take_steps()]
        together = [self._topics[stream] for stream, s, _ in self._stream_steps
                    if abs(s - step_s) <= max_step_s]
        together += [self._topics[stream] for stream in with_it]
        self._stream_steps = [s for s in self._stream_steps if abs(s[1] - step_s) > max_step_s]
        streams = ' and '.join([self._topics[self.config.driving], *together])
        self._notices.append(
            f'{streams} stamps stepped {_direction(step_s)} {abs(step_s):.3f} s (a clock step, a '
            f'simulator reset, a looped recording or a pause longer than {max_step_s:g} s): a new '
            f'timeline from stamp {anchor_ns / 1e9:.3f} s; buffers emptied, history restarted, the '
            'fall latch kept')

    def _estimate_pending(self) -> list[Estimate]:
        if self._pending is None:
            return []
        stamp_ns, new_run, fault = self._pending
        self._pending = None
        return [self._estimate(stamp_ns, new_run, fault)]

    def _estimate(self, stamp_ns: int, new_run: bool, fault: str = '') -> Estimate:
        t = self.timeline.run_time(stamp_ns)
        step_s = self.timeline.last_step_s if new_run else 0.0
        self.counts['estimates'] += 1
        if fault:
            self.counts['faults'] += 1
            return Estimate(stamp_ns, t, None, fault, new_run, step_s)
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
            return Estimate(stamp_ns, t, None, '; '.join(faults), new_run, step_s)
        self.counts['measurements'] += 1
        flags = self.sync.joints.flags()
        if flags:
            self.counts['flagged'] += 1
            self.last_flags = '; '.join(flags)
            return Estimate(stamp_ns, t, measurement, '', new_run, step_s, self.last_flags)
        return Estimate(stamp_ns, t, measurement, '', new_run, step_s)


def _direction(step_s: float) -> str:
    return 'back' if step_s < 0 else 'forward'
