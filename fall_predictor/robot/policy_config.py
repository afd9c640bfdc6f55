"""A learned walking policy's deploy settings, read from the YAML file its team writes for sim2sim.

Teams that train with legged_gym or humanoid-gym deploy with a small YAML (or Python) config:
where the network is, the physics and policy rates, PD gains, default posture, action scale, and
how the observation is made. :func:`load_policy_config` reads such a file as it is:

* **unitree_rl_gym** (Unitree's ``deploy/deploy_mujoco/configs/g1.yaml``, accepted unchanged plus
  ``joint_names``): ``policy_path``, ``simulation_dt``, ``control_decimation``, ``kps``, ``kds``,
  ``default_angles``, ``ang_vel_scale``, ``dof_pos_scale``, ``dof_vel_scale``, ``action_scale``,
  ``cmd_scale``, ``num_actions``, ``num_obs``, ``cmd_init``. Observation (``deploy_mujoco.py``):
  body angular velocity x ang_vel_scale, projected gravity, command x cmd_scale, (q - default) x
  dof_pos_scale, dq x dof_vel_scale, last action, sin and cos of the gait phase (period 0.8 s,
  hard-coded there: ``gait_period_s`` changes it);
* **humanoid_gym** (its ``sim2sim.py`` settings under its own names): ``dt``, ``decimation``,
  ``frame_stack``, ``num_single_obs``, ``obs_scales: {lin_vel, ang_vel, dof_pos, dof_vel,
  quat}``, ``cycle_time``, ``clip_observations``, ``clip_actions``, ``tau_limit``. Observation:
  sin and cos of the phase, command x (lin_vel, lin_vel, ang_vel), (q - default) x dof_pos,
  dq x dof_vel, last action, body angular velocity x ang_vel, base Euler angles x quat; the last
  ``frame_stack`` frames stacked oldest first;
* **an explicit ``observation:`` list** of terms in the network's order, each ``- NAME: SCALE`` or
  ``- NAME: {scale: ..., clip: ..., ...}`` (robot/observation_terms.py: the terms
  ``TERM_SIZES``, under their own or a maker's name ``TERM_ALIASES``; the options
  ``TERM_OPTIONS``): any other policy's observation. A gait clock is ``gait_clock`` (``order: cos_sin`` or ``sin_cos``, ``period_s`` or
  ``frequency_hz``, ``offset`` as a fraction of a cycle, ``when_standing``: ``run``, ``zero``,
  ``hold`` or ``reset`` below ``standing_below`` of the command's norm) or ``gait_phase`` (the
  phase itself, in [0, 1)).

A maker's file is read in its own shape (:mod:`~fall_predictor.robot.deploy_fields`): fields in
sections (``common:``, ``policy:``), under the maker's names (``stiffness``, ``default_qpos``, or
any name mapped by ``field_names``), gains and angles per joint as mappings. The schema, with
examples, is in docs/method.md §13 ("A deploy config of any layout").

Added by this package: ``joint_names`` (required: the MJCF/URDF joint of each action, in the
policy's order), ``observation_layout`` (default: unitree_rl_gym when its scale fields are there,
humanoid_gym when ``obs_scales`` is), ``frame_stack`` (1), ``clip_observations`` and
``clip_actions`` (none), ``tau_limit`` (none: the simulator model's), ``action_offset``
(``default_angles``: target = action x action_scale + default; or ``zero``), ``gait_period_s``.

Paths are relative to the YAML file; ``{LEGGED_GYM_ROOT_DIR}`` placeholders are refused. Every
error is a :class:`PolicyConfigError` naming the file and the field; :func:`load_policy_config`
also checks the observation length against the network's input, and the actions against its
output and the joints.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional, Union

import yaml

from fall_predictor.robot.deploy_fields import (Fields as _Fields, PolicyConfigError, flatten,
                                                number as _number, numbers as _numbers,
                                                scale as _scale)
from fall_predictor.robot.networks import load_network
from fall_predictor.robot.observation_terms import (CLOCK_TERMS, TERM_SIZES, ObservationTerm,
                                                   explicit_terms, gait_period)

__all__ = ['PolicyConfig', 'PolicyConfigError', 'ObservationTerm', 'load_policy_config',
           'read_policy_config']

LAYOUTS = ('unitree_rl_gym', 'humanoid_gym')
ACTION_OFFSETS = ('default_angles', 'zero')
#: Unitree's deploy_mujoco.py: the gait period it hard-codes [s].
UNITREE_GAIT_PERIOD_S = 0.8
#: Fields each layout reads for its scales: a field of the other layout is a mistake.
_LAYOUT_FIELDS = {'unitree_rl_gym': {'ang_vel_scale', 'dof_pos_scale', 'dof_vel_scale', 'cmd_scale'},
                  'humanoid_gym': {'obs_scales'}}
#: Fields of the deploy scripts of those projects that a policy here does not use.
_IGNORED = {'xml_path', 'simulation_duration', 'sim_duration', 'mujoco_model_path', 'control_dt',
            'msg_type', 'imu_type', 'lowcmd_topic', 'lowstate_topic', 'leg_joint2motor_idx',
            'arm_waist_joint2motor_idx', 'arm_waist_kps', 'arm_waist_kds', 'arm_waist_target',
            'max_cmd', 'joint2motor_idx'}
_KNOWN = {'policy_path', 'joint_names', 'simulation_dt', 'dt', 'control_decimation', 'decimation',
          'kps', 'kds', 'default_angles', 'action_scale', 'action_offset', 'num_actions', 'num_obs',
          'num_single_obs', 'cmd_init', 'observation_layout', 'observation', 'frame_stack',
          'clip_observations', 'clip_actions', 'tau_limit', 'gait_period_s', 'cycle_time',
          'num_observations', 'field_names', 'ignored_fields', 'motor_joint_names'} \
    | _LAYOUT_FIELDS['unitree_rl_gym'] | _LAYOUT_FIELDS['humanoid_gym']
#: Where the schema of a deploy config is told, for the errors that need it.
SCHEMA_DOC = 'docs/method.md §13, "A deploy config of any layout"'


@dataclass(frozen=True)
class PolicyConfig:
    """A learned policy's deploy settings (see the module docstring); arrays in joint order."""

    source: Path                        #: the YAML file
    policy_path: Path                   #: the network (.pt or .onnx)
    joint_names: tuple[str, ...]        #: the joint of each action, in the policy's order
    physics_dt_s: float                 #: the simulation step the policy was deployed with [s]
    decimation: int                     #: physics steps per policy step
    kp: tuple[float, ...]               #: [N m/rad]
    kd: tuple[float, ...]               #: [N m s/rad]
    default_angles_rad: tuple[float, ...]
    action_scale: tuple[float, ...]     #: per joint [rad per action unit]
    observation: tuple[ObservationTerm, ...]
    observation_layout: str = 'custom'  #: unitree_rl_gym, humanoid_gym or custom
    action_offset: str = 'default_angles'
    frame_stack: int = 1
    clip_observations: Optional[float] = None
    clip_actions: Optional[float] = None
    tau_limit_nm: Optional[tuple[float, ...]] = None
    command_init: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        n, where = len(self.joint_names), self.source
        if n == 0 or len(set(self.joint_names)) != n:
            raise PolicyConfigError(f'{where}: joint_names must name each joint once, got {self.joint_names!r}')
        for name in ('kp', 'kd', 'default_angles_rad', 'action_scale') + (
                ('tau_limit_nm',) if self.tau_limit_nm is not None else ()):
            if len(getattr(self, name)) != n:
                raise PolicyConfigError(f'{where}: {name} has {len(getattr(self, name))} values for '
                                        f'{n} joints')
        if not (self.physics_dt_s > 0 and self.decimation >= 1 and self.frame_stack >= 1):
            raise PolicyConfigError(f'{where}: need physics_dt_s > 0, decimation >= 1, frame_stack >= 1')
        if self.action_offset not in ACTION_OFFSETS:
            raise PolicyConfigError(f'{where}: action_offset must be one of {ACTION_OFFSETS}, '
                                    f'got {self.action_offset!r}')
        for term in self.observation:
            if term.name not in TERM_SIZES:
                raise PolicyConfigError(f'{where}: unknown observation term {term.name!r} '
                                        f'(known: {", ".join(TERM_SIZES)})')
            if len(term.scale) not in (1, term.size(n)):
                raise PolicyConfigError(f'{where}: observation term {term.name} needs 1 or '
                                        f'{term.size(n)} scales, got {len(term.scale)}')
            if term.name in CLOCK_TERMS and not (term.period_s or 0) > 0:
                raise PolicyConfigError(f'{where}: observation term {term.name} needs a '
                                        f'period > 0 [s] (gait_period_s or cycle_time)')

    @property
    def period_s(self) -> float:
        """The policy period [s]: physics step x decimation."""
        return self.physics_dt_s * self.decimation

    @property
    def num_actions(self) -> int:
        return len(self.joint_names)

    @property
    def gait_period_s(self) -> Optional[float]:
        """The period of the policy's gait clock [s] (its phase observation), or None."""
        return next((t.period_s for t in self.observation if t.name in CLOCK_TERMS), None)

    @property
    def single_obs_size(self) -> int:
        """The length of one observation frame."""
        return sum(t.size(self.num_actions) for t in self.observation)

    @property
    def obs_size(self) -> int:
        """The length of the network's input: one frame x frame_stack."""
        return self.single_obs_size * self.frame_stack

    def check_network(self, network: Any) -> None:
        """PolicyConfigError unless the network takes this observation and gives one action per
        joint."""
        where = f'{self.source}: policy_path {self.policy_path.name}'
        if network.input_size != self.obs_size:
            raise PolicyConfigError(
                f'{where}: the network takes {network.input_size} inputs, the observation has '
                f'{self.obs_size} ({self.single_obs_size} per frame x frame_stack {self.frame_stack}: '
                + ', '.join(f'{t.name} {t.size(self.num_actions)}' for t in self.observation) + ')')
        if network.output_size != self.num_actions:
            raise PolicyConfigError(f'{where}: the network gives {network.output_size} actions for '
                                    f'{self.num_actions} joint_names')


