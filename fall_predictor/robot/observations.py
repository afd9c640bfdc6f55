"""The observation a learned walking policy takes: the robot's sensors as its training made them.

A policy trained in legged_gym or humanoid-gym reads a vector of scaled terms in a fixed order
(:class:`~fall_predictor.robot.policy_config.PolicyConfig` says which): the base's angular
velocity and attitude as the robot's IMU gives them, the velocity command, the joints relative
to the default posture, their velocities, the previous action, the gait clock. Each term here is
computed as those projects' deploy scripts compute it:

* ``base_ang_vel``: the IMU's angular velocity, in the base (pelvis) frame [rad/s] x scale;
* ``projected_gravity``: the unit gravity direction in the base frame, ``R^T (0, 0, -1)`` for the
  base attitude ``R`` (IMU quaternion x, y, z, w, base to world): (0, 0, -1) upright;
* ``base_euler_xyz``: roll, pitch, yaw of the base [rad] (``R = Rz(yaw) Ry(pitch) Rx(roll)``, as
  humanoid-gym's sim2sim converts its IMU quaternion), x scale;
* ``command``: (vx [m/s], vy [m/s], yaw rate [rad/s]) x scale;
* ``joint_pos``: (q - default angles) x scale (or q x scale: ``relative_to_default: false``);
* ``joint_vel``: dq x scale; ``last_action``: the previous action (the network's output) x scale;
* ``gait_phase_sin_cos``: sin and cos of 2 pi t / period, t the gait clock's time [s];
* ``gait_clock``: the same two values in its ``order`` (sin, cos or cos, sin) of the phase
  t / period + ``offset`` (a fraction of a cycle); ``gait_phase``: that phase itself, in [0, 1).
  At a command whose norm is at most ``standing_below`` the clock runs on (``run``), its values
  are zero with the phase held (``zero``), the phase is held (``hold``), or back at 0 and restarts
  from there (``reset``); a held phase goes on from where it stopped.

A term with ``clip`` is clipped to [low, high] after its scale.

The frame is clipped to +-``clip_observations`` when set, and the last ``frame_stack`` frames are
stacked oldest first (zeros before the first, as humanoid-gym's history starts).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from fall_predictor.robot.policy_config import PolicyConfig


def projected_gravity(quat_xyzw: Sequence[float]) -> tuple[float, float, float]:
    """The unit gravity direction (0, 0, -1) of the world, in the frame whose attitude is the unit
    quaternion ``quat_xyzw`` (that frame to the world): minus the last row of its rotation matrix."""
    x, y, z, w = quat_xyzw
    return (2.0 * (w * y - x * z), -2.0 * (y * z + w * x), 2.0 * (x * x + y * y) - 1.0)


def euler_xyz(quat_xyzw: Sequence[float]) -> tuple[float, float, float]:
    """Roll, pitch, yaw [rad] of a unit quaternion: ``R = Rz(yaw) Ry(pitch) Rx(roll)``; pitch in
    [-pi/2, pi/2], roll and yaw in [-pi, pi]."""
    x, y, z, w = quat_xyzw
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


class ObservationBuilder:
    """Builds the network input of one policy step (see the module docstring).

    Each term is written straight into its view of a preallocated float64 frame, rounded once to
    the network's float32 when stacked: a term costs about a microsecond."""

    def __init__(self, config: PolicyConfig) -> None:
        self.config = config
        self.num_joints = n = config.num_actions
        self._default = np.asarray(config.default_angles_rad, dtype=np.float64)
        self._joints = np.zeros(n)
        size = config.single_obs_size
        self._frame = np.zeros(size)
        self._stack = np.zeros((config.frame_stack, size), np.float32)
        self._clip = config.clip_observations
        self._terms: list[tuple[str, np.ndarray, np.ndarray, object]] = []
        self._clips: list[tuple[np.ndarray, float, float]] = []
        self._clocks: list[_Clock] = []
        start = 0
        for term in config.observation:
            end = start + term.size(n)
            scale = np.broadcast_to(np.asarray(term.scale, dtype=np.float64), (end - start,)).copy()
            extra: object = term.relative_to_default if term.name == 'joint_pos' else term.period_s
            if term.name in ('gait_clock', 'gait_phase'):
                extra = _Clock(term)
                self._clocks.append(extra)
            self._terms.append((term.name, self._frame[start:end], scale, extra))
            if term.clip is not None:
                self._clips.append((self._frame[start:end], *term.clip))
            start = end

    @property
    def size(self) -> int:
        """The network input's length: one frame x frame_stack."""
        return int(self._stack.size)

    def reset(self) -> None:
        """Forget the stacked history (zeros) and restart the gait clocks."""
        self._stack[:] = 0.0
        for clock in self._clocks:
            clock.reset()

    def build(self, t_s: float, imu_quat_xyzw: Sequence[float], gyro_rad_s: Sequence[float],
              q: np.ndarray, dq: np.ndarray, command: Sequence[float], last_action: np.ndarray) -> np.ndarray:
        """The network input (float32, a new array): one frame from these readings, clipped,
        after the previous ``frame_stack - 1`` frames. ``t_s`` is the gait clock's time [s]; q, dq
        and last_action are in the policy's joint order."""
        n = self.num_joints
        if not (len(q) == len(dq) == len(last_action) == n and len(command) == 3
                and len(imu_quat_xyzw) == 4 and len(gyro_rad_s) == 3):
            raise ValueError(f'observation: expected q, dq and last_action of {n} values, a command of 3, '
                             f'a quaternion of 4 and a gyro of 3; got {len(q)}, {len(dq)}, '
                             f'{len(last_action)}, {len(command)}, {len(imu_quat_xyzw)}, {len(gyro_rad_s)}')
        for name, view, scale, extra in self._terms:
            if name == 'base_ang_vel':
                np.multiply(gyro_rad_s, scale, out=view)
            elif name == 'projected_gravity':
                view[:] = projected_gravity(_unit(imu_quat_xyzw))
                view *= scale
            elif name == 'base_euler_xyz':
                view[:] = euler_xyz(_unit(imu_quat_xyzw))
                view *= scale
            elif name == 'command':
                np.multiply(command, scale, out=view)
            elif name == 'joint_pos':
                if extra:
                    np.multiply(np.subtract(q, self._default, out=self._joints), scale, out=view)
                else:
                    np.multiply(q, scale, out=view)
            elif name == 'joint_vel':
                np.multiply(dq, scale, out=view)
            elif name == 'last_action':
                np.multiply(last_action, scale, out=view)
            elif name == 'gait_phase_sin_cos':
                angle = 2.0 * math.pi * (t_s % extra) / extra
                view[0] = math.sin(angle) * scale[0]
                view[1] = math.cos(angle) * scale[1]
            else:                                       # gait_clock, gait_phase
                extra.write(view, t_s, command)
                view *= scale
        for view, low, high in self._clips:
            np.clip(view, low, high, out=view)
        frame = self._frame
        if self._clip is not None:
            np.clip(frame, -self._clip, self._clip, out=frame)
        stack = self._stack
        if len(stack) > 1:
            stack[:-1] = stack[1:]
        stack[-1] = frame
        return stack.reshape(-1).copy()


