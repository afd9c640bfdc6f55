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
* **an explicit ``observation:`` list** of terms, each ``- NAME: SCALE`` or ``- NAME: {scale:
  ..., relative_to_default: ..., period_s: ...}`` (terms: :data:`TERM_SIZES`).

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

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional, Union

import yaml

from fall_predictor.errors import TeamFileError
from fall_predictor.robot.networks import load_network

#: Observation terms -> their size (None: one per joint).
TERM_SIZES: dict[str, Optional[int]] = {
    'base_ang_vel': 3, 'projected_gravity': 3, 'base_euler_xyz': 3, 'command': 3,
    'joint_pos': None, 'joint_vel': None, 'last_action': None, 'gait_phase_sin_cos': 2,
}
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
            'max_cmd'}
_KNOWN = {'policy_path', 'joint_names', 'simulation_dt', 'dt', 'control_decimation', 'decimation',
          'kps', 'kds', 'default_angles', 'action_scale', 'action_offset', 'num_actions', 'num_obs',
          'num_single_obs', 'cmd_init', 'observation_layout', 'observation', 'frame_stack',
          'clip_observations', 'clip_actions', 'tau_limit', 'gait_period_s', 'cycle_time',
          'num_observations'} | _LAYOUT_FIELDS['unitree_rl_gym'] | _LAYOUT_FIELDS['humanoid_gym']


class PolicyConfigError(TeamFileError):
    """A policy config is missing, malformed or does not fit its network; the message names the
    file and the field."""