# -- reading -------------------------------------------------------------------------------------

def _policy_path(f: _Fields) -> Path:
    text = f.get('policy_path')
    if not isinstance(text, str) or not text:
        raise f.error('policy_path', f'must be a path (relative to the YAML file), got {text!r}')
    if '{' in text:
        raise f.error('policy_path', f'{text!r} holds a placeholder ({{LEGGED_GYM_ROOT_DIR}} or '
                                     f'similar), which this package does not expand: write the path '
                                     f'relative to the YAML file (or absolute)')
    path = (f.path.parent / Path(text).expanduser()).resolve()
    if not path.is_file():
        raise f.error('policy_path', f'{text!r} is not a file (looked for {path})')
    return path


def _default_angles(f: _Fields, joints: tuple[str, ...], required: bool) -> tuple[float, ...]:
    value = f.get('default_angles', ... if required else None)
    if value is None:
        return (0.0,) * len(joints)
    return _numbers(f, 'default_angles', value, len(joints), broadcast=False, joints=joints)


def _layout(f: _Fields) -> str:
    if 'observation' in f.raw:
        if 'observation_layout' in f.raw:
            raise f.error('observation', 'give either observation_layout or an observation list, not both')
        return 'custom'
    layout = f.raw.get('observation_layout')
    if layout is None:
        if _LAYOUT_FIELDS['unitree_rl_gym'] & set(f.raw):
            layout = 'unitree_rl_gym'
        elif 'obs_scales' in f.raw:
            layout = 'humanoid_gym'
        else:
            raise f.error('observation_layout', f'missing: name one of {LAYOUTS} or, for a config '
                                                f'of another layout, describe the network\'s input '
                                                f'as an observation: list of terms in its order '
                                                f'({SCHEMA_DOC})')
    if layout not in LAYOUTS:
        raise f.error('observation_layout', f'must be one of {LAYOUTS}, got {layout!r}')
    return layout


