"""A team's deploy config in its own shape: sections, its own field names, per-joint mappings.

:mod:`~fall_predictor.robot.policy_config` reads a policy's deploy YAML as a flat mapping of the
package's field names. Makers write theirs otherwise; this module turns what they write into that
mapping, naming in every error the field as the team wrote it (``common.stiffness``):

* **sections**: a mapping under a key that is not a field (``common:``, ``policy:``,
  ``policy.control:``, ``normalization:``, ``env:``) holds fields, read as if written at the top.
  The same field in two sections must agree.
* **field names**: the names makers use for the same thing are read as the package's
  (:data:`SYNONYMS`: ``stiffness`` / ``kp`` / ``p_gains`` are ``kps``, ``default_joint_angles`` /
  ``default_qpos`` are ``default_angles``, ``torque_limit`` is ``tau_limit``, ...); any other name
  is mapped with ``field_names: {THEIRS: OURS}`` (THEIRS bare or as its dotted path), and a field
  the package has no use for is listed under ``ignored_fields: [...]``.
* **the motors' order**: with ``motor_joint_names`` (Unitree's ``motor_joint``), the per-joint
  lists are in that order (the robot's motors), which may differ from the policy's
  (``joint_names``, Unitree's ``lab_joint``) or hold more joints than it drives;
* **per-joint mappings**: ``kps``, ``kds``, ``action_scale``, ``tau_limit`` and
  ``default_angles`` may be a mapping of joint name to value; a key that is no joint name applies
  to every joint whose name contains it (legged_gym's ``stiffness: {hip_yaw: 100, knee: 150}``).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Optional

from fall_predictor.errors import TeamFileError

#: The maker's names of the package's fields (each its own field when the package's is absent).
SYNONYMS: dict[str, str] = {
    'kp': 'kps', 'stiffness': 'kps', 'p_gains': 'kps', 'kp_gains': 'kps',
    'kd': 'kds', 'damping': 'kds', 'd_gains': 'kds', 'kd_gains': 'kds',
    'default_joint_angles': 'default_angles', 'default_dof_pos': 'default_angles',
    'default_qpos': 'default_angles', 'default_joint_pos': 'default_angles',
    'torque_limit': 'tau_limit', 'torque_limits': 'tau_limit', 'effort_limit': 'tau_limit',
    'clip_obs': 'clip_observations', 'clip_action': 'clip_actions',
    'dof_names': 'joint_names', 'joint_order': 'joint_names',
    'model_path': 'policy_path', 'sim_dt': 'simulation_dt', 'physics_dt': 'simulation_dt',
    'command_init': 'cmd_init', 'gait_period': 'gait_period_s',
    'lab_joint': 'joint_names', 'motor_joint': 'motor_joint_names',
}
#: Fields whose value may be given per joint as a mapping.
PER_JOINT = ('kps', 'kds', 'action_scale', 'tau_limit', 'default_angles')
#: Fields whose value is a mapping itself (never a section).
MAPPING_FIELDS = frozenset({'obs_scales', 'field_names', 'observation', *PER_JOINT})


class PolicyConfigError(TeamFileError):
    """A policy config is missing, malformed or does not fit its network; the message names the
    file and the field."""


def flatten(path: Any, raw: dict) -> tuple[dict[str, Any], dict[str, str]]:
    """The fields of ``raw`` under the package's names, and for each where the team wrote it
    (its dotted path and own name): sections opened, synonyms and ``field_names`` applied."""
    mapped = raw.get('field_names') or {}
    if not isinstance(mapped, dict) or not all(isinstance(v, str) for v in mapped.values()):
        raise PolicyConfigError(f'{path}: field_names: must map your field names to the package\'s '
                                f'(THEIRS: OURS), got {mapped!r}')
    mapping_names = MAPPING_FIELDS | {k for k, v in SYNONYMS.items() if v in MAPPING_FIELDS} | {
        str(k).rsplit('.', 1)[-1] for k, v in mapped.items() if v in MAPPING_FIELDS}
    flat: dict[str, Any] = {}
    where: dict[str, str] = {}

    def visit(mapping: dict, prefix: str) -> None:
        for key, value in mapping.items():
            key = str(key)
            dotted = prefix + key
            if isinstance(value, dict) and key not in mapping_names and dotted not in mapped:
                visit(value, dotted + '.')              # a section
                continue
            name = mapped.get(dotted, mapped.get(key, SYNONYMS.get(key, key)))
            if name in flat and flat[name] != value:
                raise PolicyConfigError(f'{path}: {dotted}: {value!r} disagrees with {where[name]} '
                                        f'{flat[name]!r} (both give {name})')
            flat.setdefault(name, value)
            where.setdefault(name, dotted)
    visit(raw, '')
    return flat, where


def per_joint(value: dict, joints: tuple[str, ...]) -> tuple[list[Any], list[str], list[str]]:
    """A mapping of joint name (or part of one) to value, in ``joints`` order: (values, None where
    no key matches; the joints without a value, or with two different ones; keys matching no
    joint)."""
    out, bad = [], []
    keys = [str(k) for k in value]
    for joint in joints:
        if joint in value:
            out.append(value[joint])
            continue
        found = {repr(value[k]): value[k] for k in keys if k in joint}
        out.append(next(iter(found.values())) if len(found) == 1 else None)
        if len(found) != 1:
            bad.append(joint)
    extra = [k for k in keys if not any(k in j for j in joints)]
    return out, bad, extra


class Fields:
    """Typed access to the YAML mapping, naming the file and field in every error."""

    def __init__(self, path: Path, raw: dict, where: Optional[dict[str, str]] = None,
                 written: Optional[dict] = None) -> None:
        self.path, self.raw, self.where = path, raw, where or {}
        self.written = written if written is not None else raw      #: the file as written
        self.ignored: list[str] = []        #: ignored_fields: the team's fields left unread
        #: With motor_joint_names: (those names, the index in them of each policy joint): the
        #: per-joint lists are in the motors' order.
        self.motor_order: Optional[tuple[list[str], list[int]]] = None

    def value_at(self, field: str, value: Any) -> Any:
        """``value``, or where it names a field of the file (a dotted path as written, or a field's
        name), that field's value (a list element by element)."""
        if isinstance(value, list):
            return [self.value_at(field, v) for v in value]
        if not isinstance(value, str):
            return value
        node: Any = self.written
        for part in value.split('.'):
            node = node.get(part, ...) if isinstance(node, dict) else ...
        if node is ...:
            node = self.raw.get(value, ...)
        if node is ... or isinstance(node, (dict, list, str)):
            raise self.error(field, f'{value!r} names no number of the file (a number, or the dotted '
                                    f'path of a field holding one, e.g. policy.normalization.dof_vel)')
        return node

    def error(self, field: str, text: str) -> PolicyConfigError:
        """An error naming ``field`` as the team wrote it (its section and own name)."""
        head, _, rest = field.partition('.')
        head, _, index = head.partition('[')
        written = (self.where.get(head, head) + ('[' + index if index else '')
                   + ('.' + rest if rest else ''))
        return PolicyConfigError(f'{self.path}: {written}: {text}')

    def get(self, field: str, default: Any = ...) -> Any:
        if field not in self.raw or self.raw[field] is None and default is not ...:
            if default is ...:
                raise self.error(field, 'missing (required)')
            return default
        return self.raw[field]

    def either(self, first: str, second: str, default: Any = ...) -> Any:
        """The value of ``first`` or its synonym ``second`` (both given: they must agree)."""
        if first in self.raw and second in self.raw and self.raw[first] != self.raw[second]:
            raise self.error(first, f'{self.raw[first]!r} disagrees with '
                                    f'{self.where.get(second, second)} {self.raw[second]!r}')
        if first in self.raw:
            return self.raw[first]
        if second in self.raw:
            self.where.setdefault(first, self.where.get(second, second))    # errors name it so
            return self.raw[second]
        if default is ...:
            raise self.error(first, f'missing (required; humanoid-gym calls it {second})')
        return default


