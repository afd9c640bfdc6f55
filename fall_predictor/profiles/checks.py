"""What a team's robot profile and URDF can get wrong, found in well under a second (method §10).

``fall-predictor check`` (cli/check.py) runs these first, then the deploy configs against their
networks (robot/checks.py), the MJCF against the URDF and the runs in the simulator
(sim/checks.py). Each check gives a :class:`Check`: what was looked at, whether it passed, what
was found and, when it failed, what to do, with the file and the field to change.

The checks here read the profile file as YAML (unknown keys, named with the nearest known one)
and the URDF as XML and through Pinocchio (the onboard model): the profile loads; the URDF parses;
joint limits ordered and link masses positive; every frame the profile names (IMU, feet, soles,
F/T sensors) and every joint of its joint groups is the URDF's; the profile's mass is the URDF's
(within 1 %); at the standing posture the left foot is on +y of the right (REP 103: y to the
left) and the fallen and guard heights (method §4, §6) are below the standing CoM.
"""
from __future__ import annotations

import contextlib
import difflib
import math
import os
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Iterable, Optional

import yaml

from fall_predictor.profiles.controller_entries import CONTROLLER_KEYS
from fall_predictor.profiles.profile import (ProfileError, RobotProfile,
                                             load_profile, profile_path)

#: The keys a profile file may hold: those profile.py's _parse reads (any other is named, with
#: the nearest of these).
PROFILE_KEYS = frozenset({
    'name', 'description', 'urdf', 'sim_urdf', 'mjcf', 'simulator', 'total_mass_kg', 'imu_frame',
    'feet', 'monitor', 'joint_groups', 'servo_gains', 'controller', 'posture', 'push_force_n',
    'gait_variety', 'sim_ground', 'model', 'controllers', 'default_controller', 'unitree_hg',
    'causes'})
#: The keys of ``feet.<side>``.
FOOT_KEYS = frozenset({'foot_link', 'sole_frame', 'sole_length_m', 'sole_width_m',
                       'sole_origin_in_foot_m', 'force_torque_frame', 'sole_rpy_in_foot'})
#: The keys of ``monitor``.
MONITOR_KEYS = frozenset({'fallen_com_height_m', 'guard_com_height_m', 'joint_limits'})

#: How far the profile's total mass may be from the URDF's links' (a fraction).
MASS_TOLERANCE = 0.01
#: The guard must sit this far below the standing CoM at least [fraction of its height]: walking
#: lowers the CoM a little, and a guard at standing height fires on every step.
GUARD_MARGIN = 0.05


@dataclass(frozen=True)
class Check:
    """One check of a team's files: ``ok`` and what was ``found``; when not ok, ``fix`` says what
    to do, in ``file`` at ``field``."""

    name: str
    ok: bool
    found: str
    fix: str = ''
    file: Optional[str] = None
    field: Optional[str] = None
    #: A warning: shown, never failing (something unusual that may be intended).
    warning: bool = False

    def line(self) -> str:
        """The check as one line: FILE: FIELD: what was found; what to do."""
        parts = [p for p in (self.file, self.field) if p]
        text = ': '.join(parts + [self.found])
        return f'{text}; {self.fix}' if self.fix else text

    def to_json(self) -> dict:
        return asdict(self)


def passed(name: str, found: str) -> Check:
    return Check(name, True, found)


def failed(name: str, found: str, fix: str, file: Any = None, field: Optional[str] = None) -> Check:
    return Check(name, False, found, fix, None if file is None else str(file), field)


def nearest(name: str, known: Iterable[str]) -> str:
    """' (did you mean X?)' for the known name nearest ``name``, or ''."""
    match = difflib.get_close_matches(str(name), [k for k in known if isinstance(k, str)], n=1,
                                      cutoff=0.6)
    return f' (did you mean {match[0]!r}?)' if match else ''


# -- the profile file ---------------------------------------------------------------------------

