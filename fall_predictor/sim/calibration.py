"""The push range of a robot and its controller, calibrated on its own runs (method §3, §13).

A dataset's pushes are drawn uniformly up to a largest force; about half of its runs should fall,
so that the model sees both outcomes near the boundary. That force belongs to the robot *and* its
controller (a learned policy recovers from pushes that fell C_bal three times over). The
calibration runs ``trajectories`` pushes of the dataset protocol (the controller's commanded
velocities or gaits, directions, heights, onsets over the walk cycle), their forces drawn up to a
probe force, estimates the fall probability by force band, and gives the largest force whose
uniform range makes the wanted fall fraction (bands beyond the probe taken as the last band).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Optional, Sequence

import numpy as np

from fall_predictor.profiles.profile import RobotProfile, load_profile
from fall_predictor.sim.pushes import PushDistribution, robot_gait, trajectory_seed


#: The default probe: pushes up to this many newtons per kilogram of robot (3 N s/kg for 0.1 s;
#: C_bal's robots fall from about 1 N s/kg, Unitree's policy survives 1.5 N s/kg).
PROBE_FORCE_N_PER_KG = 30.0


@dataclass(frozen=True)
class CalibrationSetup:
    """The robot, its controller and simulator (None: the profile's), the probe force [N]
    (forces drawn uniformly up to it), the seed and the horizon after the push [s]."""

    robot: str
    controller: Optional[str]
    simulator: Optional[str]
    probe_force_n: float
    seed: int = 0
    horizon_s: float = 4.0


def _run(setup: CalibrationSetup, index: int) -> dict:
    """One calibration run: its force, outcome and push-to-fall time."""
    from fall_predictor.profiles.profile import C_BAL
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.policy_runs import commanded_pushes, physics_dt_s
    from fall_predictor.sim.sensors import SensorParams, SensorSuite
    from fall_predictor.sim.trajectory import run_trajectory

    profile = load_profile(setup.robot)
    policy = profile.controller_profile(setup.controller)
    rng = trajectory_seed(setup.seed, index)
    world = _world(profile, setup, physics_dt_s(policy))
    if policy is None:
        dist = replace(PushDistribution.for_robot(profile), force_n=(0.0, setup.probe_force_n))
        if profile.gait_variety:
            gait, push = dist.sample_with_gait(rng)
        else:
            gait, push = None, dist.sample(rng, robot_gait(setup.robot))
        controller = make_controller(profile, C_BAL, dt_s=world.dt_s,
                                     walk_duration_s=push.t_push + 20.0, gait=gait)
        command, sensors = None, None
    else:
        probed = replace(policy, push_force_n=(0.0, setup.probe_force_n))
        command, push = commanded_pushes(probed).sample(rng)
        controller = make_controller(profile, setup.controller, command)
        sensors = SensorSuite(SensorParams(), seed=index, dt_s=world.dt_s, profile=profile)
    result = run_trajectory(push, push.t_force_end + setup.horizon_s, world=world,
                            controller=controller, sensors=sensors)
    return {'index': index, 'force_n': push.force_n, 'angle_deg': push.angle_deg,
            'impulse_ns': push.impulse_ns, 'command': None if command is None else list(command),
            'fallen': result.fallen,
            'push_to_fall_s': None if not result.fallen else result.t_fallen - push.t_push}


_WORLDS: dict = {}


def _world(profile: RobotProfile, setup: CalibrationSetup, dt_s: Optional[float]):
    from fall_predictor.sim.world import make_world
    key = (setup.robot, setup.simulator, dt_s)
    if key not in _WORLDS:
        _WORLDS[key] = make_world(profile, setup.simulator, dt_s)
    return _WORLDS[key]


def calibration_run(item: tuple[CalibrationSetup, int]) -> dict:
    """``_run`` for a parallel map (one argument)."""
    return _run(*item)


def suggest_force_range(rows: Sequence[dict], target_fall_fraction: float = 0.5,
                        bands: int = 10) -> dict:
    """The fall probability by force band of ``rows`` and the largest force F whose uniform range
    [0, F] is predicted to fell ``target_fall_fraction`` of the runs (each band's probability made
    non-decreasing with force, as falls are more likely with more force; bands beyond the probe:
    the last band's)."""
    forces = np.array([r['force_n'] for r in rows])
    fallen = np.array([r['fallen'] for r in rows], dtype=float)
    probe = float(forces.max()) if len(forces) else 0.0
    edges = np.linspace(0.0, probe, bands + 1)
    index = np.clip(np.digitize(forces, edges) - 1, 0, bands - 1)
    counts = np.bincount(index, minlength=bands)
    falls = np.bincount(index, weights=fallen, minlength=bands)
    raw = np.divide(falls, counts, out=np.full(bands, np.nan), where=counts > 0)
    smooth = np.maximum.accumulate(np.nan_to_num(raw, nan=0.0))
    width = edges[1] - edges[0] if bands else 0.0
    best, best_gap, predicted = probe, math.inf, None
    for k in range(1, 4 * bands + 1):
        upper = k * width
        probability = np.concatenate([smooth, np.full(max(0, k - bands), smooth[-1])])[:k]
        fraction = float(probability.mean())
        if abs(fraction - target_fall_fraction) < best_gap:
            best, best_gap, predicted = upper, abs(fraction - target_fall_fraction), fraction
    delays = [r['push_to_fall_s'] for r in rows if r['fallen']]
    return {'runs': len(rows), 'fall_fraction': float(fallen.mean()) if len(rows) else None,
            'probe_force_n': probe,
            'fall_probability_by_force': [
                {'force_n': [float(edges[i]), float(edges[i + 1])], 'runs': int(counts[i]),
                 'fall_fraction': None if counts[i] == 0 else float(raw[i])} for i in range(bands)],
            'suggested_push_force_n': [0.0, round(float(best), 1)],
            'predicted_fall_fraction': predicted,
            'push_to_fall_s_median': float(np.median(delays)) if delays else None}


def calibrate(setup: CalibrationSetup, trajectories: int,
              map_fn: Optional[Callable[[Callable, Sequence], list]] = None,
              target_fall_fraction: float = 0.5) -> dict:
    """Run ``trajectories`` calibration pushes (``map_fn(function, items)``: a parallel map, or
    ``map``) and suggest the push range (:func:`suggest_force_range`)."""
    items = [(setup, i) for i in range(trajectories)]
    rows = list(map_fn(calibration_run, items) if map_fn else map(calibration_run, items))
    return {'setup': {'robot': setup.robot, 'controller': setup.controller,
                      'simulator': setup.simulator, 'seed': setup.seed,
                      'probe_force_n': setup.probe_force_n, 'horizon_s': setup.horizon_s},
            **suggest_force_range(rows, target_fall_fraction), 'rows': rows}