def _terms(f: _Fields, layout: str) -> tuple[ObservationTerm, ...]:
    foreign = set(f.raw) & (_LAYOUT_FIELDS['unitree_rl_gym'] | _LAYOUT_FIELDS['humanoid_gym'])
    foreign -= _LAYOUT_FIELDS.get(layout, set())
    foreign = {k for k in foreign if not _ignored(f.where.get(k, k), f.ignored)}
    if foreign:
        raise f.error(sorted(foreign)[0], f'not used by the observation layout {layout} (remove '
                                          f'it, list it under ignored_fields, or choose the layout '
                                          f'it belongs to)')
    if layout == 'unitree_rl_gym':
        scale = {k: _scale(f, k, f.get(k)) for k in sorted(_LAYOUT_FIELDS[layout])}
        return (ObservationTerm('base_ang_vel', scale['ang_vel_scale']),
                ObservationTerm('projected_gravity'),
                ObservationTerm('command', scale['cmd_scale']),
                ObservationTerm('joint_pos', scale['dof_pos_scale']),
                ObservationTerm('joint_vel', scale['dof_vel_scale']),
                ObservationTerm('last_action'),
                ObservationTerm('gait_phase_sin_cos', period_s=gait_period(f, UNITREE_GAIT_PERIOD_S)))
    if layout == 'humanoid_gym':
        scales = f.get('obs_scales')
        if not isinstance(scales, dict):
            raise f.error('obs_scales', f'must be a mapping (lin_vel, ang_vel, dof_pos, dof_vel, '
                                        f'quat), got {scales!r}')
        unknown = set(scales) - {'lin_vel', 'ang_vel', 'dof_pos', 'dof_vel', 'quat', 'height_measurements'}
        if unknown:
            raise f.error('obs_scales', f'unknown entries {sorted(unknown)}')

        def s(key: str, default: Any = ...) -> float:
            if key not in scales and default is ...:
                raise f.error(f'obs_scales.{key}', 'missing (required)')
            return _number(f, f'obs_scales.{key}', scales.get(key, default))
        return (ObservationTerm('gait_phase_sin_cos', period_s=gait_period(f, None)),
                ObservationTerm('command', (s('lin_vel'), s('lin_vel'), s('ang_vel'))),
                ObservationTerm('joint_pos', (s('dof_pos'),)),
                ObservationTerm('joint_vel', (s('dof_vel'),)),
                ObservationTerm('last_action'),
                ObservationTerm('base_ang_vel', (s('ang_vel'),)),
                ObservationTerm('base_euler_xyz', (s('quat', 1.0),)))
    return explicit_terms(f)


