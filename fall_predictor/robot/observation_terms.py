"""The observation of a learned policy as a deploy config describes it term by term: the terms a
policy may observe (:data:`TERM_SIZES`, under makers' names too: :data:`TERM_ALIASES`), each
:class:`ObservationTerm` with its scale, clip and, for a gait clock, its period, order, offset and
what it does at a standing command; :func:`explicit_terms` reads an ``observation:`` list
(robot/policy_config.py reads the rest of the config; docs/method.md §13 has the schema)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from fall_predictor.robot.deploy_fields import Fields, number, scale

#: Observation terms -> their size (None: one per joint).
TERM_SIZES: dict[str, Optional[int]] = {
    'base_ang_vel': 3, 'projected_gravity': 3, 'base_euler_xyz': 3, 'command': 3,
    'joint_pos': None, 'joint_vel': None, 'last_action': None, 'gait_phase_sin_cos': 2,
    'gait_clock': 2, 'gait_phase': 1,
}
#: The gait clock's terms (a period, and the clock's options).
CLOCK_TERMS = ('gait_phase_sin_cos', 'gait_clock', 'gait_phase')
#: Makers' names of the terms (IsaacLab's, legged_gym's).
TERM_ALIASES = {'ang_vel': 'base_ang_vel', 'gyro': 'base_ang_vel', 'gravity': 'projected_gravity',
                'commands': 'command', 'velocity_commands': 'command', 'dof_pos': 'joint_pos',
                'joint_pos_rel': 'joint_pos', 'dof_vel': 'joint_vel', 'joint_vel_rel': 'joint_vel',
                'actions': 'last_action', 'euler': 'base_euler_xyz', 'rpy': 'base_euler_xyz',
                'clock': 'gait_clock', 'phase': 'gait_phase'}
#: The options of a term: every term's, then the clock's.
TERM_OPTIONS = ('scale', 'clip', 'relative_to_default', 'period_s', 'frequency_hz', 'order',
                'offset', 'when_standing', 'standing_below')
CLOCK_ORDERS = ('sin_cos', 'cos_sin')
STANDING_CLOCKS = ('run', 'zero', 'hold', 'reset')


@dataclass(frozen=True)
class ObservationTerm:
    """One term of the observation: its name (:data:`TERM_SIZES`), scale (one number, or one per
    element), whether joint positions are taken relative to the default angles, and the gait
    period [s] of a phase term."""

    name: str
    scale: tuple[float, ...] = (1.0,)
    relative_to_default: bool = True
    period_s: Optional[float] = None
    #: After the scale: the term's elements clipped to [low, high] (None: not clipped).
    clip: Optional[tuple[float, float]] = None
    #: A gait_clock's order of its two values: 'sin_cos' or 'cos_sin'.
    order: str = 'sin_cos'
    #: The clock's phase offset, a fraction of a cycle in [0, 1).
    offset: float = 0.0
    #: The clock at a standing command (norm <= standing_below): 'run' on, its values 'zero' (the
    #: phase held), the phase held ('hold'), or back to 0 and restarted from there ('reset').
    when_standing: str = 'run'
    standing_below: float = 0.0

    def size(self, num_joints: int) -> int:
        n = TERM_SIZES[self.name]
        return num_joints if n is None else n


def gait_period(f: Fields, default: Optional[float]) -> Optional[float]:
    """The config's gait period [s] (``gait_period_s``, humanoid-gym's ``cycle_time``), else
    ``default``."""
    value = f.either('gait_period_s', 'cycle_time', default)
    return None if value is None else number(f, 'gait_period_s', value, positive=True)


def explicit_terms(f: Fields) -> tuple[ObservationTerm, ...]:
    """The terms of an ``observation:`` list (or mapping, in the file's order)."""
    items = f.get('observation')
    if isinstance(items, dict):                 # NAME: SCALE in the file's order
        items = [{name: value} for name, value in items.items()]
    if not isinstance(items, list) or not items:
        raise f.error('observation', 'must be a non-empty list of terms (- NAME: SCALE)')
    return tuple(_term(f, f'observation[{k}]', item) for k, item in enumerate(items))


def _term(f: Fields, field: str, item: Any) -> ObservationTerm:
    """One term of an explicit observation list (module docstring)."""
    if not isinstance(item, dict) or len(item) != 1:
        raise f.error(field, f'each term is a mapping with one key, the term name, got {item!r}')
    (written, value), = item.items()
    name = TERM_ALIASES.get(written, written)
    if name not in TERM_SIZES:
        raise f.error(field, f'unknown term {written!r} (known: {", ".join(TERM_SIZES)}; also '
                             f'under the names {", ".join(TERM_ALIASES)})')
    options = value if isinstance(value, dict) else {'scale': 1.0 if value is None else value}
    options = {k: v if k in ('order', 'when_standing') else f.value_at(f'{field}.{k}', v)
               for k, v in options.items()}
    unknown = set(options) - set(TERM_OPTIONS[:3] + (TERM_OPTIONS[3:] if name in CLOCK_TERMS else ()))
    if unknown:
        known = TERM_OPTIONS if name in CLOCK_TERMS else TERM_OPTIONS[:3]
        raise f.error(field, f'unknown options {sorted(unknown)} ({", ".join(known)})')
    relative = options.get('relative_to_default', True)
    if not isinstance(relative, bool):
        raise f.error(field, f'relative_to_default must be true or false, got {relative!r}')
    clock = _clock(f, field, name, options) if name in CLOCK_TERMS else {}
    return ObservationTerm(name, scale(f, f'{field}.scale', options.get('scale', 1.0)), relative,
                           clip=_clip(f, f'{field}.clip', options.get('clip')), **clock)


def _clip(f: Fields, field: str, value: Any) -> Optional[tuple[float, float]]:
    """A term's clip: c (to [-c, c]) or [low, high]."""
    if value is None:
        return None
    if isinstance(value, (list, tuple)) and len(value) == 2:
        low, high = (number(f, field, v) for v in value)
    else:
        high = number(f, field, value, positive=True)
        low = -high
    if not low < high:
        raise f.error(field, f'must be c > 0 or [low, high] with low < high, got {value!r}')
    return low, high


def _clock(f: Fields, field: str, name: str, options: dict) -> dict[str, Any]:
    """A clock term's period and options (module docstring)."""
    period, frequency = options.get('period_s'), options.get('frequency_hz')
    if period is not None and frequency is not None:
        raise f.error(field, 'give period_s or frequency_hz, not both')
    if frequency is not None:
        period = 1.0 / number(f, f'{field}.frequency_hz', frequency, positive=True)
    if period is None:
        period = gait_period(f, None)
        if period is None:
            raise f.error(field, f'{name} needs a period: period_s here, or gait_period_s (cycle_time)')
    order = options.get('order', 'sin_cos')
    if isinstance(order, list):
        order = '_'.join(map(str, order))
    if order not in CLOCK_ORDERS or name == 'gait_phase_sin_cos' and order != 'sin_cos':
        raise f.error(f'{field}.order', f'must be one of {CLOCK_ORDERS} (gait_clock), got '
                                        f'{options.get("order")!r}')
    offset = number(f, f'{field}.offset', options.get('offset', 0.0), low=0.0)
    standing = options.get('when_standing', 'run')
    if standing not in STANDING_CLOCKS:
        raise f.error(f'{field}.when_standing', f'must be one of {STANDING_CLOCKS}, got {standing!r}')
    if not offset < 1.0:
        raise f.error(f'{field}.offset', f'is a fraction of a cycle, in [0, 1), got {offset!r}')
    return {'period_s': number(f, f'{field}.period_s', period, positive=True), 'order': order,
            'offset': offset, 'when_standing': standing,
            'standing_below': number(f, f'{field}.standing_below',
                                      options.get('standing_below', 0.0), low=0.0)}
