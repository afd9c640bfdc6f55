"""``fall-predictor check``: what a team's robot files can get wrong, in seconds, before any dataset.

The static checks (profiles/checks.py, robot/checks.py, sim/checks.py: the profile, URDF, MJCF,
each deploy config against its network) take about a second; then, unless ``--static``, each
controller stands and walks without a push for a few seconds of simulation. A table of checks,
each ✓ or ✗ with what to do; exit 1 on any ✗.
"""
from __future__ import annotations

import argparse
import time

from fall_predictor.cli.args import emit

OK, FAIL, WARN = '✓', '✗', '!'


def cmd_check(args) -> int:
    from fall_predictor.sim.checks import controllers_to_check, dynamic_checks, static_checks

    start = time.perf_counter()
    checks, profile = static_checks(args.robot, args.controller)
    static_s = time.perf_counter() - start
    dynamic = not args.static and profile is not None and all(c.ok or c.warning for c in checks)
    if dynamic:
        for name in controllers_to_check(profile, args.controller):
            checks += dynamic_checks(profile, name, args.simulator)
    elif not args.static and profile is not None:
        checks.append(_skipped('runs', 'not run: a static check failed'))
    wall = time.perf_counter() - start
    failures = [c for c in checks if not c.ok and not c.warning]
    payload = {'robot': args.robot, 'profile': None if profile is None else str(profile.source),
               'ok': not failures, 'failures': len(failures), 'static_s': static_s, 'wall_s': wall,
               'checks': [c.to_json() for c in checks]}
    title = args.robot if profile is None else f'{profile.name} ({profile.source})'
    lines = [f'check of {title}:']
    width = max(len(c.name) for c in checks)
    for c in checks:
        mark = WARN if c.warning else OK if c.ok else FAIL
        lines.append(f'  {mark} {c.name:<{width}}  {c.found}')
        if not c.ok or c.warning:
            where = ': '.join(str(p) for p in (c.file, c.field) if p)
            lines.append(f'      fix: {c.fix}' + (f' [{where}]' if where else ''))
    warnings = sum(c.warning for c in checks)
    lines.append(f'{sum(c.ok for c in checks)} of {len(checks)} checks passed'
                 + (f', {warnings} warning(s)' if warnings else '')
                 + (f' in {static_s:.2f} s' if args.static else
                    f' in {wall:.1f} s (static {static_s:.2f} s)')
                 + ('' if dynamic or args.static else '; the runs wait for the static checks'))
    emit(args, payload, lines)
    return 1 if failures else 0


def _skipped(name: str, why: str):
    from fall_predictor.profiles.checks import Check
    return Check(name, False, why, 'fix the failures above, then check again', warning=True)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser('check', help='check a robot\'s profile, URDF, MJCF, deploy configs and '
                                     'networks, and that it stands and walks',
                       description='Check a team\'s robot files in seconds, before any dataset: '
                                   'the profile\'s fields (unknown keys named), URDF and MJCF '
                                   '(parse, agree: joints, mass, CoM), limits, masses, frames, feet '
                                   'sides, fall heights, the mass, each deploy config against its '
                                   'network (sizes, finite bounded actions, degrees, gains); then '
                                   'a 5 s stand and walks under each controller, without a push. '
                                   'Prints a table of checks (each with its fix); exit 1 on any '
                                   'failure.')
    # The profile is checked here, not when parsed: a profile that does not load is a failed
    # check in the table.
    p.add_argument('--robot', required=True, metavar='NAME|PATH',
                   help='robot profile: a shipped profile\'s name or the path to a profile file')
    p.add_argument('--controller', default=None, metavar='NAME',
                   help='check this controller only (default: every controller of the robot)')
    p.add_argument('--simulator', choices=('pybullet', 'mujoco'), default=None,
                   help='the simulator of the runs (default: the robot profile\'s)')
    p.add_argument('--static', action='store_true', help='the static checks only (about a second)')
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.set_defaults(func=cmd_check)