def _optional_positive(f: _Fields, field: str) -> Optional[float]:
    value = f.get(field, None)
    return None if value is None else _number(f, field, value, positive=True)


def read_policy_config(path: Union[str, Path]) -> PolicyConfig:
    """Read and check a policy YAML (see the module docstring), without opening the network."""
    path = Path(path).expanduser().resolve()
    if not path.is_file():
        raise PolicyConfigError(f'{path}: no such policy config file')
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise PolicyConfigError(f'{path}: not valid YAML: {exc}') from exc
    if not isinstance(raw, dict):
        raise PolicyConfigError(f'{path}: the file must be a mapping of fields')
    flat, where = flatten(path, raw)
    f = _Fields(path, flat, where, raw)
    ignored = f.get('ignored_fields', [])
    if not isinstance(ignored, list) or not all(isinstance(i, str) for i in ignored):
        raise f.error('ignored_fields', f'must be a list of field or section names, got {ignored!r}')
    # The team's fields a term takes its scale, clip or clock from are read, not unknown.
    f.ignored = ignored + _references(f, flat.get('observation'))
    unknown = sorted(k for k in set(flat) - _KNOWN - _IGNORED if not _ignored(where[k], f.ignored))
    if unknown:
        raise f.error(unknown[0], f'unknown field (known: {", ".join(sorted(_KNOWN))}; a field of '
                                  f'your own under another name: field_names: {{{where[unknown[0]]}: '
                                  f'KNOWN}}; one this package does not use: ignored_fields: '
                                  f'[{where[unknown[0]]}]; {SCHEMA_DOC})')
    joints = f.get('joint_names')
    if not isinstance(joints, list) or not joints or not all(isinstance(j, str) and j for j in joints):
        raise f.error('joint_names', f'must be the list of the joint of each action, in the '
                                     f'policy\'s order (the MJCF/URDF joint names), got {joints!r}')
    joints = tuple(joints)
    n = len(joints)
    motors = f.get('motor_joint_names', None)
    if motors is not None:
        names = motors if isinstance(motors, list) and all(isinstance(m, str) for m in motors) else []
        if not names or len(set(names)) != len(names) or set(joints) - set(names):
            raise f.error('motor_joint_names', f'must list each motor once, every joint_names entry '
                                               f'among them; missing {sorted(set(joints) - set(names))}')
        f.motor_order = (motors, [motors.index(j) for j in joints])
    num_actions = f.get('num_actions', n)
    if num_actions != n:
        raise f.error('num_actions', f'{num_actions!r}, but joint_names names {n} joints')
    layout = _layout(f)
    decimation = f.either('control_decimation', 'decimation')
    if isinstance(decimation, bool) or not isinstance(decimation, int) or decimation < 1:
        raise f.error('control_decimation', f'must be an integer >= 1, got {decimation!r}')
    frame_stack = f.get('frame_stack', 1)
    if isinstance(frame_stack, bool) or not isinstance(frame_stack, int) or frame_stack < 1:
        raise f.error('frame_stack', f'must be an integer >= 1, got {frame_stack!r}')
    tau = f.get('tau_limit', None)
    offset = f.get('action_offset', 'default_angles')
    if offset not in ACTION_OFFSETS:
        raise f.error('action_offset', f'must be one of {ACTION_OFFSETS}, got {offset!r}')
    config = PolicyConfig(
        source=path, policy_path=_policy_path(f), joint_names=joints,
        physics_dt_s=_number(f, 'simulation_dt', f.either('simulation_dt', 'dt'), positive=True),
        decimation=decimation,
        kp=_numbers(f, 'kps', f.get('kps'), n, joints=joints),
        kd=_numbers(f, 'kds', f.get('kds'), n, joints=joints),
        default_angles_rad=_default_angles(f, joints, layout == 'unitree_rl_gym'),
        action_scale=_numbers(f, 'action_scale', f.get('action_scale'), n, joints=joints),
        observation=_terms(f, layout), observation_layout=layout, action_offset=offset,
        frame_stack=frame_stack, clip_observations=_optional_positive(f, 'clip_observations'),
        clip_actions=_optional_positive(f, 'clip_actions'),
        tau_limit_nm=None if tau is None else _numbers(f, 'tau_limit', tau, n, positive=True,
                                                       joints=joints),
        command_init=_numbers(f, 'cmd_init', f.get('cmd_init', [0.0, 0.0, 0.0]), 3, broadcast=False))
    if any(k < 0 for k in config.kp + config.kd):
        raise f.error('kps', 'gains must be >= 0')
    num_obs = f.either('num_obs', 'num_single_obs', None)
    if num_obs is not None and num_obs != config.single_obs_size:
        raise f.error('num_obs', f'{num_obs!r}, but the observation layout {layout} makes '
                                 f'{config.single_obs_size} values per frame for {n} joints')
    total = f.get('num_observations', None)
    if total is not None and total != config.obs_size:
        raise f.error('num_observations', f'{total!r}, but {config.single_obs_size} values per frame '
                                          f'x frame_stack {frame_stack} make {config.obs_size}')
    return config


