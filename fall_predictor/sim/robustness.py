"""Push robustness of a robot under its controller: which impulses, from which directions, at which
gait phases, it survives (the robustness tables in docs/results.md).

Every push is the method §3 push (a constant horizontal force for 0.1 s on the torso) with the
impulse, direction and onset on a grid: the onset at ``k / n_phases`` of one walk cycle after the
gait has settled (C_bal's gait cycle, two steps; a learned policy's gait clock, walking at a
given command after its settling time). A push is survived when the robot has not fallen
``horizon_s`` after it ends.
"""
from __future__ import annotations

import threading
from dataclasses import asdict, dataclass
from typing import Callable, Optional, Sequence

import numpy as np

from fall_predictor.monitor.records import PUSH_DURATION_S, PushSpec
from fall_predictor.sim.pushes import PushDistribution, robot_gait


@dataclass(frozen=True)
class RobustnessGrid:
    impulses_ns: tuple[float, ...] = tuple(float(i) for i in range(5, 55, 5))
    #: Push directions from the robot's heading, counter-clockwise seen from above [deg]:
    #: 0 pushes forward, 90 to the robot's left, 180 backward.
    directions_deg: tuple[float, ...] = (0.0, 45.0, 90.0, 135.0, 180.0, -135.0, -90.0, -45.0)
    n_phases: int = 8
    height_m: float = 0.1            #: application height above the CoM (mid method §3 range)
    horizon_s: float = 3.0
    #: The robot (a profile's name or path), its walking controller (None: the profile's) and the
    #: simulator (None: the profile's); a learned policy walks at ``command`` (vx, vy, yaw rate).
    robot: str = 'asimo_like'
    controller: Optional[str] = None
    simulator: Optional[str] = None
    command: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not self.impulses_ns or min(self.impulses_ns) <= 0:
            raise ValueError('impulses must be positive')
        if self.n_phases < 1 or not self.directions_deg or self.horizon_s <= 0:
            raise ValueError('need at least one phase and one direction, and a positive horizon')

    def walk(self) -> tuple[float, float, float]:
        """(settling time [s], walk cycle [s], physics step [s]) of the robot's controller."""
        from fall_predictor.profiles.profile import load_profile
        from fall_predictor.sim.policy_runs import commanded_pushes
        profile = load_profile(self.robot)
        policy = profile.controller_profile(self.controller)
        if policy is None:
            dist = PushDistribution()
            return dist.settle_s, dist.walk_cycle_s(robot_gait(self.robot)), 0.001
        pushes = commanded_pushes(policy)
        return policy.settle_s, pushes.cycle_s, pushes.dt_s

    def pushes(self) -> list[tuple[int, int, int, PushSpec]]:
        """(impulse index, direction index, phase index, push) for every cell of the grid."""
        settle_s, cycle, dt_s = self.walk()
        out = []
        for k in range(self.n_phases):
            onset = round(round((settle_s + cycle * k / self.n_phases) / dt_s) * dt_s, 6)
            for d, angle in enumerate(self.directions_deg):
                for i, impulse in enumerate(self.impulses_ns):
                    out.append((i, d, k, PushSpec(impulse / PUSH_DURATION_S, angle, self.height_m, onset)))
        return out


def survival_table(grid: RobustnessGrid, survived: np.ndarray) -> dict:
    """Summary of a (impulse, direction, phase) boolean array of survived pushes.

    Returns per direction the largest impulse survived at every phase (with every smaller
    impulse of the grid also survived at that phase), the survival fraction per impulse, and
    whether the robot's aims hold (15 N s everywhere; 30 N s forward and backward at every
    phase), None where the grid lacks that impulse.
    """
    impulses = np.array(grid.impulses_ns)
    per_direction = {}
    for d, angle in enumerate(grid.directions_deg):
        # Survived at every phase up to and including this impulse.
        ok = np.logical_and.accumulate(survived[:, d, :].all(axis=1))
        per_direction[f'{angle:g}'] = float(impulses[ok][-1]) if ok.any() else 0.0
    fraction = {f'{impulse:g}': float(survived[i].mean()) for i, impulse in enumerate(impulses)}
    # An aim is judged only when the grid holds its impulse (None otherwise).
    everywhere_15 = bool(survived[impulses <= 15.0].all()) if 15.0 in impulses else None
    sagittal = [d for d, a in enumerate(grid.directions_deg) if a % 180.0 == 0.0]
    sagittal_30 = (bool(survived[np.ix_(impulses <= 30.0, sagittal)].all())
                   if 30.0 in impulses and sagittal else None)
    return {'largest_impulse_survived_at_every_phase_ns': per_direction,
            'survival_fraction_by_impulse': fraction,
            'aim_15_ns_everywhere': everywhere_15,
            'aim_30_ns_forward_backward': sagittal_30}


def run_robustness(grid: RobustnessGrid = RobustnessGrid(),
                   map_fn: Optional[Callable[[Callable, Sequence], list]] = None) -> dict:
    """Simulate every push of ``grid`` with the default gait and summarise.

    Args:
        grid: the impulses, directions and phases.
        map_fn: ``map_fn(function, items) -> list`` to run the trajectories in parallel; plain
            ``map`` (one process) if None.
    """
    cells = grid.pushes()
    setup = (grid.robot, grid.controller, grid.simulator, tuple(grid.command))
    items = [(grid.horizon_s, push, setup) for *_, push in cells]
    results = list(map_fn(survives, items) if map_fn else map(survives, items))
    survived = np.zeros((len(grid.impulses_ns), len(grid.directions_deg), grid.n_phases), dtype=bool)
    for (i, d, k, _), ok in zip(cells, results):
        survived[i, d, k] = ok
    return {'grid': asdict(grid), 'survived': survived.astype(int).tolist(),
            **survival_table(grid, survived)}


_WORKER = threading.local()


def survives(item: tuple) -> bool:
    """Whether the robot survives ``push``: item = (horizon [s], push, (robot, controller,
    simulator, command)). C_bal walks its default gait (one walk per worker thread, simulated once
    and restored from snapshots); a learned policy walks from a fresh world every time (its
    recurrent state and live sensors start with the run)."""
    from fall_predictor.profiles.profile import load_profile
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.policy_runs import physics_dt_s
    from fall_predictor.sim.trajectory import WalkPrefix, run_trajectory
    from fall_predictor.sim.world import make_world

    horizon_s, push, (robot, controller, simulator, command) = item
    profile = load_profile(robot)
    policy = profile.controller_profile(controller)
    key = (robot, controller, simulator)
    cache = getattr(_WORKER, 'cache', None)
    if cache is None or cache[0] != key:
        world = make_world(profile, simulator, physics_dt_s(policy))
        if policy is None:
            dist = PushDistribution()
            until = dist.settle_s + dist.walk_cycle_s(robot_gait(robot)) + 0.01
            cache = (key, WalkPrefix(world, until_s=until, walk_duration_s=until + 60.0), None)
        else:
            cache = (key, world, make_controller(profile, controller, command))
        _WORKER.cache = cache
    if policy is None:
        result = run_trajectory(push, push.t_force_end + horizon_s, prefix=cache[1])
    else:
        control = cache[2]
        control.velocity_command = tuple(command)
        control.policy.reset()
        result = run_trajectory(push, push.t_force_end + horizon_s, world=cache[1],
                                controller=control)
    return not result.fallen