@dataclass(frozen=True)
class ObservationTerm:
    """One term of the observation: its name (:data:`TERM_SIZES`), scale (one number, or one per
    element), whether joint positions are taken relative to the default angles, and the gait
    period [s] of a phase term."""

    name: str
    scale: tuple[float, ...] = (1.0,)
    relative_to_default: bool = True
    period_s: Optional[float] = None

    def size(self, num_joints: int) -> int:
        n = TERM_SIZES[self.name]
        return num_joints if n is None else n


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
            if term.name == 'gait_phase_sin_cos' and not (term.period_s or 0) > 0:
                raise PolicyConfigError(f'{where}: observation term gait_phase_sin_cos needs a '
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
        return next((t.period_s for t in self.observation if t.name == 'gait_phase_sin_cos'), None)

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

class _Fields:
    """Typed access to the YAML mapping, naming the file and field in every error."""

    def __init__(self, path: Path, raw: dict) -> None:
        self.path, self.raw = path, raw

    def error(self, field: str, text: str) -> PolicyConfigError:
        return PolicyConfigError(f'{self.path}: {field}: {text}')

    def get(self, field: str, default: Any = ...) -> Any:
        if field not in self.raw or self.raw[field] is None and default is not ...:
            if default is ...:
                raise self.error(field, 'missing (required)')
            return default
        return self.raw[field]

    def either(self, first: str, second: str, default: Any = ...) -> Any:
        """The value of ``first`` or its synonym ``second`` (both given: they must agree)."""
        if first in self.raw and second in self.raw and self.raw[first] != self.raw[second]:
            raise self.error(first, f'{self.raw[first]!r} disagrees with {second} {self.raw[second]!r}')
        if first in self.raw:
            return self.raw[first]
        if second in self.raw:
            return self.raw[second]
        if default is ...:
            raise self.error(first, f'missing (required; humanoid-gym calls it {second})')
        return default


def _number(f: _Fields, field: str, value: Any, low: float = -math.inf, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or value < low or (positive and value <= 0):
        bound = '> 0' if positive else (f'>= {low:g}' if low > -math.inf else 'finite')
        raise f.error(field, f'must be a number {bound}, got {value!r}')
    return float(value)


def _numbers(f: _Fields, field: str, value: Any, n: int, broadcast: bool = True,
             positive: bool = False) -> tuple[float, ...]:
    """``n`` numbers from a list of ``n`` (or one number, when ``broadcast``)."""
    if broadcast and isinstance(value, (int, float)) and not isinstance(value, bool):
        return (_number(f, field, value, positive=positive),) * n
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise f.error(field, f'must be a list of {n} numbers{" or one number" if broadcast else ""}, '
                             f'got {value!r}')
    return tuple(_number(f, field, v, positive=positive) for v in value)


def _scale(f: _Fields, field: str, value: Any) -> tuple[float, ...]:
    values = [value] if not isinstance(value, (list, tuple)) else list(value)
    if not values:
        raise f.error(field, 'an empty scale')
    return tuple(_number(f, field, v) for v in values)


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
    if isinstance(value, dict):
        if set(value) != set(joints):
            raise f.error('default_angles', f'a mapping must name exactly the joint_names; missing '
                                            f'{sorted(set(joints) - set(value))}, extra '
                                            f'{sorted(set(value) - set(joints))}')
        return tuple(_number(f, 'default_angles', value[j]) for j in joints)
    return _numbers(f, 'default_angles', value, len(joints), broadcast=False)


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
            raise f.error('observation_layout', f'missing: name one of {LAYOUTS} or give an '
                                                f'observation list')
    if layout not in LAYOUTS:
        raise f.error('observation_layout', f'must be one of {LAYOUTS}, got {layout!r}')
    return layout


def _gait_period(f: _Fields, default: Optional[float]) -> Optional[float]:
    value = f.either('gait_period_s', 'cycle_time', default)
    return None if value is None else _number(f, 'gait_period_s', value, positive=True)


def _terms(f: _Fields, layout: str) -> tuple[ObservationTerm, ...]:
    foreign = set(f.raw) & (_LAYOUT_FIELDS['unitree_rl_gym'] | _LAYOUT_FIELDS['humanoid_gym'])
    foreign -= _LAYOUT_FIELDS.get(layout, set())
    if foreign:
        raise f.error(sorted(foreign)[0], f'not used by the observation layout {layout} (remove '
                                          f'it, or choose the layout it belongs to)')
    if layout == 'unitree_rl_gym':
        scale = {k: _scale(f, k, f.get(k)) for k in sorted(_LAYOUT_FIELDS[layout])}
        return (ObservationTerm('base_ang_vel', scale['ang_vel_scale']),
                ObservationTerm('projected_gravity'),
                ObservationTerm('command', scale['cmd_scale']),
                ObservationTerm('joint_pos', scale['dof_pos_scale']),
                ObservationTerm('joint_vel', scale['dof_vel_scale']),
                ObservationTerm('last_action'),
                ObservationTerm('gait_phase_sin_cos', period_s=_gait_period(f, UNITREE_GAIT_PERIOD_S)))
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
        return (ObservationTerm('gait_phase_sin_cos', period_s=_gait_period(f, None)),
                ObservationTerm('command', (s('lin_vel'), s('lin_vel'), s('ang_vel'))),
                ObservationTerm('joint_pos', (s('dof_pos'),)),
                ObservationTerm('joint_vel', (s('dof_vel'),)),
                ObservationTerm('last_action'),
                ObservationTerm('base_ang_vel', (s('ang_vel'),)),
                ObservationTerm('base_euler_xyz', (s('quat', 1.0),)))
    return _explicit_terms(f)


def _explicit_terms(f: _Fields) -> tuple[ObservationTerm, ...]:
    items = f.get('observation')
    if not isinstance(items, list) or not items:
        raise f.error('observation', 'must be a non-empty list of terms (- NAME: SCALE)')
    terms = []
    for k, item in enumerate(items):
        field = f'observation[{k}]'
        if not isinstance(item, dict) or len(item) != 1:
            raise f.error(field, f'each term is a mapping with one key, the term name, got {item!r}')
        (name, value), = item.items()
        if name not in TERM_SIZES:
            raise f.error(field, f'unknown term {name!r} (known: {", ".join(TERM_SIZES)})')
        options = value if isinstance(value, dict) else {'scale': 1.0 if value is None else value}
        unknown = set(options) - {'scale', 'relative_to_default', 'period_s'}
        if unknown:
            raise f.error(field, f'unknown options {sorted(unknown)} (scale, relative_to_default, period_s)')
        relative = options.get('relative_to_default', True)
        if not isinstance(relative, bool):
            raise f.error(field, f'relative_to_default must be true or false, got {relative!r}')
        period = options.get('period_s')
        if name == 'gait_phase_sin_cos' and period is None:
            period = _gait_period(f, None)
            if period is None:
                raise f.error(field, 'gait_phase_sin_cos needs a period: period_s here, or '
                                     'gait_period_s (cycle_time)')
        terms.append(ObservationTerm(name, _scale(f, f'{field}.scale', options.get('scale', 1.0)),
                                     relative, None if period is None
                                     else _number(f, f'{field}.period_s', period, positive=True)))
    return tuple(terms)


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
    f = _Fields(path, raw)
    unknown = sorted(set(raw) - _KNOWN - _IGNORED)
    if unknown:
        raise f.error(unknown[0], f'unknown field (known: {", ".join(sorted(_KNOWN))})')
    joints = f.get('joint_names')
    if not isinstance(joints, list) or not joints or not all(isinstance(j, str) and j for j in joints):
        raise f.error('joint_names', f'must be the list of the joint of each action, in the '
                                     f'policy\'s order (the MJCF/URDF joint names), got {joints!r}')
    joints = tuple(joints)
    n = len(joints)
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
        kp=_numbers(f, 'kps', f.get('kps'), n),
        kd=_numbers(f, 'kds', f.get('kds'), n),
        default_angles_rad=_default_angles(f, joints, layout == 'unitree_rl_gym'),
        action_scale=_numbers(f, 'action_scale', f.get('action_scale'), n),
        observation=_terms(f, layout), observation_layout=layout, action_offset=offset,
        frame_stack=frame_stack, clip_observations=_optional_positive(f, 'clip_observations'),
        clip_actions=_optional_positive(f, 'clip_actions'),
        tau_limit_nm=None if tau is None else _numbers(f, 'tau_limit', tau, n, positive=True),
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


def load_policy_config(path: Union[str, Path], check_network: bool = True) -> PolicyConfig:
    """:func:`read_policy_config`, then (by default) the network opened and its input and output
    sizes checked against the observation and the joints."""
    config = read_policy_config(path)
    if check_network:
        try:
            network = load_network(config.policy_path)
        except ValueError as exc:
            raise PolicyConfigError(f'{config.source}: policy_path: {exc}') from exc
        config.check_network(network)
    return config