def number(f: Fields, field: str, value: Any, low: float = -math.inf, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or value < low or (positive and value <= 0):
        bound = '> 0' if positive else (f'>= {low:g}' if low > -math.inf else 'finite')
        raise f.error(field, f'must be a number {bound}, got {value!r}')
    return float(value)


def numbers(f: Fields, field: str, value: Any, n: int, broadcast: bool = True,
             positive: bool = False, joints: tuple[str, ...] = ()) -> tuple[float, ...]:
    """``n`` numbers from a list of ``n`` (or one number, when ``broadcast``; or, with ``joints``,
    a mapping of joint names or parts of them: :func:`~fall_predictor.robot.deploy_fields.per_joint`)."""
    if joints and isinstance(value, dict):
        values, bad, extra = per_joint(value, joints)
        if bad:
            raise f.error(field, f'a mapping must give every joint_names entry one value (by its '
                                 f'name, or a part of it as legged_gym\'s stiffness does); missing '
                                 f'{bad}, extra {extra}')
        return tuple(number(f, field, v, positive=positive) for v in values)
    if broadcast and isinstance(value, (int, float)) and not isinstance(value, bool):
        return (number(f, field, value, positive=positive),) * n
    if joints and f.motor_order is not None and isinstance(value, (list, tuple)):
        if len(value) != len(f.motor_order[0]):
            raise f.error(field, f'must be a list of {len(f.motor_order[0])} numbers, one per '
                                 f'motor_joint_names entry in its order, got {value!r}')
        value = [value[k] for k in f.motor_order[1]]
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise f.error(field, f'must be a list of {n} numbers{" or one number" if broadcast else ""}, '
                             f'got {value!r}')
    return tuple(number(f, field, v, positive=positive) for v in value)


def scale(f: Fields, field: str, value: Any) -> tuple[float, ...]:
    values = [value] if not isinstance(value, (list, tuple)) else list(value)
    if not values:
        raise f.error(field, 'an empty scale')
    return tuple(number(f, field, v) for v in values)
