#!/usr/bin/env python3
"""Which walking gait a robot survives pushes with: falls over a grid of pushes, per setting.

For each ``--setting`` (controller overrides of the robot profile's gait, reflex or stabilizer,
``name=value`` pairs; ``profile`` for none), the robot walks from a fresh world under C_bal (its
profile's reflex and stabilizer) and is pushed once, for 0.1 s, 0.1 m above its CoM, with every
impulse of ``--impulses`` from 8 directions at 4 onsets 0.15 s apart; it must stay up for 4.1 s
after the onset. The unpushed walk is checked first: a setting whose walk fires the reflex or
falls without any push is reported as such (its push results would be those of a robot that
stopped walking). Writes JSON (``--out``).

    python benchmarks/bench_gait_pushes.py --robot g1 --setting profile \\
        --setting single_support_s=0.5 --out docs/robots/g1_c_bal/gait_pushes.json
"""
from __future__ import annotations

import argparse
import dataclasses
import json
from multiprocessing import Pool
from pathlib import Path

DIRECTIONS_DEG = (0.0, 45.0, 90.0, 135.0, 180.0, -135.0, -90.0, -45.0)
ONSETS_S = (3.45, 3.6, 3.75, 3.9)
HORIZON_S = 4.1


def parse_setting(text: str) -> dict[str, float]:
    """``'a=1 b=2'`` as ``{'a': 1.0, 'b': 2.0}``; ``'profile'`` as ``{}``."""
    if text.strip() in ('', 'profile'):
        return {}
    pairs = [item.split('=', 1) for item in text.split()]
    if any(len(pair) != 2 for pair in pairs):
        raise ValueError(f'a setting is name=value pairs or "profile", got {text!r}')
    return {name: float(value) for name, value in pairs}


def controller(robot: str, overrides: dict[str, float]):
    """The profile's gait, reflex and stabilizer settings with ``overrides`` applied."""
    from fall_predictor.profiles.profile import load_profile
    from fall_predictor.robot.balance_controller import controller_configs
    profile = load_profile(robot)
    parts = list(controller_configs(profile))
    unknown = set(overrides)
    for i, part in enumerate(parts):
        own = {k: v for k, v in overrides.items() if hasattr(part, k)}
        unknown -= set(own)
        parts[i] = dataclasses.replace(part, **own)
    if unknown:
        raise ValueError(f'not a gait, reflex or stabilizer setting: {sorted(unknown)}')
    return profile, parts


def run(job: tuple) -> dict:
    """One run: ``(robot, setting, impulse [N s], direction [deg], onset [s])``; impulse 0 is
    the unpushed walk."""
    from fall_predictor.monitor.records import PushSpec
    from fall_predictor.robot.balance_controller import BalanceController
    from fall_predictor.sim.pybullet_world import PybulletWorld
    robot, setting, impulse, direction, onset = job
    profile, (gait, reflex, stabilizer) = controller(robot, parse_setting(setting))
    with PybulletWorld(profile=profile) as sim:
        balance = BalanceController(gait, reflex, stabilizer=stabilizer, profile=profile)
        q0, torso = balance.initial_posture()
        m = sim.reset(q0, torso)
        if impulse > 0.0:
            sim.schedule_push(PushSpec(impulse / 0.1, direction, 0.1, onset))
        while m.t < onset + HORIZON_S and not m.fallen:
            sim.set_joint_targets(balance.update(m))
            m = sim.step()
    return {'setting': setting, 'impulse_ns': impulse, 'direction_deg': direction, 'onset_s': onset,
            'fell': bool(m.fallen), 'reflex': balance.reflex_event is not None}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--robot', default='g1')
    parser.add_argument('--setting', action='append', required=True,
                        help='"name=value ..." controller overrides, or "profile"')
    parser.add_argument('--impulses', type=float, nargs='+', default=[2.0, 4.0, 7.0, 10.0])
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    for setting in args.setting:
        controller(args.robot, parse_setting(setting))          # fail early on a bad name
    jobs = [(args.robot, s, 0.0, 0.0, ONSETS_S[0]) for s in args.setting]
    jobs += [(args.robot, s, j, d, t) for s in args.setting for t in ONSETS_S
             for j in args.impulses for d in DIRECTIONS_DEG]
    with Pool(args.jobs) as pool:
        runs = pool.map(run, jobs, chunksize=1)
    settings = {}
    for setting in args.setting:
        mine = [r for r in runs if r['setting'] == setting]
        walk = next(r for r in mine if r['impulse_ns'] == 0.0)
        pushed = [r for r in mine if r['impulse_ns'] > 0.0]

        def falls(keep) -> str:
            chosen = [r for r in pushed if keep(r)]
            return f'{sum(r["fell"] for r in chosen)}/{len(chosen)}'
        settings[setting] = {
            'unpushed_walk': {'fell': walk['fell'], 'reflex_fired': walk['reflex']},
            'falls_by_impulse_ns': {f'{j:g}': falls(lambda r, j=j: r['impulse_ns'] == j)
                                    for j in args.impulses},
            'falls_by_direction': {
                'forward (0, +-45 deg)': falls(lambda r: abs(r['direction_deg']) <= 45.0),
                'sideways (+-90 deg)': falls(lambda r: abs(r['direction_deg']) == 90.0),
                'backward (180, +-135 deg)': falls(lambda r: abs(r['direction_deg']) >= 135.0)},
            'falls': falls(lambda r: True)}
    result = {'robot': args.robot, 'impulses_ns': args.impulses, 'directions_deg': DIRECTIONS_DEG,
              'onsets_s': ONSETS_S, 'horizon_s': HORIZON_S, 'push_height_m': 0.1,
              'settings': settings, 'runs': runs}
    text = json.dumps(result, indent=1)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')
    print(json.dumps({'robot': args.robot, 'settings': settings}, indent=1))
    return result


if __name__ == '__main__':
    main()