def unknown_keys(path: Path, raw: Any) -> list[Check]:
    """Keys the profile's reader does not know, at the top level, in ``feet.<side>``, ``monitor``
    and ``controllers.<name>``: each named with the nearest known key (a misspelt key is otherwise silently
    its default)."""
    found = []
    if not isinstance(raw, dict):
        return found
    places = [('', raw, PROFILE_KEYS)]
    for side, foot in (raw.get('feet') or {}).items() if isinstance(raw.get('feet'), dict) else ():
        if isinstance(foot, dict):
            places.append((f'feet.{side}.', foot, FOOT_KEYS))
    if isinstance(raw.get('monitor'), dict):
        places.append(('monitor.', raw['monitor'], MONITOR_KEYS))
    if isinstance(raw.get('controllers'), dict):
        places += [(f'controllers.{name}.', fields, CONTROLLER_KEYS)
                   for name, fields in raw['controllers'].items() if isinstance(fields, dict)]
    for prefix, mapping, known in places:
        for key in mapping:
            if key not in known:
                found.append(f'{prefix}{key}{nearest(key, known)}')
    return found


def profile_checks(robot: Any) -> tuple[list[Check], Optional[RobotProfile]]:
    """The profile file's own checks, and the profile (None when it does not load)."""
    try:
        path = profile_path(robot)
    except ProfileError as error:
        return [failed('profile loads', str(error), 'give a shipped profile\'s name or the path '
                       'to a profile.yaml', robot, 'robot')], None
    try:
        raw = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, OSError, UnicodeDecodeError) as error:
        mark = getattr(error, 'problem_mark', None)
        where = f'line {mark.line + 1}' if mark is not None else 'the file'
        return [failed('profile loads', f'not valid YAML ({where}: '
                       f'{getattr(error, "problem", None) or error})',
                       'fix the YAML syntax there', path, where)], None
    checks = []
    unknown = unknown_keys(path, raw)
    if unknown:
        checks.append(failed('profile keys', 'unknown key ' + '; '.join(unknown),
                             'rename it (or remove it): an unknown key is ignored, its setting '
                             'silently the default', path, unknown[0].split(' ')[0]))
    try:
        profile = load_profile(path)
    except ProfileError as error:
        return checks + [failed('profile loads', str(error).replace(f'{path}: ', ''),
                                'fix that field', path, _field_of(str(error), path))], None
    if not unknown:
        checks.append(passed('profile keys', f'{len(raw)} keys, all known'))
    checks.append(passed('profile loads', f'{profile.name}: fields and types as documented'))
    return checks, profile


def _field_of(message: str, path: Path) -> Optional[str]:
    rest = message.replace(f'{path}: ', '', 1)
    head = rest.split(' ', 1)[0].rstrip(':')
    return head if head and all(c.isalnum() or c in '._[]' for c in head) else None


# -- the URDF -----------------------------------------------------------------------------------

def _parse_urdf(path: Path) -> ET.Element:
    text = path.read_text()
    if not text.strip():
        raise ET.ParseError('the file is empty')
    root = ET.fromstring(text)
    if root.tag != 'robot':
        raise ET.ParseError(f'its root element is <{root.tag}>, not <robot>')
    return root


def urdf_checks(profile: RobotProfile, posture: Optional[dict[str, float]] = None) -> list[Check]:
    """The URDF (and the simulator's URDF when it differs) against itself and the profile."""
    checks = []
    roots = {}
    for key, path in (('urdf', profile.urdf_path), ('sim_urdf', profile.sim_urdf_path)):
        if path in roots.values():
            continue
        try:
            roots[key] = path, _parse_urdf(path)
        except (ET.ParseError, OSError, UnicodeDecodeError) as error:
            wrong_file = 'root element' in str(error)
            checks.append(failed('URDF parses', f'not a valid URDF: {error}',
                                 f'name the robot\'s URDF in {key} (an MJCF goes in mjcf)'
                                 if wrong_file else 'fix the XML (a truncated copy? an unclosed '
                                 'tag?)', path, key if wrong_file else None))
    if checks:
        return checks
    path, root = roots['urdf']
    checks.append(passed('URDF parses', f'{path.name}: {len(list(root.iter("link")))} links, '
                         f'{len(_movable(root))} movable joints'))
    checks += _limits_and_masses(path, root)
    if 'sim_urdf' in roots:
        sim_path, sim_root = roots['sim_urdf']
        a, b = set(_movable(root)), set(_movable(sim_root))
        if a != b:
            checks.append(failed('sim URDF agrees', f'joints only in {path.name}: {sorted(a - b)}, '
                                 f'only in {sim_path.name}: {sorted(b - a)}',
                                 'give both files the same joint names', sim_path, 'joint'))
    links = {link.get('name') for link in root.iter('link')}
    joints = {j.get('name') for j in root.iter('joint')}
    checks.append(_joint_groups(profile, set(_movable(root))))
    frames = _frames(profile, links, joints)
    checks.append(frames)
    if frames.ok:                           # the model needs the feet's links
        checks += _model_checks(profile, posture or {})
    return checks


