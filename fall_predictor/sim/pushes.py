"""The push protocol of SPEC §3: random pushes at random instants of the walk cycle."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fall_predictor.robot.controllers import GaitConfig
from fall_predictor.monitor.records import PUSH_DURATION_S, PushSpec


@dataclass(frozen=True)
class PushDistribution:
    """SPEC §3 ranges. The onset is drawn uniformly over one full walk cycle (two steps)
    starting ``settle_s`` into the walk, when the gait has reached its periodic pattern."""

    force_n: tuple[float, float] = (0.0, 500.0)
    angle_deg: tuple[float, float] = (-180.0, 180.0)
    height_m: tuple[float, float] = (-0.05, 0.25)
    settle_s: float = 2.1
    duration_s: float = PUSH_DURATION_S

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

    def onset(self, rng: np.random.Generator, gait: GaitConfig = GaitConfig()) -> float:
        return round(self.settle_s + rng.uniform(0.0, self.walk_cycle_s(gait)), 3)


def trajectory_seed(dataset_seed: int, index: int) -> np.random.Generator:
    """The random generator of trajectory ``index`` of a dataset: independent of how many
    trajectories are generated, in which order, or by how many processes."""
    return np.random.default_rng([dataset_seed, index])