class _Clock:
    """A gait clock term's phase through standing and walking (module docstring)."""

    def __init__(self, term) -> None:
        self.term = term
        self.reset()

    def reset(self) -> None:
        self._last_t: float | None = None
        self._clock_s = 0.0                 #: the clock's own time [s]: t, less what was held

    def write(self, view: np.ndarray, t_s: float, command: Sequence[float]) -> None:
        term = self.term
        step = 0.0 if self._last_t is None else t_s - self._last_t
        self._last_t = t_s
        standing = (term.when_standing != 'run'
                    and math.hypot(*(float(c) for c in command)) <= term.standing_below)
        if not standing:
            self._clock_s += step
        elif term.when_standing == 'reset':
            self._clock_s = 0.0
        clock_s = t_s if term.when_standing == 'run' else self._clock_s
        phase = (clock_s % term.period_s / term.period_s + term.offset) % 1.0
        if term.name == 'gait_phase':
            view[0] = 0.0 if standing and term.when_standing == 'zero' else phase
            return
        if standing and term.when_standing == 'zero':
            view[:] = 0.0
            return
        angle = 2.0 * math.pi * phase
        first, second = math.sin(angle), math.cos(angle)
        view[0], view[1] = (first, second) if term.order == 'sin_cos' else (second, first)


def _unit(quat_xyzw: Sequence[float]) -> tuple[float, float, float, float]:
    x, y, z, w = (float(v) for v in quat_xyzw)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not norm > 0.0:
        raise ValueError(f'observation: the IMU quaternion {tuple(quat_xyzw)} is not a rotation')
    return x / norm, y / norm, z / norm, w / norm
