"""A learned policy on the robot's sensor streams, without ROS: joint states and IMU readings in, one
sensor sample per joint state stamp out, and when the policy acts on them.

A learned walking policy observes what the robot measures (its joint encoders and its IMU), never
a simulator's state. :class:`PolicyInputs` merges the two streams as the state estimator's
pipeline does (:class:`~fall_predictor.monitor.sensor_pipeline.SensorPipeline`, with the same
:class:`~fall_predictor.monitor.sensor_sync.SensorSync` and the same time rule,
:class:`~fall_predictor.monitor.timeline.StampTimeline`): each joint state stamp (a split message's
parts count once) whose stamp the time rule accepts waits until every joint and the IMU have a
reading at or after it (the IMU stamped a fraction of a millisecond after the encoders arrives
after them), or until the next joint state stamp comes; then it becomes a :class:`PolicyStep`:
the :class:`~fall_predictor.monitor.sensor_records.SensorSample` at that stamp (the IMU
interpolated where two readings bracket it), or the fault that prevented it, in words ("no
/imu/data within 5 ms of /joint_states", "joint left_knee_joint never received"). A sensor that
stops is never taken as zero. A confirmed step of the joint states' clock (a simulator's new
world, a looped recording) starts a new run (``new_run``).

:class:`PolicySchedule` says at which steps the policy acts: at the first usable sample of a run,
then at the first usable sample at or after each whole number of policy periods from there (on
the integer stamps: the simulated robot's samples fall exactly on that grid, as the offline loop
``sim/trajectory.py`` runs the policy every ``period / dt`` physics steps); a due step whose
sample has a fault does not act, and the next usable one does.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

from fall_predictor.monitor.plausibility import JointBounds
from fall_predictor.monitor.sensor_records import ImuReading, JointStateReading, SensorSample
from fall_predictor.monitor.sensor_sync import SensorSync, SyncConfig
from fall_predictor.monitor.timeline import NS_PER_S, Stamp, StampTimeline, TimelineConfig


@dataclass(frozen=True)
class PolicyStep:
    """One joint state stamp, complete: its sample, or the fault that prevented it."""

    stamp_ns: int                       #: the joint states' own stamp (ROS time)
    t_s: float                          #: run time [s]
    sample: Optional[SensorSample]      #: None when ``fault`` says why
    fault: str = ''
    new_run: bool = False               #: this stamp started a new run (a confirmed clock step)


class PolicyInputs:
    """Joint states and IMU readings -> :class:`PolicyStep` s (module docstring).

    ``joint_names``: the robot's joints (the sample's order); ``bounds``: their plausible
    positions and speeds (refused readings are faults, never used); ``topics``: the resolved
    topic names for the words of the faults (keys 'joints', 'imu').
    """

    def __init__(self, joint_names: Sequence[str], bounds: Optional[JointBounds] = None,
                 config: SyncConfig = SyncConfig(), timeline: TimelineConfig = TimelineConfig(),
                 topics: Optional[dict[str, str]] = None) -> None:
        # No foot force sensors: a policy observes none, and none is waited for.
        self.sync = SensorSync(joint_names, (), 1000.0, config, bounds, topics, timeline)
        self.timeline = StampTimeline(timeline)
        #: The latest joint state stamp seen (the parts of a split message share it).
        self._seen_ns: Optional[int] = None
        #: An accepted stamp waiting for its readings: (stamp [ns], starts a new run).
        self._pending: Optional[tuple[int, bool]] = None
        self.counts = {'steps': 0, 'faults': 0}

    def reset(self) -> None:
        """A new run (the monitor's reset): time and the IMU readings start over."""
        self.timeline.reset()
        self.sync.reset()
        self._seen_ns = None
        self._pending = None

    def joint_state(self, reading: JointStateReading) -> tuple[list[PolicyStep], list[str]]:
        """One joint state message: (the steps it completes, joint names the robot does not
        have, seen for the first time). ValueError if malformed."""
        unknown = self.sync.add_joint_state(reading)
        if reading.stamp_ns == self._seen_ns:
            return self._complete(), unknown          # another part of the same sample
        self._seen_ns = reading.stamp_ns
        out = self._take_pending()
        kind = self.timeline.classify(reading.stamp_ns)
        if kind.accepted:
            if kind is Stamp.NEW_RUN:
                self.sync.follow(reading.stamp_ns)
            self._pending = (reading.stamp_ns, kind is Stamp.NEW_RUN)
        return out + self._complete(), unknown

    def imu(self, reading: ImuReading) -> list[PolicyStep]:
        """One IMU message: the steps it completes."""
        self.sync.add_imu(reading)
        return self._complete()

    def flush(self) -> list[PolicyStep]:
        """The step of a stamp still waiting for its readings (end of a stream)."""
        return self._take_pending()

    def _complete(self) -> list[PolicyStep]:
        if self._pending is not None and self.sync.complete_at(self._pending[0]):
            return self._take_pending()
        return []

    def _take_pending(self) -> list[PolicyStep]:
        if self._pending is None:
            return []
        stamp_ns, new_run = self._pending
        self._pending = None
        t_s = self.timeline.run_time(stamp_ns)
        sample, faults = self.sync.sample_at(stamp_ns, t_s)
        self.counts['steps'] += 1
        if sample is None:
            self.counts['faults'] += 1
            return [PolicyStep(stamp_ns, t_s, None, '; '.join(faults), new_run)]
        return [PolicyStep(stamp_ns, t_s, sample, '', new_run)]


class PolicySchedule:
    """When a policy of period ``period_s`` acts (module docstring)."""

    def __init__(self, period_s: float) -> None:
        if not period_s > 0.0:
            raise ValueError(f'a policy period must be > 0 s, got {period_s!r}')
        self.period_ns = round(period_s * NS_PER_S)
        self.restart()

    def restart(self) -> None:
        """A new run: the next usable sample acts and starts the grid."""
        self._start_ns: Optional[int] = None
        self._next_ns: Optional[int] = None

    def due(self, stamp_ns: int) -> bool:
        """Whether the policy acts at ``stamp_ns`` (if its sample is usable)."""
        return self._next_ns is None or stamp_ns >= self._next_ns

    def acted(self, stamp_ns: int) -> None:
        """The policy acted at ``stamp_ns``: the next time is the grid point after it."""
        if self._start_ns is None:
            self._start_ns = stamp_ns
        periods = (stamp_ns - self._start_ns) // self.period_ns
        self._next_ns = self._start_ns + (periods + 1) * self.period_ns
