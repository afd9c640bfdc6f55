"""The push protocol of method §3: a random gait, then a random push at a random instant of its
walk cycle."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fall_predictor.profiles import load_profile
from fall_predictor.robot.controllers import GaitConfig, controller_configs
from fall_predictor.monitor.records import PUSH_DURATION_S, PushSpec


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
