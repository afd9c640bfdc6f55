"""How a robot's drivers publish its sensors: each stream at its own rate, on its own clock.

The simulator samples every sensor at once, every 1 ms step, with simulation-time stamps. A robot
does not: its joint states come at 100 Hz-1 kHz, maybe split over several messages (legs and arms
from different controllers) with the joints in the driver's order; its IMU is stamped a fraction of
a millisecond after the encoders; its foot sensors at yet another rate; and every stamp is ROS time
(nanoseconds since 1970). :class:`DriverTiming` describes such a robot and :func:`driver_messages`
turns a stream of simulated :class:`~fall_predictor.monitor.sensor_records.SensorSample` into the
messages its drivers would publish, in the order they would arrive. One implementation serves the
simulator node (``sensor_timing``), ``generate --sensor-timing`` and the tests.

A stream at rate ``R`` publishes the simulator's sample at each step where ``floor(t R)``
increments (sample and hold of the 1 kHz simulation), stamped ``t + offset`` plus the clock offset.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Iterator, Optional, Sequence, Union

import numpy as np

from fall_predictor.monitor.sensor_records import (ImuReading, JointStateReading, SensorSample,
                                                   WrenchReading)
from fall_predictor.monitor.timeline import NS_PER_S

Reading = Union[JointStateReading, ImuReading, WrenchReading]
#: Stream names of :func:`driver_messages`: joint states, the IMU, the left and right foot sensors.
STREAMS = ('joints', 'imu', 'l', 'r')


@dataclass(frozen=True)
class DriverTiming:
    """Rates [Hz] and stamp offsets [s] of the sensor streams, and how joint states are split.

    ``joint_groups``: joint states published as one message per group (empty: one message with
    every joint); ``reverse_joint_order``: the driver lists the joints in reverse (not the URDF's
    order); ``clock_offset_ns``: added to every stamp (0: simulation time; a robot: ROS time).
    """

    joint_rate_hz: float = 1000.0
    imu_rate_hz: float = 1000.0
    wrench_rate_hz: float = 1000.0
    imu_offset_s: float = 0.0
    wrench_offset_s: float = 0.0
    joint_groups: tuple[tuple[str, ...], ...] = ()
    reverse_joint_order: bool = False
    clock_offset_ns: int = 0

    def __post_init__(self) -> None:
        for name in ('joint_rate_hz', 'imu_rate_hz', 'wrench_rate_hz'):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 < value <= 1000.0):
                raise ValueError(f'{name} must lie in (0, 1000] Hz (the simulation rate), got {value!r}')
        for name in ('imu_offset_s', 'wrench_offset_s'):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value < 0.001):
                raise ValueError(f'{name} must lie in [0, 1) ms, got {value!r}')

    @property
    def simulator_like(self) -> bool:
        """Every stream at 1 kHz with one identical stamp: the simulator's own timing."""
        return self == DriverTiming(clock_offset_ns=self.clock_offset_ns)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> 'DriverTiming':
        """The timing of :meth:`to_dict` (JSON: joint groups as lists)."""
        values = dict(values)
        values['joint_groups'] = tuple(tuple(g) for g in values.get('joint_groups', ()))
        return cls(**values)

    @classmethod
    def robot(cls, joint_rate_hz: float = 500.0, joint_groups: tuple[tuple[str, ...], ...] = (),
              clock_offset_ns: int = 1_795_521_600 * NS_PER_S) -> 'DriverTiming':
        """A robot as the drivers of one publish: joints at ``joint_rate_hz`` in reverse order,
        split into ``joint_groups``, IMU 0.3 ms and foot sensors 0.4 ms after the encoders, both at
        1 kHz, epoch stamps (2026-11-24 12:00 UTC at t = 0)."""
        return cls(joint_rate_hz=joint_rate_hz, imu_rate_hz=1000.0, wrench_rate_hz=1000.0,
                   imu_offset_s=0.0003, wrench_offset_s=0.0004, joint_groups=joint_groups,
                   reverse_joint_order=True, clock_offset_ns=clock_offset_ns)


class DriverStreams:
    """The drivers of one robot, step by step: each simulated sample in, the messages published
    by the end of its step out (in arrival order)."""

    def __init__(self, timing: DriverTiming = DriverTiming()) -> None:
        self.timing = timing
        self._ticks: dict[str, Optional[int]] = {'joints': None, 'imu': None, 'wrench': None}
        self._pending: list[tuple[int, int, str, Reading]] = []
        self._order = 0

    def _due(self, stream: str, t: float, rate_hz: float) -> bool:
        tick = math.floor(round(t * rate_hz, 6))
        due = tick != self._ticks[stream]
        self._ticks[stream] = tick
        return due

    def _add(self, stamp_ns: int, stream: str, reading: Reading) -> None:
        self._pending.append((stamp_ns, self._order, stream, reading))
        self._order += 1

    def push(self, s: SensorSample) -> list[tuple[str, Reading]]:
        """The messages stamped up to the end of ``s``'s step (offsets are below one step)."""
        timing = self.timing
        base_ns = round(s.t * NS_PER_S) + timing.clock_offset_ns
        if self._due('joints', s.t, timing.joint_rate_hz):
            for reading in joint_messages(s, base_ns, timing):
                self._add(base_ns, 'joints', reading)
        if self._due('imu', s.t, timing.imu_rate_hz):
            stamp = base_ns + round(timing.imu_offset_s * NS_PER_S)
            self._add(stamp, 'imu', ImuReading(stamp, s.imu_frame, np.asarray(s.imu_quat_xyzw),
                                               np.asarray(s.gyro_rad_s), np.asarray(s.accel_m_s2)))
        if self._due('wrench', s.t, timing.wrench_rate_hz):
            stamp = base_ns + round(timing.wrench_offset_s * NS_PER_S)
            for side, wrench, frame in (('l', s.left_wrench, s.wrench_frames[0]),
                                        ('r', s.right_wrench, s.wrench_frames[1])):
                if wrench is not None:
                    self._add(stamp, side, WrenchReading(stamp, frame, np.asarray(wrench)))
        self._pending.sort()
        horizon = base_ns + NS_PER_S // 1000
        out = []
        while self._pending and self._pending[0][0] < horizon:
            _, _, stream, reading = self._pending.pop(0)
            out.append((stream, reading))
        return out

    def flush(self) -> list[tuple[str, Reading]]:
        out = [(stream, reading) for _, _, stream, reading in sorted(self._pending)]
        self._pending.clear()
        return out


def driver_messages(samples: Sequence[SensorSample], timing: DriverTiming = DriverTiming()
                    ) -> Iterator[tuple[str, Reading]]:
    """The messages the robot's drivers publish for a stream of simulated samples, in arrival
    order: (stream, reading) with stream one of :data:`STREAMS`."""
    drivers = DriverStreams(timing)
    for s in samples:
        yield from drivers.push(s)
    yield from drivers.flush()


def joint_messages(s: SensorSample, stamp_ns: int, timing: DriverTiming) -> list[JointStateReading]:
    """One sample's joint states as the drivers publish them (split and ordered per ``timing``)."""
    index = {name: i for i, name in enumerate(s.joint_names)}
    groups = timing.joint_groups or (tuple(s.joint_names),)
    tau = np.asarray(s.tau)
    out = []
    for group in groups:
        names = tuple(reversed(group)) if timing.reverse_joint_order else tuple(group)
        k = np.array([index[n] for n in names], dtype=np.int64)
        out.append(JointStateReading(stamp_ns, names, np.asarray(s.q)[k], np.asarray(s.dq)[k],
                                     tau[k] if tau.size else np.zeros(0)))
    return out
