"""The runs of a dataset disturbed by something other than a push (sim/disturbances.py): which
cause each run draws (``generate --causes``), and one run of a cause simulated for the generator
(data/generation.py records it as it records a push's).

A run's cause is drawn from its own random stream (``(seed, index, CAUSE_STREAM)``), so a push
run of a mixed dataset draws its push, gait and command from ``(seed, index)`` exactly as the
push-only dataset of the same seed does: its bag is bit for bit that one's. A run of another
cause draws its disturbance from ``(seed, index)`` (sim/disturbance_runs.py) and is recorded from
``pre_push_s`` before its measured onset (before the expected one when the disturbance never
acted; a long walk: from its controller's settle time) to the horizon after it; its index row
keeps the push fields at a zero force with ``t_push`` = ``t_force_end`` = its onset (the start of
its recording for a walk) and gives the cause, its parameters and the measured onset.
"""
from __future__ import annotations

import json
from functools import partial
from typing import Optional, Sequence

import numpy as np

from fall_predictor.data.dataset import CAUSE_PUSH, CAUSE_WALK, CAUSES, cause_params_text
from fall_predictor.monitor.records import PushSpec
from fall_predictor.profiles.profile import load_profile

#: The third seed word of a run's cause draw.
CAUSE_STREAM = 57


def parse_causes(text: str) -> tuple[tuple[str, float], ...]:
    """``push,trip`` (equal weights) or ``push:0.4,trip:0.15,...`` as (cause, weight) pairs,
    normalised to sum 1 (ValueError naming what is wrong)."""
    pairs = []
    for item in (part.strip() for part in text.split(',')):
        if not item:
            continue
        name, _, weight = item.partition(':')
        if name not in CAUSES:
            raise ValueError(f'unknown cause {name!r} (one of {", ".join(CAUSES)})')
        try:
            w = float(weight) if weight else 1.0
        except ValueError:
            raise ValueError(f'the weight of {name!r} is not a number: {weight!r}') from None
        if not w > 0 or not np.isfinite(w):
            raise ValueError(f'the weight of {name!r} must be positive, got {weight!r}')
        pairs.append((name, w))
    names = [n for n, _ in pairs]
    if not pairs or len(set(names)) != len(names):
        raise ValueError(f'--causes names each cause once, at least one: got {text!r}')
    total = sum(w for _, w in pairs)
    return tuple((n, round(w / total, 6)) for n, w in pairs)


def run_cause(causes: Optional[Sequence[tuple[str, float]]], seed: int, index: int) -> str:
    """The cause of run ``index``: a push without ``causes``, else drawn by weight."""
    if not causes:
        return CAUSE_PUSH
    rng = np.random.default_rng([seed, index, CAUSE_STREAM])
    weights = np.array([w for _, w in causes], float)
    return causes[int(rng.choice(len(causes), p=weights / weights.sum()))][0]


def causes_manifest(config) -> dict:
    """What a mixed dataset's manifest records of its causes: the weights, each cause's ranges
    for its robot and controller, and a long walk's length."""
    from fall_predictor.sim.disturbance_runs import cause_ranges
    profile = load_profile(config.robot)
    return {'causes': {name: weight for name, weight in config.causes},
            'cause_ranges': {name: {k: list(v) for k, v in cause_ranges(profile, config.controller, name).items()}
                             for name, _ in config.causes if name != CAUSE_PUSH},
            'walk_s': config.walk_s}


def run_randomization(config, index: int):
    """Run ``index``'s randomised world (sim/randomization.py), or None without ``randomize``."""
    if not config.randomize:
        return None
    from fall_predictor.sim.randomization import RandomizationRanges, WorldRandomization, randomization_rng
    return WorldRandomization.sample(RandomizationRanges(), randomization_rng(config.seed, index))


def randomization_fields(config, index: int) -> dict:
    """Run ``index``'s index fields of its randomised world (none for a nominal one)."""
    randomization = run_randomization(config, index)
    return {} if randomization is None else {'randomization': cause_params_text(randomization.to_dict())}


def sensor_params(config, index: int, noise_scale: float):
    """The sensor model of run ``index`` (noise x ``noise_scale``; a randomised world's latency
    and IMU bias)."""
    from fall_predictor.sim.sensors import SensorParams
    params = SensorParams(noise_scale=noise_scale)
    randomization = run_randomization(config, index)
    return params if randomization is None else randomization.sensor_params(params)


def disturbed_run(config, index: int, cause: str, world, start, still_moving, randomization=None) -> tuple:
    """Simulate run ``index`` of ``cause`` (not a push) in ``world`` (C_bal's), or with
    ``start(command)``, a learned policy's run_trajectory arguments for its command (its world,
    controller and sensors): (its stand-in push, the result, the recording's start [s], C_bal's
    gait, a policy's command, its index fields). ``still_moving(t_push, t_start, mass_kg,
    measurements)``: whether a run goes on past its horizon (data/generation.py)."""
    from fall_predictor.sim.disturbance_runs import (cause_ranges, fault_joints, run_length_s,
                                                     sample_disturbance, walker_for)
    from fall_predictor.sim.pushes import trajectory_seed
    from fall_predictor.sim.trajectory import gait_run, run_trajectory

    profile = load_profile(config.robot)
    walker = walker_for(profile, config.controller)
    rng = trajectory_seed(config.seed, index)
    disturbance, gait, expected_s = sample_disturbance(
        cause, rng, walker, cause_ranges(profile, config.controller, cause),
        fault_joints(profile) if cause == 'fault' else (), config.walk_s)
    duration = run_length_s(cause, expected_s, config.horizon_after_push_s)
    if walker.policy is None:
        start = gait_run(world, gait, duration + config.settle_extension_s)
    else:
        command = disturbance.command or (disturbance.schedule.at(0.0) if disturbance.schedule else None)
        start = start(command)
    still_moving = partial(still_moving, expected_s, max(expected_s - config.pre_push_s, 0.0),
                           profile.total_mass_kg)
    result = run_trajectory(None, duration, record_sensors=config.sensor_noise_scale is not None,
                            disturbance=disturbance, max_extension_s=config.settle_extension_s,
                            randomization=randomization,
                            go_on_while=None if cause == CAUSE_WALK else still_moving, **start)
    t_onset = result.extras['t_onset']
    if cause == CAUSE_WALK:
        anchor = t_start = walker.settle_s
    else:
        anchor = t_onset if t_onset is not None else expected_s
        t_start = round(max(anchor - config.pre_push_s, 0.0), 6)
    fields = {'cause': cause, 'cause_params': cause_params_text(disturbance.params), 't_onset': t_onset}
    return PushSpec(0.0, 0.0, 0.0, round(anchor, 6), 0.0), result, t_start, gait, disturbance.command, fields


def undisturbed_fall_fields(cause: str, push: PushSpec, fields: dict) -> dict:
    """The index fields of a run that fell before its disturbance acted: an undisturbed walk
    (no onset) whose parameters keep what was meant to disturb it (``fell_before_onset_of``: the
    cause; a push's force, angle and height, or the cause's own parameters)."""
    meant = (json.loads(fields['cause_params']) if fields.get('cause_params') else
             {'force_n': push.force_n, 'angle_deg': push.angle_deg, 'height_m': push.height_m,
              't_push_s': push.t_push})
    return {'cause': CAUSE_WALK, 't_onset': None,
            'cause_params': cause_params_text({**meant, 'fell_before_onset_of': cause})}