def _movable(root: ET.Element) -> list[str]:
    return [j.get('name') for j in root.iter('joint')
            if j.get('type') in ('revolute', 'continuous', 'prismatic')]


def _limits_and_masses(path: Path, root: ET.Element) -> list[Check]:
    bad_limits, bad_masses = [], []
    for joint in root.iter('joint'):
        limit = joint.find('limit')
        if joint.get('type') in ('revolute', 'prismatic') and limit is not None:
            try:
                lower, upper = float(limit.get('lower', 0)), float(limit.get('upper', 0))
            except ValueError:
                bad_limits.append(f'{joint.get("name")} (limits {limit.get("lower")!r}, '
                                  f'{limit.get("upper")!r} are not numbers)')
                continue
            if not lower < upper:
                bad_limits.append(f'{joint.get("name")} (lower {lower:g} >= upper {upper:g})')
    for link in root.iter('link'):
        mass = link.find('inertial/mass')
        if mass is None:
            continue
        try:
            value = float(mass.get('value'))
        except (TypeError, ValueError):
            value = math.nan
        if not (math.isfinite(value) and value >= 0.0):
            bad_masses.append(f'{link.get("name")} ({mass.get("value")})')
    checks = []
    checks.append(failed('URDF joint limits', 'limits not ordered: ' + ', '.join(bad_limits),
                         'write lower < upper in each <limit> (the monitor refuses every sample '
                         'otherwise)', path, bad_limits[0].split(' ')[0])
                  if bad_limits else passed('URDF joint limits', 'every limit lower < upper'))
    checks.append(failed('URDF masses', 'masses not >= 0: ' + ', '.join(bad_masses),
                         'give each link its mass in kg (>= 0)', path, bad_masses[0].split(' ')[0])
                  if bad_masses else passed('URDF masses', 'every link mass >= 0'))
    return checks


def _joint_groups(profile: RobotProfile, joints: set[str]) -> Check:
    unknown = [(group, j) for group, names in profile.joint_groups.items() for j in names
               if j not in joints]
    if unknown:
        group, joint = unknown[0]
        return failed('joint groups', f'{joint!r} is not a movable joint of {profile.urdf_path.name}'
                      + nearest(joint, joints) + (f' (and {len(unknown) - 1} more)' if len(unknown) > 1 else ''),
                      'name the URDF\'s joints', profile.source, f'joint_groups.{group}')
    return passed('joint groups', f'{sum(map(len, profile.joint_groups.values()))} joints in '
                  f'{len(profile.joint_groups)} groups, all the URDF\'s')


def _frames(profile: RobotProfile, links: set[str], joints: set[str]) -> Check:
    frames = links | joints
    wanted = [('imu_frame', profile.imu_frame)]
    for side, foot in profile.feet.items():
        wanted.append((f'feet.{side}.foot_link', foot.foot_link))
        if foot.force_torque_frame:
            # the sole frame is added to the model when the URDF lacks it
            wanted.append((f'feet.{side}.force_torque_frame', foot.force_torque_frame))
    soles = {foot.sole_frame for foot in profile.feet.values()}
    for field, frame in wanted:
        if frame not in frames and not (field.endswith('force_torque_frame') and frame in soles):
            return failed('profile frames', f'{frame!r} is not a link or joint of '
                          f'{profile.urdf_path.name}{nearest(frame, frames)}',
                          'name a frame of the URDF', profile.source, field)
    if profile.feet['l'].foot_link == profile.feet['r'].foot_link:
        return failed('profile frames', 'both feet on the same link', 'give each foot its own link',
                      profile.source, 'feet')
    return passed('profile frames', 'IMU, feet' + (', F/T frames' if any(
        f.force_torque_frame for f in profile.feet.values()) else '') + ' found in the URDF')


