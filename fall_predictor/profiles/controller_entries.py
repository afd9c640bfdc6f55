"""A robot profile's controllers (``controllers:``): each learned walking policy the robot walks
with, by name (its deploy config, push force and command ranges, settling time, shipped model and
disturbance ranges); C_bal, the package's own balance controller, needs no entry (:data:`C_BAL`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

#: The package's own model-based balance controller (robot/balance_controller.py), always available.
C_BAL = 'c_bal'


@dataclass(frozen=True)
class VelocityCommandRange:
    """Uniform ranges of the velocity command a learned policy walks at, per run."""

    vx_m_s: tuple[float, float] = (0.0, 0.0)
    vy_m_s: tuple[float, float] = (0.0, 0.0)
    yaw_rate_rad_s: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ('vx_m_s', 'vy_m_s', 'yaw_rate_rad_s'):
            low, high = getattr(self, name)
            if not (math.isfinite(low) and math.isfinite(high) and low <= high):
                raise ValueError(f'command.{name} must be [low, high] with low <= high, '
                                 f'got {[low, high]}')


@dataclass(frozen=True)
class PolicyControllerProfile:
    """A learned walking policy of the robot (``controllers.<name>`` of the profile)."""

    name: str
    policy_path: Path                   #: the deploy config (YAML) of the policy
    push_force_n: tuple[float, float]   #: force range of its datasets' 0.1 s pushes [N]
    command: VelocityCommandRange
    #: Walking before the push window opens [s] (the window is one gait period long).
    settle_s: float = 2.0
    #: The shipped model for this robot and controller: a file name in the package's models/.
    model: Optional[str] = None
    #: Its datasets' ranges of the disturbances beyond pushes (profiles/cause_ranges.py).
    causes: dict = field(default_factory=dict)


#: The keys of ``controllers.<name>``.
CONTROLLER_KEYS = frozenset({'policy', 'push_force_n', 'command', 'settle_s', 'model', 'causes'})


def parse_controllers(path: Path, raw: Any) -> dict[str, PolicyControllerProfile]:
    """The ``controllers`` mapping of profile ``path`` (ValueError naming the key when wrong)."""
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise ValueError(f'{path}: controllers must be a mapping of name -> settings')
    out = {}
    for name, fields in raw.items():
        where = f'controllers.{name}'
        if name == C_BAL:
            raise ValueError(f'{path}: {where}: {C_BAL!r} is the package\'s own balance controller '
                             '(its settings are the profile\'s controller section)')
        if not isinstance(fields, dict):
            raise ValueError(f'{path}: {where} must be a mapping')
        unknown = sorted(set(fields) - CONTROLLER_KEYS)
        if unknown:
            raise ValueError(f'{path}: {where}: unknown keys {unknown}')
        policy = fields.get('policy')
        if not isinstance(policy, str):
            raise ValueError(f'{path}: {where}.policy must name the policy\'s deploy config (YAML)')
        policy_path = (path.parent / policy).resolve()
        if not policy_path.is_file():
            raise ValueError(f'{path}: {where}.policy names {policy!r}, which is not a file '
                             f'(looked for {policy_path})')
        command = fields.get('command', {}) or {}
        if not isinstance(command, dict) or set(command) - {'vx_m_s', 'vy_m_s', 'yaw_rate_rad_s'}:
            raise ValueError(f'{path}: {where}.command takes vx_m_s, vy_m_s and yaw_rate_rad_s, '
                             f'each [low, high]')
        try:
            ranges = VelocityCommandRange(**{k: _pair(v, f'{where}.command.{k}')
                                             for k, v in command.items()})
            force = _pair(fields.get('push_force_n'), f'{where}.push_force_n')
            causes = _mapping(fields.get('causes'), f'{where}.causes')
        except ValueError as error:
            raise ValueError(f'{path}: {error}') from None
        if force[0] < 0.0:
            raise ValueError(f'{path}: {where}.push_force_n must be >= 0')
        settle = fields.get('settle_s', 2.0)
        if isinstance(settle, bool) or not isinstance(settle, (int, float)) or not 0.5 <= settle <= 60:
            raise ValueError(f'{path}: {where}.settle_s must be a number in [0.5, 60] s')
        model = fields.get('model')
        if model is not None and not isinstance(model, str):
            raise ValueError(f'{path}: {where}.model must be a file name')
        out[str(name)] = PolicyControllerProfile(str(name), policy_path, force, ranges,
                                                 float(settle), model, causes)
    return out


def _mapping(value: Any, where: str) -> dict:
    """A mapping (checked in full where it is used: profiles/cause_ranges.py), {} for none."""
    if value is not None and not isinstance(value, dict):
        raise ValueError(f'{where} must be a mapping')
    return dict(value or {})


def _pair(value: Any, where: str) -> tuple[float, float]:
    if (not isinstance(value, (list, tuple)) or len(value) != 2
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       and math.isfinite(v) for v in value) or value[0] > value[1]):
        raise ValueError(f'{where} must be [low, high] (numbers, low <= high), got {value!r}')
    return float(value[0]), float(value[1])
