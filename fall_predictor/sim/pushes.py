"""The push protocol of method §3: a random gait (C_bal) or a random commanded velocity (a learned
policy), then a random push at a random instant of its walk cycle."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from fall_predictor.profiles.profile import load_profile
from fall_predictor.profiles.profile import PolicyControllerProfile
from fall_predictor.robot.balance_controller import GaitConfig, controller_configs
from fall_predictor.monitor.records import PUSH_DURATION_S, PushSpec


def checked_force_range(low: float, high: float) -> tuple[float, float]:
    """``(low, high)`` as a push force range [N] a dataset can draw from uniformly: two finite
    numbers, ``0 <= low <= high`` (ValueError saying which is wrong)."""
    low, high = float(low), float(high)
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ValueError(f'push force range [{low:g}, {high:g}] N: both ends must be finite numbers')
    if low < 0.0:
        raise ValueError(f'push force range [{low:g}, {high:g}] N: the low end must be >= 0 '
                         '(a push\'s direction is drawn separately)')
    if low > high:
        raise ValueError(f'push force range [{low:g}, {high:g}] N: the low end must not exceed the high one')
    return low, high


@dataclass(frozen=True)
class PushDistribution:
    """method §3 ranges. The onset is drawn uniformly over one full walk cycle (two steps)
    starting ``settle_s`` into the walk, when the gait has reached its periodic pattern."""

    force_n: tuple[float, float] = (0.0, 500.0)
    angle_deg: tuple[float, float] = (-180.0, 180.0)
    height_m: tuple[float, float] = (-0.05, 0.25)
    settle_s: float = 2.1
    duration_s: float = PUSH_DURATION_S
    #: Gait variety (method §3 amendment), drawn by :meth:`sample_with_gait` before the push:
    #: forward speed, single-support duration (double support fixed), step width between the
    #: sole centres, and the fraction of trajectories that stand still instead of walking.
    gait_speed_m_s: tuple[float, float] = (0.0, 0.25)
    gait_single_support_s: tuple[float, float] = (0.45, 0.7)
    gait_double_support_s: float = 0.2
    gait_step_width_m: tuple[float, float] = (0.16, 0.22)
    standing_fraction: float = 0.1

    @classmethod
    def for_robot(cls, profile) -> 'PushDistribution':
        """The protocol's distribution with the robot profile's force range."""
        return cls(force_n=tuple(profile.push_force_n))

    def walk_cycle_s(self, gait: GaitConfig = GaitConfig()) -> float:
        return 2.0 * (gait.single_support_s + gait.double_support_s)

    def sample(self, rng: np.random.Generator, gait: GaitConfig = GaitConfig()) -> PushSpec:
        """One push; the order of draws is fixed so a seed always gives the same push."""
        force = rng.uniform(*self.force_n)
        angle = rng.uniform(*self.angle_deg)
        height = rng.uniform(*self.height_m)
        onset = self.settle_s + rng.uniform(0.0, self.walk_cycle_s(gait))
        # Onsets on the 1 ms simulation grid, so a push starts exactly at a step.
        return PushSpec(force_n=float(force), angle_deg=float(angle), height_m=float(height),
                        t_push=round(onset, 3), duration_s=self.duration_s)

    def sample_gait(self, rng: np.random.Generator) -> GaitConfig:
        """One gait of the method §3 amendment (speed 0 steps in place); fixed order of draws."""
        speed = rng.uniform(*self.gait_speed_m_s)
        single = rng.uniform(*self.gait_single_support_s)
        width = rng.uniform(*self.gait_step_width_m)
        standing = bool(rng.uniform() < self.standing_fraction)
        cycle_half_s = single + self.gait_double_support_s
        return replace(GaitConfig(), single_support_s=float(single),
                       double_support_s=self.gait_double_support_s,
                       step_length_m=float(speed * cycle_half_s), stance_half_width_m=float(width / 2),
                       standing=standing)

    def sample_with_gait(self, rng: np.random.Generator) -> tuple[GaitConfig, PushSpec]:
        """The gait of a trajectory, then its push, the onset uniform over one cycle of that gait."""
        gait = self.sample_gait(rng)
        return gait, self.sample(rng, gait)

    def onset(self, rng: np.random.Generator, gait: GaitConfig = GaitConfig()) -> float:
        return round(self.settle_s + rng.uniform(0.0, self.walk_cycle_s(gait)), 3)


def robot_gait(robot: str) -> GaitConfig:
    """The gait robot ``robot`` (a profile's name or path) walks when a dataset draws none: its
    profile's. A push onset is drawn over one cycle of it."""
    return controller_configs(load_profile(robot))[0]


def trajectory_seed(dataset_seed: int, index: int) -> np.random.Generator:
    """The random generator of trajectory ``index`` of a dataset: independent of how many
    trajectories are generated, in which order, or by how many processes."""
    return np.random.default_rng([dataset_seed, index])


@dataclass(frozen=True)
class CommandedPushes:
    """method §3 for a learned walking policy: each run draws its commanded velocity (vx, vy, yaw
    rate, uniform over the controller's ranges), walks ``settle_s`` at it, and is pushed at an
    instant drawn uniformly over one period of the policy's gait clock (1 s for a policy without
    one), with the protocol's force (the controller's range), direction and height draws. Onsets
    lie on the simulation's step grid (``dt_s``)."""

    controller: PolicyControllerProfile
    cycle_s: float
    dt_s: float
    angle_deg: tuple[float, float] = (-180.0, 180.0)
    height_m: tuple[float, float] = (-0.05, 0.25)
    duration_s: float = PUSH_DURATION_S

    def sample(self, rng: np.random.Generator) -> tuple[tuple[float, float, float], PushSpec]:
        """(command, push); the order of draws is fixed so a seed always gives the same run."""
        c = self.controller.command
        command = (float(rng.uniform(*c.vx_m_s)), float(rng.uniform(*c.vy_m_s)),
                   float(rng.uniform(*c.yaw_rate_rad_s)))
        force = rng.uniform(*self.controller.push_force_n)
        angle = rng.uniform(*self.angle_deg)
        height = rng.uniform(*self.height_m)
        onset = self.controller.settle_s + rng.uniform(0.0, self.cycle_s)
        onset = round(round(onset / self.dt_s) * self.dt_s, 6)
        return command, PushSpec(force_n=float(force), angle_deg=float(angle), height_m=float(height),
                                 t_push=onset, duration_s=self.duration_s)

    def manifest(self) -> dict:
        """What a dataset records of the distribution."""
        c = self.controller
        return {'force_n': list(c.push_force_n), 'angle_deg': list(self.angle_deg),
                'height_m': list(self.height_m), 'settle_s': c.settle_s, 'cycle_s': self.cycle_s,
                'duration_s': self.duration_s, 'command_vx_m_s': list(c.command.vx_m_s),
                'command_vy_m_s': list(c.command.vy_m_s),
                'command_yaw_rate_rad_s': list(c.command.yaw_rate_rad_s)}


class PushProtocol:
    """The push of method §3, the same in every engine: a constant horizontal force of
    ``force_n`` for ``duration_s`` from ``t_push``, its direction fixed at the onset at
    ``angle_deg`` from the robot's heading, applied at a point fixed on the base, ``height_m``
    above the CoM on the base's vertical axis at the onset. The engine asks :meth:`force_at`
    every step and applies what it gets."""

    def __init__(self) -> None:
        self.push: Optional[PushSpec] = None
        self._direction = np.zeros(3)
        self._point_local = np.zeros(3)
        self._started = False

    def schedule(self, push: PushSpec) -> None:
        if not (math.isfinite(push.force_n) and push.force_n >= 0 and push.duration_s > 0):
            raise ValueError(f'invalid push {push}')
        self.push = push
        self._started = False

    def clear(self) -> None:
        self.push = None
        self._started = False

    def force_at(self, t: float, base_pos: np.ndarray, base_rot: np.ndarray,
                 com: Optional[np.ndarray]) -> Optional[tuple[np.ndarray, np.ndarray]]:
        """The world force [N] and its world application point [m] at time ``t``, or None when
        no push acts. ``base_pos``, ``base_rot``: the base's position and rotation; ``com``: the
        CoM of the previous sample (None: the base's position), read at the onset."""
        push = self.push
        if push is None or t < push.t_push - 1e-9:
            return None
        if t >= push.t_force_end - 1e-9:
            self.clear()
            return None
        if not self._started:
            # Onset: the direction in the heading frame, the point on the base's vertical axis.
            self._started = True
            heading = math.atan2(base_rot[1, 0], base_rot[0, 0])
            angle = heading + math.radians(push.angle_deg)
            self._direction = np.array([math.cos(angle), math.sin(angle), 0.0])
            z = (base_pos if com is None else com)[2]
            point = np.array([base_pos[0], base_pos[1], z + push.height_m])
            self._point_local = base_rot.T @ (point - np.asarray(base_pos))
        force = push.force_n * self._direction
        return force, np.asarray(base_pos) + base_rot @ self._point_local
