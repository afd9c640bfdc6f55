"""The robot's sensor streams, each on its own clock and rate, merged into one sample per estimate
(method §12).

A robot publishes its joint encoders, IMU and foot force/torque sensors on separate topics, each
stamped by its own driver: joint states at 100 Hz-1 kHz, possibly split over several messages
(legs and arms from different controllers) with the joints in the driver's order; the IMU a
fraction of a millisecond after the encoders; foot wrenches optional. :class:`SensorSync` keeps

* the newest value of every joint of the robot description (:class:`JointTable`): merged from any
  number of messages, names the description does not know ignored (reported once), velocities
  estimated from positions when the driver reports none;
* the last few plausible readings of the IMU and of each foot sensor (:class:`StreamBuffer`),

and :meth:`SensorSync.sample_at` builds the :class:`SensorSample` at the stamp of a driving message:
each joint's newest value, the IMU and wrench readings interpolated to the stamp when readings on
both sides lie within ``tolerance_s``, else the nearest within it. What cannot be had is a fault in
an integrator's words ("no /imu/data within 5 ms of /joint_states", "joint l_knee_pitch never
received", "joint l_knee_pitch stuck at 0.4 rad while reporting 2 rad/s"); a sample with a fault is
not estimated: a sensor that stops is never taken as zero. Implausible readings (the sensor bounds
of :mod:`fall_predictor.monitor.plausibility`) are refused on arrival, and a sample that would need
them says so.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from fall_predictor.monitor.plausibility import JointBounds, check_imu, check_wrench
from fall_predictor.monitor.sensor_records import (ImuReading, JointStateReading, SensorSample,
                                                   WrenchReading)
from fall_predictor.monitor.timeline import NS_PER_S

SIDES = ('l', 'r')


@dataclass(frozen=True)
class SyncConfig:
    """How readings are matched to a driving stamp, and when a joint counts as missing or stuck."""

    #: The IMU and wrench readings used lie within this of the driving stamp [s].
    tolerance_s: float = 0.005
    #: A joint not updated within this of the driving stamp is missing [s].
    joint_timeout_s: float = 0.05
    #: A joint whose position stays identical for this long [s] while its reported speed is at
    #: least ``stuck_speed_rad_s`` is stuck (a frozen encoder or driver).
    stuck_time_s: float = 0.1
    stuck_speed_rad_s: float = 0.5
    #: Readings kept per stream (interpolation needs two around the stamp).
    buffer_readings: int = 16

    def __post_init__(self) -> None:
        for name in ('tolerance_s', 'joint_timeout_s', 'stuck_time_s', 'stuck_speed_rad_s'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f'{name} must be a finite number > 0, got {value!r}')
        if self.buffer_readings < 2:
            raise ValueError(f'buffer_readings must be >= 2, got {self.buffer_readings}')


class StreamBuffer:
    """The last readings of one sensor stream (values as flat float arrays), in stamp order."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._stamps: list[int] = []
        self._values: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self._stamps)

    @property
    def newest_ns(self) -> Optional[int]:
        return self._stamps[-1] if self._stamps else None

    @property
    def newest(self) -> Optional[np.ndarray]:
        return self._values[-1] if self._values else None

    def clear(self) -> None:
        self._stamps.clear()
        self._values.clear()

    def add(self, stamp_ns: int, values: np.ndarray) -> None:
        """Insert a reading in stamp order (a late one too); a repeated stamp replaces it."""
        stamps = self._stamps
        i = bisect.bisect_left(stamps, stamp_ns)
        if i < len(stamps) and stamps[i] == stamp_ns:
            self._values[i] = values
            return
        stamps.insert(i, stamp_ns)
        self._values.insert(i, values)
        if len(stamps) > self.size:
            del stamps[0], self._values[0]

    def at(self, stamp_ns: int, tolerance_ns: int) -> Optional[np.ndarray]:
        """The reading at ``stamp_ns``: interpolated between the readings around it when both lie
        within ``tolerance_ns``, else the nearest within it, else None."""
        stamps = self._stamps
        i = bisect.bisect_right(stamps, stamp_ns) - 1          # newest at or before the stamp
        before = i if i >= 0 and stamp_ns - stamps[i] <= tolerance_ns else None
        after = i + 1 if i + 1 < len(stamps) and stamps[i + 1] - stamp_ns <= tolerance_ns else None
        if before is not None and (after is None or stamps[before] == stamp_ns):
            return self._values[before]
        if before is not None and after is not None:
            w = (stamp_ns - stamps[before]) / (stamps[after] - stamps[before])
            return self._values[before] + w * (self._values[after] - self._values[before])
        return None if after is None else self._values[after]


