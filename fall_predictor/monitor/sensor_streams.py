"""One sensor stream's readings on its own timeline, and the newest value of every joint: the
state :class:`~fall_predictor.monitor.sensor_sync.SensorSync` keeps per stream (method §12).

* :class:`StreamBuffer`: the last readings of the IMU or of a foot sensor, in stamp order, each
  stream's stamps following the time rule on their own (a step of its clock starts it again);
* :class:`JointTable`: the newest position, velocity and effort of each joint of the robot
  description, merged from any number of joint state messages, with the checks of missing,
  stuck, implausible and (where they feed the estimate) refused efforts;
* :class:`SyncConfig`: how readings are matched to a driving stamp.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

from fall_predictor.monitor.plausibility import MAX_NAME_CHARS, JointBounds, bound_names
from fall_predictor.monitor.sensor_records import JointStateReading
from fall_predictor.monitor.timeline import NS_PER_S, Stamp, StampTimeline, TimelineConfig

SIDES = ('l', 'r')
#: Message layouts (name lists) whose mapping is kept; unknown joint names remembered.
_MAX_LAYOUTS = 64
_MAX_UNKNOWN_NAMES = 200


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
    """The last readings of one sensor stream (values as flat float arrays), in stamp order, on
    the stream's own timeline.

    Each stream's stamps go through the time rule of :mod:`~fall_predictor.monitor.timeline` (its
    own :class:`~fall_predictor.monitor.timeline.StampTimeline`): a late reading is put in its
    place, a repeated stamp replaces its reading, a stray is dropped; a step of the stream's clock
    (back or forward, confirmed as the rule confirms it) empties the buffer and starts it again
    from the readings that confirmed the step, so that readings of the old timeline are never
    matched with the new one's (a clock stepped back 10 s would otherwise keep the old readings,
    all "newer" than every new one, until the new timeline caught up with them).
    """

    def __init__(self, size: int, timeline: TimelineConfig = TimelineConfig()) -> None:
        self.size = size
        self._stamps: list[int] = []
        self._values: list[np.ndarray] = []
        self.clock = StampTimeline(timeline)
        self._max_step_ns = round(timeline.max_step_s * NS_PER_S)
        #: Readings held while the stream's timeline decides whether its clock stepped.
        self._held: list[tuple[int, np.ndarray]] = []
        self.clock_steps = 0            #: steps of this stream's clock that emptied the buffer

    def __len__(self) -> int:
        return len(self._stamps)

    @property
    def newest_ns(self) -> Optional[int]:
        return self._stamps[-1] if self._stamps else None

    @property
    def newest(self) -> Optional[np.ndarray]:
        return self._values[-1] if self._values else None

    def clear(self) -> None:
        """Forget every reading and the stream's timeline (the next reading anchors it)."""
        self._stamps.clear()
        self._values.clear()
        self._held.clear()
        self.clock.reset()

    def add(self, stamp_ns: int, values: np.ndarray) -> bool:
        """Take one reading; returns whether its stamp confirmed a step of the stream's clock
        (the buffer then holds only the new timeline's readings)."""
        kind = self.clock.classify(stamp_ns)
        if kind is Stamp.JUMP_PENDING or kind is Stamp.OUT_OF_ORDER:
            # Held until the timeline tells a step from a stray; a late reading (out of order) is
            # also put in its place now, as it may be just that.
            self._held.append((stamp_ns, values))
            del self._held[:-self.clock.config.jump_samples]
            if kind is Stamp.JUMP_PENDING:
                return False
        if kind is Stamp.NEW_RUN:
            self._restart([(s, v) for s, v in self._held
                           if 0 <= stamp_ns - s <= self._max_step_ns * self.clock.config.jump_samples])
            self.clock_steps += 1
        elif kind is Stamp.NEXT:
            self._held.clear()
        self._insert(stamp_ns, values)      # NEXT, a late one (OUT_OF_ORDER) or a repeat
        return kind is Stamp.NEW_RUN

    def _restart(self, readings: list[tuple[int, np.ndarray]]) -> None:
        self._stamps.clear()
        self._values.clear()
        self._held.clear()
        for stamp_ns, values in readings:
            self._insert(stamp_ns, values)

    def holds_readings_near(self, anchor_ns: int) -> bool:
        """Whether readings held by the stream's timeline lie within ``max_step_s`` of
        ``anchor_ns``."""
        return any(abs(s - anchor_ns) <= self._max_step_ns for s, _ in self._held)

    def follow(self, anchor_ns: int) -> bool:
        """The driving stream started a new run at ``anchor_ns``: readings of another timeline
        (further than ``max_step_s`` from it) can never be matched with it. When readings held
        by this stream's timeline lie near the anchor, its clock stepped with the driving one's:
        the stream restarts from them at once; else readings far from the anchor are dropped.
        Returns whether the buffer was emptied or restarted."""
        near = [(s, v) for s, v in self._held if abs(s - anchor_ns) <= self._max_step_ns]
        if near:
            self._restart(near)
            self.clock.restart(near[-1][0])
            self.clock_steps += 1
            return True
        newest = self.newest_ns
        if newest is not None and abs(newest - anchor_ns) > self._max_step_ns:
            self.clear()
            return True
        return False

    def _insert(self, stamp_ns: int, values: np.ndarray) -> None:
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
        #: Per joint: an effort was ever reported (a driver that publishes none leaves it False).
        self.reports_effort = np.zeros(n, dtype=bool)
        #: Per joint: the effort last refused (non-finite or beyond the bound) and whether the
        #: latest one was refused; how many efforts were refused in all.
        self.refused_tau = np.full(n, np.nan)
        self.effort_refused = np.zeros(n, dtype=bool)
        self.refused_efforts = 0
        self._max_effort = None if bounds is None else bounds.max_effort
        self.unknown: set[str] = set()        #: names seen that the description does not have
        self.unknown_beyond_bound = 0          #: unknown names not remembered (beyond the bound)
        self.oldest_stamp_ns = 0               #: the stamp of the joint longest without news
        self.newest_stamp_ns = 0               #: the newest stamp of any joint
        self.all_received = n == 0             #: every joint has been received
        self._flags: list[str] = []            #: the last judged sample's flags (:meth:`flags`)
        self._maps: dict[tuple[str, ...], tuple] = {}

    def _map(self, names: tuple[str, ...]) -> tuple:
        """Of a message layout: (positions in the message, joint indices) of its known names, and
        its names the description lacks."""
        cached = self._maps.get(names)
        if cached is None:
            if len(self._maps) >= _MAX_LAYOUTS:
                self._maps.clear()          # a driver changing its layout every message: no cache
            longest = max(map(len, names), default=0)
            if longest > MAX_NAME_CHARS:
                raise ValueError(f'a joint name of {longest} characters (no robot description names '
                                 f'a joint so; at most {MAX_NAME_CHARS} are read)')
            if len(set(names)) != len(names):
                raise ValueError(f'joint names repeat in one message: {bound_names(names)}')
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
        if new_unknown:
            # Remembered up to a bound (names are reported once each); beyond it only counted.
            room = max(0, _MAX_UNKNOWN_NAMES - len(self.unknown))
            self.unknown_beyond_bound += max(0, len(new_unknown) - room)
            new_unknown = new_unknown[:room]
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
        if effort.size:
            self._take_efforts(j, effort[k])
        else:
            self.tau[j] = np.nan
        self.stamp_ns[j] = stamp
        if not self.all_received:
            self.received[j] = True
            self.all_received = not np.count_nonzero(~self.received)
        # Kept per message, read per sample and per reading (complete_at, faults); a message with
        # every joint makes its stamp the oldest.
        self.oldest_stamp_ns = stamp if len(j) == len(self.names) else int(self.stamp_ns.min())
        self.newest_stamp_ns = max(self.newest_stamp_ns, stamp)
        return new_unknown

    def new_run(self, anchor_ns: int) -> None:
        """The driving stream started a new run at ``anchor_ns``: the stuck clocks start again
        from it, and the newest stamp is the newest of the joints on or before it (joints stamped
        on another timeline show in :meth:`faults`)."""
        self._frozen_since_ns[:] = anchor_ns
        self.newest_stamp_ns = anchor_ns
        ahead = self.stamp_ns > anchor_ns
        if np.count_nonzero(ahead):
            self.newest_stamp_ns = int(self.stamp_ns.max())

    def _take_efforts(self, j: np.ndarray, tau_new: np.ndarray) -> None:
        """The efforts of joints ``j``: a non-finite one, or one beyond the joint's bound, is
        refused (kept as NaN, remembered in :attr:`refused_tau`, counted)."""
        self.reports_effort[j] = True
        with np.errstate(invalid='ignore'):
            good = np.abs(tau_new) <= (np.inf if self._max_effort is None else self._max_effort[j])
        if good.all():                      # NaN compares False: not finite is not good
            self.tau[j] = tau_new
            self.effort_refused[j] = False
            return
        self.refused_efforts += int(np.count_nonzero(~good))
        self.tau[j] = np.where(good, tau_new, np.nan)
        self.effort_refused[j] = ~good
        self.refused_tau[j] = np.where(good, np.nan, tau_new)

    def efforts(self) -> np.ndarray:
        """A copy of every joint's effort, or an empty array where any is unknown."""
        return self.tau.copy() if np.isfinite(self.tau).all() else np.zeros(0)

    def effort_faults(self, joints: np.ndarray) -> list[str]:
        """Why the efforts of ``joints`` (indices) cannot be used, for a robot whose feet without
        force sensors take their contact from them: a driver that reports efforts and then gives a
        non-finite or impossible one, or none. A driver that never reports any is not a fault (the
        estimator then takes the contacts from the kinematics and statics, method §10)."""
        missing = joints[self.reports_effort[joints] & ~np.isfinite(self.tau[joints])]
        if not missing.size:
            return []
        words = [f'{self.names[i]} {self.refused_tau[i]:.4g}' if self.effort_refused[i]
                 else f'{self.names[i]} not reported' for i in missing[:6]]
        more = f' and {len(missing) - 6} more' if len(missing) > 6 else ''
        return [f'joint efforts refused: {", ".join(words)}{more} (the feet without force '
                'sensors take their contact from the leg efforts)']

    def never_received(self) -> list[str]:
        return [self.names[i] for i in np.flatnonzero(~self.received)]

    def faults(self, stamp_ns: int, config: SyncConfig, max_step_ns: Optional[int] = None
               ) -> list[str]:
        """Why the joints cannot be used at ``stamp_ns`` (empty when they can); ``max_step_ns``:
        joints stamped further than this ahead of it are on another clock's timeline."""
        out = []
        if max_step_ns is not None and self.newest_stamp_ns - stamp_ns > max_step_ns:
            ahead_s = (self.stamp_ns - stamp_ns) / NS_PER_S
            ahead = self.received & (ahead_s > max_step_ns / NS_PER_S)
            if np.count_nonzero(ahead):
                out.append(_joint_list(f'stamped {ahead_s[ahead].max():.3f} s ahead of this sample '
                                       '(their clock and the driving one differ)',
                                       [self.names[i] for i in np.flatnonzero(ahead)]))
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
        self._flags = []
        if self.bounds is not None and not out:
            # The impossible lies beyond the flagged: one test per sample while nothing is past.
            self._flags = self.bounds.exceedances(self.q, self.dq)
            if self._flags:
                out.extend(self.bounds.violations(self.q, self.dq))
        return out

    def flags(self) -> list[str]:
        """Of the sample :meth:`faults` last judged usable: its joints past their limits or speed
        but possible, in words (kept and flagged: :mod:`~fall_predictor.monitor.plausibility`)."""
        return self._flags


def _joint_list(what: str, names: list[str]) -> str:
    return f'joint{"s" if len(names) > 1 else ""} {bound_names(names)} {what}'