def _model_checks(profile: RobotProfile, posture: dict[str, float]) -> list[Check]:
    """Through Pinocchio (the onboard model): mass, feet sides, heights at ``posture``."""
    from fall_predictor.monitor.robot_description import DescriptionError

    with _native_stderr() as said:          # urdfdom says why on fd 2: into the message
        try:
            description = profile.sensor_layout().description(profile.urdf_xml())
        except DescriptionError as error:
            description, failure = None, error
    if description is None:
        why = ' '.join(line.strip() for line in said() if line.strip())
        return [failed('URDF model', str(failure) + (f' ({why})' if why else ''), 'fix the URDF',
                       profile.urdf_path, None)]
    checks = []
    urdf_mass = description.total_mass_kg
    if abs(profile.total_mass_kg - urdf_mass) > MASS_TOLERANCE * urdf_mass:
        checks.append(failed('total mass', f'{profile.total_mass_kg:g} kg, but the URDF\'s links '
                             f'weigh {urdf_mass:.3f} kg', f'write total_mass_kg: {urdf_mass:.3f} '
                             '(or fix the URDF\'s masses)', profile.source, 'total_mass_kg'))
    else:
        checks.append(passed('total mass', f'{profile.total_mass_kg:g} kg, the URDF\'s '
                             f'{urdf_mass:.3f} kg within {MASS_TOLERANCE:.0%}'))
    com, soles = standing_geometry(description, posture)
    y_left, y_right = soles['l'][1], soles['r'][1]
    if not y_left > y_right:
        checks.append(failed('feet sides', f'the left foot ({profile.feet["l"].foot_link}) is at '
                             f'y = {y_left:+.3f} m, the right at {y_right:+.3f} m (REP 103: +y is '
                             'the robot\'s left)', 'swap feet.l and feet.r', profile.source, 'feet'))
    else:
        checks.append(passed('feet sides', f'left foot at y = {y_left:+.3f} m, right at '
                             f'{y_right:+.3f} m'))
    height = com[2] - 0.5 * (soles['l'][2] + soles['r'][2])
    fallen, guard = profile.fallen_com_height_m, profile.guard_com_height_m
    if not fallen < height:
        checks.append(failed('fall heights', f'fallen_com_height_m {fallen:g} m is not below the '
                             f'standing CoM ({height:.3f} m over the soles): every run is '
                             '"fallen" at once', f'write about {0.56 * height:.2f} (0.56 of the '
                             'standing CoM height, as the shipped robots)', profile.source,
                             'monitor.fallen_com_height_m'))
    elif not guard < (1.0 - GUARD_MARGIN) * height:
        checks.append(failed('fall heights', f'guard_com_height_m {guard:g} m is not below the '
                             f'standing CoM ({height:.3f} m over the soles) by '
                             f'{GUARD_MARGIN:.0%}', f'write about {0.81 * height:.2f} (0.81 of '
                             'the standing CoM height, as the shipped robots)', profile.source,
                             'monitor.guard_com_height_m'))
    else:
        checks.append(passed('fall heights', f'fallen {fallen:g} m < guard {guard:g} m < standing '
                             f'CoM {height:.3f} m'))
    return checks


@contextlib.contextmanager
def _native_stderr():
    """What native code writes on file descriptor 2 meanwhile, kept off the terminal: the
    context gives a function returning its lines."""
    lines: list[str] = []
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:
        yield lambda: lines
        return
    with tempfile.TemporaryFile(mode='w+') as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield lambda: lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            lines.extend(sink.read().splitlines())


def standing_geometry(description, posture: dict[str, float]) -> tuple[Any, dict[str, Any]]:
    """The CoM and both soles' origins [m] in the base frame at joint angles ``posture`` (by
    name; others zero)."""
    import numpy as np
    import pinocchio as pin

    q_joints = np.array([posture.get(name, 0.0) for name in description.joint_names])
    q = description.configuration(q_joints)
    com = pin.centerOfMass(description.model, description.data, q)
    pin.framesForwardKinematics(description.model, description.data, q)
    soles = {side: description.data.oMf[frame].translation.copy()
             for side, frame in description.sole_ids.items()}
    return np.asarray(com).copy(), soles