class JointTable:
    """The newest position, velocity and effort of each joint of the robot description."""

    def __init__(self, names: Sequence[str], bounds: Optional[JointBounds] = None) -> None:
        self.names = tuple(names)
        n = len(self.names)
        self._index = {name: i for i, name in enumerate(self.names)}
        self.q = np.full(n, np.nan)
        self.dq = np.full(n, np.nan)
        self.tau = np.full(n, np.nan)
        self.stamp_ns = np.zeros(n, dtype=np.int64)
        self.received = np.zeros(n, dtype=bool)
        self.reports_velocity = np.zeros(n, dtype=bool)
        self._frozen_since_ns = np.zeros(n, dtype=np.int64)
        self.bounds = bounds
        self.unknown: set[str] = set()        #: names seen that the description does not have
        self.oldest_stamp_ns = 0               #: the stamp of the joint longest without news
        self.all_received = n == 0             #: every joint has been received
        self._maps: dict[tuple[str, ...], tuple] = {}

    def _map(self, names: tuple[str, ...]) -> tuple:
        """Of a message layout: (positions in the message, joint indices) of its known names, and
        its names the description lacks."""
        cached = self._maps.get(names)
        if cached is None:
            if len(set(names)) != len(names):
                raise ValueError(f'joint names repeat in one message: {list(names)}')
            pairs = [(k, self._index[n]) for k, n in enumerate(names) if n in self._index]
            message = np.array([k for k, _ in pairs], dtype=np.int64)
            joints = np.array([j for _, j in pairs], dtype=np.int64)
            cached = self._maps[names] = (message, joints,
                                          [n for n in names if n not in self._index])
        return cached

    def update(self, reading: JointStateReading) -> list[str]:
        """Take one message's joints; returns the names the description does not know that were
        not seen before (to be reported once). ValueError for a malformed message."""
        names = tuple(reading.names)
        position = np.asarray(reading.position, dtype=float)
        velocity = np.asarray(reading.velocity, dtype=float)
        effort = np.asarray(reading.effort, dtype=float)
        n = len(names)
        if position.shape != (n,) or velocity.size not in (0, n) or effort.size not in (0, n):
            raise ValueError(f'joint state with {n} names has {position.size} positions, '
                             f'{velocity.size} velocities and {effort.size} efforts')
        k, j, unknown = self._map(names)
        new_unknown = [name for name in unknown if name not in self.unknown]
        self.unknown.update(new_unknown)
        if not j.size:
            return new_unknown
        q_new = position[k]
        stamp = reading.stamp_ns
        if not np.isfinite(q_new).all():
            raise ValueError('joint positions are not finite')
        if velocity.size:
            dq_new = velocity[k]
            if not np.isfinite(dq_new).all():
                raise ValueError('joint velocities are not finite')
            self.reports_velocity[j] = True
        else:
            # No velocities reported: the backward difference of positions per joint.
            dt = (stamp - self.stamp_ns[j]) / NS_PER_S
            with np.errstate(invalid='ignore', divide='ignore'):
                dq_new = np.where(self.received[j] & (dt > 0), (q_new - self.q[j]) / dt, 0.0)
            self.reports_velocity[j] = False
        moved = q_new != self.q[j]
        if not self.all_received:
            moved |= ~self.received[j]          # a first reading starts the stuck clock too
        self._frozen_since_ns[j[moved]] = stamp
        self.q[j] = q_new
        self.dq[j] = dq_new
        self.tau[j] = effort[k] if effort.size else np.nan
        self.stamp_ns[j] = stamp
        if not self.all_received:
            self.received[j] = True
            self.all_received = not np.count_nonzero(~self.received)
        # Kept per message, read per sample and per reading (complete_at, faults); a message with
        # every joint makes its stamp the oldest.
        self.oldest_stamp_ns = stamp if len(j) == len(self.names) else int(self.stamp_ns.min())
        return new_unknown

    def efforts(self) -> np.ndarray:
        """A copy of every joint's effort, or an empty array where any is unknown."""
        return self.tau.copy() if np.isfinite(self.tau).all() else np.zeros(0)

    def never_received(self) -> list[str]:
        return [self.names[i] for i in np.flatnonzero(~self.received)]

    def faults(self, stamp_ns: int, config: SyncConfig) -> list[str]:
        """Why the joints cannot be used at ``stamp_ns`` (empty when they can)."""
        out = []
        if not self.all_received:
            missing = ~self.received
            out.append(_joint_list('never received', [self.names[i] for i in np.flatnonzero(missing)]))
        # Each check in full only when its cheap bound says a joint may fail it.
        if (stamp_ns - self.oldest_stamp_ns) / NS_PER_S > config.joint_timeout_s:
            age_s = (stamp_ns - self.stamp_ns) / NS_PER_S
            old = self.received & (age_s > config.joint_timeout_s)
            if np.count_nonzero(old):
                out.append(_joint_list(f'not received for more than {config.joint_timeout_s * 1e3:.0f} ms',
                                       [self.names[i] for i in np.flatnonzero(old)]))
        if (stamp_ns - int(self._frozen_since_ns.min())) / NS_PER_S >= config.stuck_time_s:
            frozen_s = (stamp_ns - self._frozen_since_ns) / NS_PER_S
            stuck = (self.received & self.reports_velocity & (frozen_s >= config.stuck_time_s)
                     & (np.abs(self.dq) >= config.stuck_speed_rad_s))
            for i in np.flatnonzero(stuck):
                out.append(f'joint {self.names[i]} stuck at {self.q[i]:.4g} rad for {frozen_s[i]:.2f} s '
                           f'while reporting {self.dq[i]:.3g} rad/s')
        if self.bounds is not None and not out:
            out.extend(self.bounds.violations(self.q, self.dq))
        return out


