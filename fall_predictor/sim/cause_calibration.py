"""Each disturbance's range calibrated per robot and controller (method §3 for pushes; here for
the causes of sim/disturbances.py): runs of the dataset protocol with the cause's severity
(sim/disturbance_runs.SEVERITY: a trip's height, a slip's friction, a step's height, a fault's
remaining torque) drawn over a wide probe, the fall probability by severity band, and the range
from the probe's mild end whose uniform draws fell the wanted fraction (30–60 %). Where even the
severest band fells fewer than that, the cause cannot fell the robot within the probe, and the
summary says so.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Sequence

import numpy as np

from fall_predictor.profiles.profile import load_profile
from fall_predictor.sim.disturbance_runs import (SEVERITY, cause_ranges, fault_joints, run_length_s,
                                                 sample_disturbance, walker_for)
from fall_predictor.sim.pushes import trajectory_seed

#: A cause can fell the robot when its severest probe band fells at least this fraction.
FELLS_AT_LEAST = 0.3


@dataclass(frozen=True)
class CauseCalibrationSetup:
    """The robot, controller, simulator (None: the profile's), the cause, its severity's probe
    range (None: sim/disturbance_runs.DEFAULT_RANGES'), the seed and the horizon after the
    expected onset [s]."""

    robot: str
    controller: Optional[str]
    simulator: Optional[str]
    cause: str
    probe: Optional[tuple[float, float]] = None
    seed: int = 0
    horizon_s: float = 4.0


_WORLDS: dict = {}


def cause_calibration_run(item: tuple[CauseCalibrationSetup, int]) -> dict:
    """One run of the cause (a parallel map's one argument): its severity, outcome, onset."""
    from fall_predictor.profiles.profile import C_BAL
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.policy_runs import physics_dt_s
    from fall_predictor.sim.sensors import SensorParams, SensorSuite
    from fall_predictor.sim.trajectory import WALK_MARGIN_S, run_trajectory
    from fall_predictor.sim.world import make_world

    setup, index = item
    profile = load_profile(setup.robot)
    policy = profile.controller_profile(setup.controller)
    key, _ = SEVERITY[setup.cause]
    ranges = cause_ranges(profile, setup.controller, setup.cause)
    if setup.probe is not None:
        ranges[key] = tuple(setup.probe)
    disturbance, gait, expected_s = sample_disturbance(
        setup.cause, trajectory_seed(setup.seed, index), walker_for(profile, setup.controller), ranges,
        fault_joints(profile) if setup.cause == 'fault' else ())
    dt_s = physics_dt_s(policy)
    world_key = (setup.robot, setup.simulator, dt_s)
    if world_key not in _WORLDS:
        _WORLDS[world_key] = make_world(profile, setup.simulator, dt_s)
    world = _WORLDS[world_key]
    duration = run_length_s(setup.cause, expected_s, setup.horizon_s)
    if policy is None:
        controller = make_controller(profile, C_BAL, dt_s=world.dt_s, walk_duration_s=duration + WALK_MARGIN_S,
                                     gait=gait)
        sensors = None
    else:
        controller = make_controller(profile, setup.controller, disturbance.command)
        sensors = SensorSuite(SensorParams(), seed=index, dt_s=world.dt_s, profile=profile)
    result = run_trajectory(None, duration, world=world, controller=controller, sensors=sensors,
                            disturbance=disturbance)
    onset = result.extras['t_onset']
    severity = disturbance.params.get(key)
    if severity is None and disturbance.fault is not None:          # a stuck joint: no torque left
        severity = 0.0
    return {'index': index, 'severity': severity, 'params': disturbance.params, 'fallen': result.fallen,
            't_onset': onset, 'onset_to_fall_s': None if not result.fallen or onset is None
            else round(result.t_fallen - onset, 6), 'fell_before_onset': bool(
                result.fallen and (onset is None or result.t_fallen < onset))}


def suggest_cause_range(cause: str, rows: Sequence[dict], probe: tuple[float, float],
                        target_fall_fraction: float = 0.45, bands: int = 6) -> dict:
    """The fall probability by severity band (bands from the mild end; each made non-decreasing
    with severity) and the range from the mild end whose uniform draws are predicted to fell
    ``target_fall_fraction`` of the runs; ``can_fell``: whether the severest band fells at least
    :data:`FELLS_AT_LEAST`."""
    key, larger_is_severer = SEVERITY[cause]
    mild, severe = (probe[0], probe[1]) if larger_is_severer else (probe[1], probe[0])
    scored = [r for r in rows if r['severity'] is not None]
    x = np.array([(r['severity'] - mild) / (severe - mild) for r in scored])      # 0 mild .. 1 severe
    fallen = np.array([r['fallen'] for r in scored], float)
    index = np.clip((x * bands).astype(int), 0, bands - 1)
    counts = np.bincount(index, minlength=bands)
    falls = np.bincount(index, weights=fallen, minlength=bands)
    raw = np.divide(falls, counts, out=np.full(bands, np.nan), where=counts > 0)
    smooth = np.maximum.accumulate(np.nan_to_num(raw, nan=0.0))
    best_k = min(range(1, bands + 1), key=lambda k: abs(smooth[:k].mean() - target_fall_fraction))
    end = mild + (severe - mild) * best_k / bands
    suggested = sorted([round(mild, 4), round(end, 4)])
    edges = [mild + (severe - mild) * k / bands for k in range(bands + 1)]
    delays = [r['onset_to_fall_s'] for r in rows if r['onset_to_fall_s'] is not None]
    return {'cause': cause, 'parameter': key, 'probe': list(probe), 'runs': len(rows),
            'fall_fraction': float(np.mean([r['fallen'] for r in rows])) if rows else None,
            'without_onset': sum(r['t_onset'] is None for r in rows),
            'fell_before_onset': sum(r['fell_before_onset'] for r in rows),
            'fall_probability_by_band': [
                {key: sorted([round(edges[k], 4), round(edges[k + 1], 4)]), 'runs': int(counts[k]),
                 'fall_fraction': None if counts[k] == 0 else float(raw[k])} for k in range(bands)],
            'can_fell': bool(smooth[-1] >= FELLS_AT_LEAST),
            'suggested': {key: suggested}, 'predicted_fall_fraction': float(smooth[:best_k].mean()),
            'onset_to_fall_s_median': float(np.median(delays)) if delays else None}


def calibrate_cause(setup: CauseCalibrationSetup, trajectories: int,
                    map_fn: Optional[Callable[[Callable, Sequence], list]] = None,
                    target_fall_fraction: float = 0.45) -> dict:
    """Run ``trajectories`` runs of the cause and suggest its range (:func:`suggest_cause_range`)."""
    from fall_predictor.sim.disturbance_runs import DEFAULT_RANGES
    key, _ = SEVERITY[setup.cause]
    probe = tuple(setup.probe or DEFAULT_RANGES[setup.cause][key])
    setup = CauseCalibrationSetup(setup.robot, setup.controller, setup.simulator, setup.cause, probe,
                                  setup.seed, setup.horizon_s)
    items = [(setup, i) for i in range(trajectories)]
    rows = list(map_fn(cause_calibration_run, items) if map_fn else map(cause_calibration_run, items))
    return {'setup': {'robot': setup.robot, 'controller': setup.controller, 'simulator': setup.simulator,
                      'cause': setup.cause, 'probe': list(probe), 'seed': setup.seed,
                      'horizon_s': setup.horizon_s},
            **suggest_cause_range(setup.cause, rows, probe, target_fall_fraction), 'rows': rows}
