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

import math
from typing import Optional, Sequence

import numpy as np

from fall_predictor.monitor.plausibility import MAX_NAME_CHARS, JointBounds, check_imu, check_wrench
from fall_predictor.monitor.sensor_records import (ImuReading, JointStateReading, SensorSample,
                                                   WrenchReading)
# The per-stream state, re-exported: SyncConfig, StreamBuffer and JointTable live there.
from fall_predictor.monitor.sensor_streams import (SIDES, JointTable, StreamBuffer,  # noqa: F401
                                                   SyncConfig)
from fall_predictor.monitor.timeline import NS_PER_S, TimelineConfig


def _frame_problem(frame_id: str) -> Optional[str]:
    """Why a reading's frame cannot be a frame of the robot description, or None."""
    if len(frame_id) > MAX_NAME_CHARS:
        return f'a frame_id of {len(frame_id)} characters (at most {MAX_NAME_CHARS} are read)'
    return None


class SensorSync:
    """Merges joint states, IMU and foot wrenches into :class:`SensorSample` s (module docstring).

    ``joint_names``: the joints of the robot description, in the estimator's order;
    ``force_sensors``: the sides ('l', 'r') that have a foot force/torque sensor;
    ``robot_weight_n``: for the wrench bounds; ``topics``: the resolved topic names, for the words
    of the faults (keys 'joints', 'imu', 'l', 'r'); ``timeline``: the time rule each stream's
    readings follow (a step of a stream's clock starts its buffer again); ``effort_joints``: the
    joints whose efforts feed the estimate (the legs of the feet without force sensors): a sample
    whose effort of one of them was refused, or not reported by a driver that reports them, is not
    made.
    """

    def __init__(self, joint_names: Sequence[str], force_sensors: Sequence[str] = SIDES,
                 robot_weight_n: float = 1000.0, config: SyncConfig = SyncConfig(),
                 bounds: Optional[JointBounds] = None,
                 topics: Optional[dict[str, str]] = None,
                 timeline: TimelineConfig = TimelineConfig(),
                 effort_joints: Sequence[str] = ()) -> None:
        self.config = config
        self.joints = JointTable(joint_names, bounds)
        index = {name: i for i, name in enumerate(self.joints.names)}
        self._effort_joints = np.array([index[name] for name in effort_joints], dtype=np.int64)
        self._max_step_ns = round(timeline.max_step_s * NS_PER_S)
        #: Streams whose clock stepped on their own since the last :meth:`take_steps`:
        #: (stream, step [s]).
        self.steps: list[tuple[str, float]] = []
        self.force_sensors = tuple(force_sensors)
        self.robot_weight_n = robot_weight_n
        self.topics = {'joints': '/joint_states', 'imu': '/imu/data', 'l': '/left_foot/wrench',
                       'r': '/right_foot/wrench', **(topics or {})}
        self._tolerance_ns = round(config.tolerance_s * NS_PER_S)
        self.imu = StreamBuffer(config.buffer_readings, timeline)
        self.wrenches = {side: StreamBuffer(config.buffer_readings, timeline)
                         for side in self.force_sensors}
        self.imu_frame = ''
        self.wrench_frames = {side: '' for side in SIDES}
        #: Per stream: (stamp [ns], reason) of the latest reading refused as implausible.
        self.refused: dict[str, tuple[int, str]] = {}
        self.counts = {'joint_messages': 0, 'imu_readings': 0, 'wrench_readings': 0,
                       'refused_readings': 0, 'refused_efforts': 0, 'sensor_clock_steps': 0}

    def reset(self) -> None:
        """Forget the IMU and wrench readings (a new run); joint values stay (they are absolute)."""
        self.imu.clear()
        for buffer in self.wrenches.values():
            buffer.clear()
        self.refused.clear()

    def _buffers(self) -> list[tuple[str, StreamBuffer]]:
        return [('imu', self.imu), *self.wrenches.items()]

    def follow(self, anchor_ns: int) -> list[str]:
        """The driving stream started a new run at ``anchor_ns`` (its clock stepped): every other
        stream starts again from its readings on the new timeline, or from none
        (:meth:`StreamBuffer.follow`); the joints' stuck clocks start again. Returns the streams
        whose readings showed that their clock stepped with the driving one's."""
        self.joints.new_run(anchor_ns)
        with_it = []
        for stream, buffer in self._buffers():
            held = buffer.holds_readings_near(anchor_ns)
            if buffer.follow(anchor_ns) and held:
                self.counts['sensor_clock_steps'] += 1
                with_it.append(stream)
        self.refused.clear()
        return with_it

    def take_steps(self) -> list[tuple[str, float]]:
        """The streams whose clock stepped on their own since the last call: (stream, step [s])."""
        out, self.steps = self.steps, []
        return out

    def _added(self, stream: str, buffer: StreamBuffer, stepped: bool) -> None:
        if stepped:
            self.counts['sensor_clock_steps'] += 1
            self.steps.append((stream, buffer.clock.last_step_s))

    def _refuse(self, stream: str, stamp_ns: int, reason: str) -> None:
        self.refused[stream] = (stamp_ns, reason)
        self.counts['refused_readings'] += 1

    def add_joint_state(self, reading: JointStateReading) -> list[str]:
        """One joint state message; returns newly seen joint names the description lacks."""
        self.counts['joint_messages'] += 1
        unknown = self.joints.update(reading)
        self.counts['refused_efforts'] = self.joints.refused_efforts
        return unknown

    def add_imu(self, reading: ImuReading) -> None:
        reason = _frame_problem(reading.frame_id) or check_imu(
            reading.orientation_xyzw, reading.angular_velocity, reading.linear_acceleration)
        if reason is not None:
            self._refuse('imu', reading.stamp_ns, reason)
            return
        self.counts['imu_readings'] += 1
        quat = np.asarray(reading.orientation_xyzw, dtype=float)
        previous = self.imu.newest
        if previous is not None and float(previous[:4] @ quat) < 0.0:
            quat = -quat                    # the same attitude: keep the sign for interpolation
        self.imu_frame = reading.frame_id
        values = np.concatenate([quat, np.asarray(reading.angular_velocity, dtype=float),
                                 np.asarray(reading.linear_acceleration, dtype=float)])
        self._added('imu', self.imu, self.imu.add(reading.stamp_ns, values))

    def add_wrench(self, side: str, reading: WrenchReading) -> None:
        if side not in self.wrenches:
            return                          # a foot without a configured sensor: not used
        reason = _frame_problem(reading.frame_id) or check_wrench(reading.wrench, self.robot_weight_n)
        if reason is not None:
            self._refuse(side, reading.stamp_ns, reason)
            return
        self.counts['wrench_readings'] += 1
        self.wrench_frames[side] = reading.frame_id
        buffer = self.wrenches[side]
        self._added(side, buffer, buffer.add(reading.stamp_ns, np.asarray(reading.wrench, dtype=float)))

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
        lag_ns = stamp_ns - buffer.newest_ns
        if abs(lag_ns) > self._max_step_ns:     # not late: on another timeline
            return (f'no {self.topics[stream]} {within} (its stamps are {abs(lag_ns) / NS_PER_S:.3f} s '
                    f'{"behind" if lag_ns > 0 else "ahead of"} {self.topics[driving]}: the clocks differ)')
        if lag_ns < 0:
            return f'no {self.topics[stream]} {within} (the nearest {-lag_ns / 1e6:.0f} ms newer)'
        return f'no {self.topics[stream]} {within} (newest {lag_ns / 1e6:.0f} ms older)'

    def sample_at(self, stamp_ns: int, t: float, driving: str = 'joints'
                  ) -> tuple[Optional[SensorSample], list[str]]:
        """The sample at a driving message's ``stamp_ns`` (run time ``t`` [s]) and its faults; the
        sample is None when there are any (module docstring)."""
        faults = self.joints.faults(stamp_ns, self.config, self._max_step_ns)
        if self._effort_joints.size:
            faults += self.joints.effort_faults(self._effort_joints)
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