def _joint_list(what: str, names: list[str]) -> str:
    shown = ', '.join(names[:6]) + (f' and {len(names) - 6} more' if len(names) > 6 else '')
    return f'joint{"s" if len(names) > 1 else ""} {shown} {what}'


class SensorSync:
    """Merges joint states, IMU and foot wrenches into :class:`SensorSample` s (module docstring).

    ``joint_names``: the joints of the robot description, in the estimator's order;
    ``force_sensors``: the sides ('l', 'r') that have a foot force/torque sensor;
    ``robot_weight_n``: for the wrench bounds; ``topics``: the resolved topic names, for the words
    of the faults (keys 'joints', 'imu', 'l', 'r').
    """

    def __init__(self, joint_names: Sequence[str], force_sensors: Sequence[str] = SIDES,
                 robot_weight_n: float = 1000.0, config: SyncConfig = SyncConfig(),
                 bounds: Optional[JointBounds] = None,
                 topics: Optional[dict[str, str]] = None) -> None:
        self.config = config
        self.joints = JointTable(joint_names, bounds)
        self.force_sensors = tuple(force_sensors)
        self.robot_weight_n = robot_weight_n
        self.topics = {'joints': '/joint_states', 'imu': '/imu/data', 'l': '/left_foot/wrench',
                       'r': '/right_foot/wrench', **(topics or {})}
        self._tolerance_ns = round(config.tolerance_s * NS_PER_S)
        self.imu = StreamBuffer(config.buffer_readings)
        self.wrenches = {side: StreamBuffer(config.buffer_readings) for side in self.force_sensors}
        self.imu_frame = ''
        self.wrench_frames = {side: '' for side in SIDES}
        #: Per stream: (stamp [ns], reason) of the latest reading refused as implausible.
        self.refused: dict[str, tuple[int, str]] = {}
        self.counts = {'joint_messages': 0, 'imu_readings': 0, 'wrench_readings': 0,
                       'refused_readings': 0}

    def reset(self) -> None:
        """Forget the IMU and wrench readings (a new run); joint values stay (they are absolute)."""
        self.imu.clear()
        for buffer in self.wrenches.values():
            buffer.clear()
        self.refused.clear()

    def _refuse(self, stream: str, stamp_ns: int, reason: str) -> None:
        self.refused[stream] = (stamp_ns, reason)
        self.counts['refused_readings'] += 1

    def add_joint_state(self, reading: JointStateReading) -> list[str]:
        """One joint state message; returns newly seen joint names the description lacks."""
        self.counts['joint_messages'] += 1
        return self.joints.update(reading)

    def add_imu(self, reading: ImuReading) -> None:
        reason = check_imu(reading.orientation_xyzw, reading.angular_velocity,
                           reading.linear_acceleration)
        if reason is not None:
            self._refuse('imu', reading.stamp_ns, reason)
            return
        self.counts['imu_readings'] += 1
        quat = np.asarray(reading.orientation_xyzw, dtype=float)
        previous = self.imu.newest
        if previous is not None and float(previous[:4] @ quat) < 0.0:
            quat = -quat                    # the same attitude: keep the sign for interpolation
        self.imu_frame = reading.frame_id
        self.imu.add(reading.stamp_ns, np.concatenate([quat, np.asarray(reading.angular_velocity, dtype=float),
                                                       np.asarray(reading.linear_acceleration, dtype=float)]))

    def add_wrench(self, side: str, reading: WrenchReading) -> None:
        if side not in self.wrenches:
            return                          # a foot without a configured sensor: not used
        reason = check_wrench(reading.wrench, self.robot_weight_n)
        if reason is not None:
            self._refuse(side, reading.stamp_ns, reason)
            return
        self.counts['wrench_readings'] += 1
        self.wrench_frames[side] = reading.frame_id
        self.wrenches[side].add(reading.stamp_ns, np.asarray(reading.wrench, dtype=float))

    def complete_at(self, stamp_ns: int) -> bool:
        """Whether every stream has a reading at or after ``stamp_ns`` (nothing more to wait for)."""
        if self.imu.newest_ns is None or self.imu.newest_ns < stamp_ns:
            return False
        for buffer in self.wrenches.values():
            if buffer.newest_ns is None or buffer.newest_ns < stamp_ns:
                return False
        return self.joints.oldest_stamp_ns >= stamp_ns

    def _missing(self, stream: str, buffer: StreamBuffer, stamp_ns: int, driving: str) -> str:
        refused = self.refused.get(stream)
        if refused is not None and abs(refused[0] - stamp_ns) <= self._tolerance_ns:
            return f'{self.topics[stream]} refused: {refused[1]}'
        within = f'within {self.config.tolerance_s * 1e3:.0f} ms of {self.topics[driving]}'
        if not len(buffer):
            return f'no {self.topics[stream]} {within}'
        lag_s = (stamp_ns - buffer.newest_ns) / NS_PER_S
        return f'no {self.topics[stream]} {within} (newest {lag_s * 1e3:.0f} ms older)'

    def sample_at(self, stamp_ns: int, t: float, driving: str = 'joints'
                  ) -> tuple[Optional[SensorSample], list[str]]:
        """The sample at a driving message's ``stamp_ns`` (run time ``t`` [s]) and its faults; the
        sample is None when there are any (module docstring)."""
        faults = self.joints.faults(stamp_ns, self.config)
        imu = self.imu.at(stamp_ns, self._tolerance_ns)
        if imu is None:
            faults.append(self._missing('imu', self.imu, stamp_ns, driving))
        wrenches: dict[str, Optional[np.ndarray]] = {'l': None, 'r': None}
        for side, buffer in self.wrenches.items():
            wrenches[side] = buffer.at(stamp_ns, self._tolerance_ns)
            if wrenches[side] is None:
                faults.append(self._missing(side, buffer, stamp_ns, driving))
        if faults:
            return None, faults
        assert imu is not None
        quat = imu[:4] / math.sqrt(float(imu[:4] @ imu[:4]))
        table = self.joints
        sample = SensorSample(
            t=t, joint_names=table.names, q=table.q.copy(), dq=table.dq.copy(),
            tau=table.efforts(),
            imu_quat_xyzw=quat, gyro_rad_s=imu[4:7], accel_m_s2=imu[7:10],
            left_wrench=wrenches['l'], right_wrench=wrenches['r'], imu_frame=self.imu_frame,
            wrench_frames=(self.wrench_frames['l'], self.wrench_frames['r']))
        return sample, []