def _references(f: _Fields, items: Any) -> list[str]:
    """The fields of the file an observation list's options name (``scale: policy.dof_vel``),
    each checked to hold a number."""
    out = []
    if isinstance(items, dict):
        items = [{name: value} for name, value in items.items()]
    for k, item in enumerate(items if isinstance(items, list) else []):
        for value in item.values() if isinstance(item, dict) else []:
            options = value if isinstance(value, dict) else {'scale': value}
            for key, v in options.items():
                names = [x for x in (v if isinstance(v, list) else [v]) if isinstance(x, str)]
                if key not in ('order', 'when_standing') and names:
                    f.value_at(f'observation[{k}].{key}', names)
                    out += names
    return out


def _ignored(dotted: str, ignored: list[str]) -> bool:
    """Whether a field written at ``dotted`` is listed in ``ignored`` (ignored_fields and the
    fields the observation reads), lies in a section listed, or holds a value listed."""
    return any(dotted == i or dotted.startswith(i + '.') or i.startswith(dotted + '.')
               or dotted.rsplit('.', 1)[-1] == i for i in ignored)


def load_policy_config(path: Union[str, Path], check_network: bool = True) -> PolicyConfig:
    """:func:`read_policy_config`, then (by default) the network opened and its input and output
    sizes checked against the observation and the joints."""
    config = _read_once(path)
    if check_network:
        try:
            network = load_network(config.policy_path)
        except ValueError as exc:
            raise PolicyConfigError(f'{config.source}: policy_path: {exc}') from exc
        config.check_network(network)
    return config


def _read_once(path: Union[str, Path]) -> PolicyConfig:
    """:func:`read_policy_config`, parsed once per process for each version of the file (every
    tool and node that needs a controller's deploy config shares the same frozen config)."""
    try:
        resolved = Path(path).resolve()
        stat = resolved.stat()
    except OSError:
        return read_policy_config(path)          # says which file is missing, as it says it
    return _read_version(resolved, stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=64)
def _read_version(path: Path, mtime_ns: int, size: int) -> PolicyConfig:
    return read_policy_config(path)

