"""Where the robot is falling: a heading-frame direction predicted from the features.

The monitor publishes, with each falling event, the horizontal direction in which the CoM is
expected to leave. The physical default is the instantaneous capture point of the linear
inverted pendulum, taken relative to the feature frame's origin (the CoP, method §6): the
point the CoM "aims at" is ``xi = c + v / omega`` with ``omega = sqrt(g / c_z)``; a robot
whose capture point lies at bearing ``theta`` from the CoP tips towards ``theta``.

Everything is in the feature frame (x along the pelvis heading, y to its left, z up), so the
result is a direction in the robot's heading frame, not in the world.

A model may carry a **learned direction** (:class:`LearnedDirection`, method §8b): the momentum's
direction turned by an angle that boosted regression trees predict from
:func:`direction_inputs`, the features seen from the momentum (the CoM's offset from the CoP
and the angular momentum, each along and across it). The angular momentum along the momentum
and the CoM's offset across it carry most of the turn: a body already rotating about the axis
it moves along, or whose CoM is off to one side of its CoP, falls to that side of its momentum.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence

import numpy as np

from fall_predictor.monitor.boosted_trees import checked_tree_sum
from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2
from fall_predictor.monitor.time_to_fall import RegressionTree, TimeToFallError

#: Feature columns used: CoM position relative to the CoP [m] and linear momentum [kg m/s].
_COM_X, _COM_Y, _COM_Z, _P_X, _P_Y = 0, 1, 2, 3, 4
#: Smallest CoM height [m] used for omega (a CoM on the ground would make omega infinite).
_MIN_HEIGHT_M = 0.05


def capture_point_direction(x: Sequence[float], mass_kg: float) -> np.ndarray:
    """Unit vector (3,) in the heading frame from the CoP towards the capture point.

    Args:
        x: the 15 features of one sample (method §6, CoP frame).
        mass_kg: total robot mass [kg], to turn the linear momentum into a CoM velocity.

    Returns:
        ``(cos theta, sin theta, 0)``; ``(nan, nan, nan)`` when the direction is undefined
        (non-finite features, or the capture point exactly on the CoP).
    """
    if not (math.isfinite(mass_kg) and mass_kg > 0.0):
        raise ValueError(f'mass_kg must be a finite number > 0, got {mass_kg!r}')
    com_x, com_y, com_z = float(x[_COM_X]), float(x[_COM_Y]), float(x[_COM_Z])
    omega = math.sqrt(STANDARD_GRAVITY_M_S2 / max(com_z, _MIN_HEIGHT_M))
    xi_x = com_x + float(x[_P_X]) / (mass_kg * omega)
    xi_y = com_y + float(x[_P_Y]) / (mass_kg * omega)
    norm = math.hypot(xi_x, xi_y)
    if not (math.isfinite(norm) and norm > 0.0):
        return np.full(3, np.nan)
    return np.array([xi_x / norm, xi_y / norm, 0.0])


def angular_error_rad(predicted: Sequence[float], actual: Sequence[float]) -> float:
    """Angle [rad] in [0, pi] between two horizontal directions (their z is ignored)."""
    a = math.atan2(float(predicted[1]), float(predicted[0]))
    b = math.atan2(float(actual[1]), float(actual[0]))
    return abs((a - b + math.pi) % (2.0 * math.pi) - math.pi)


def momentum_direction(x: Sequence[float], mass_kg: float) -> np.ndarray:
    """Unit vector (3,) in the heading frame along the horizontal linear momentum.

    Same signature as :func:`capture_point_direction` (``mass_kg`` is checked but does not
    change a direction). At trigger time the CoM already moves the way it falls, while the
    capture point relative to the CoP is dominated by the CoM's offset from a CoP that sits on
    the support edge: on 36 held-out trajectories the momentum's direction erred by 10 deg
    (median) against 34 deg for the capture point (docs/results.md).

    Returns ``(nan, nan, nan)`` for non-finite or zero horizontal momentum.
    """
    if not (math.isfinite(mass_kg) and mass_kg > 0.0):
        raise ValueError(f'mass_kg must be a finite number > 0, got {mass_kg!r}')
    px, py = float(x[_P_X]), float(x[_P_Y])
    norm = math.hypot(px, py)
    if not (math.isfinite(norm) and norm > 0.0):
        return np.full(3, np.nan)
    return np.array([px / norm, py / norm, 0.0])


#: The inputs of a learned direction, in order (:func:`direction_inputs`): the horizontal
#: momentum's bearing in the heading frame (cosine, sine) and magnitude [kg m/s], the CoM
#: height above the CoP [m], the CoM's offset from the CoP along and across the momentum [m]
#: (across: to the momentum's left), and the angular momentum about the CoM along and across it
#: [kg m^2/s].
DIRECTION_INPUT_NAMES: tuple[str, ...] = (
    'bearing_cos', 'bearing_sin', 'lin_mom_xy', 'com_z', 'com_along', 'com_across',
    'ang_mom_along', 'ang_mom_across')
_ANG_X, _ANG_Y = 6, 7


class FallDirectionError(ValueError):
    """A learned direction that is malformed (the message names the field)."""


def direction_inputs(x: Sequence[float]) -> Optional[tuple[float, ...]]:
    """The :data:`DIRECTION_INPUT_NAMES` of one sample's 15 features; None when the horizontal
    momentum has no direction (zero or not finite), as :func:`momentum_direction` is NaN."""
    px, py = float(x[_P_X]), float(x[_P_Y])
    norm = math.hypot(px, py)
    if not (math.isfinite(norm) and norm > 0.0):
        return None
    c, s = px / norm, py / norm
    cx, cy = float(x[_COM_X]), float(x[_COM_Y])
    lx, ly = float(x[_ANG_X]), float(x[_ANG_Y])
    return (c, s, norm, float(x[_COM_Z]), c * cx + s * cy, c * cy - s * cx,
            c * lx + s * ly, c * ly - s * lx)


@dataclass(frozen=True)
class LearnedDirection:
    """The fall direction as the momentum's direction turned by ``bias + sum(trees(inputs))``
    radians (counter-clockwise), the trees reading :func:`direction_inputs`.

    Plain data (the trees' arrays, as :mod:`fall_predictor.monitor.boosted_trees` stores a
    mode's classifier), run as one generated Python function (a few microseconds).
    """

    trees: tuple[RegressionTree, ...]
    bias: float = 0.0
    _run: Callable[[Sequence[float]], float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        checked_tree_sum(self, len(DIRECTION_INPUT_NAMES), 'direction inputs', FallDirectionError)

    def __reduce__(self):
        # The compiled function is not picklable; it is made again from the trees.
        return LearnedDirection, (self.trees, self.bias)

    def turn_rad(self, inputs: Sequence[float]) -> float:
        """The angle [rad] from the momentum's direction to the fall direction."""
        return self._run(inputs)

    def direction(self, x: Sequence[float], mass_kg: float = 1.0) -> np.ndarray:
        """Unit vector (3,) in the heading frame (the signature of :func:`momentum_direction`;
        ``mass_kg`` is checked, unused); NaN where the momentum has no direction."""
        if not (math.isfinite(mass_kg) and mass_kg > 0.0):
            raise ValueError(f'mass_kg must be a finite number > 0, got {mass_kg!r}')
        inputs = direction_inputs(x)
        if inputs is None:
            return np.full(3, np.nan)
        angle = math.atan2(inputs[1], inputs[0]) + self._run(inputs)
        return np.array([math.cos(angle), math.sin(angle), 0.0])

    def to_json(self) -> dict[str, Any]:
        return {'inputs': list(DIRECTION_INPUT_NAMES), 'bias': self.bias,
                'trees': [tree.to_json() for tree in self.trees]}

    @classmethod
    def from_json(cls, value: Any, where: str = 'fall_direction') -> 'LearnedDirection':
        """Validated: raises :class:`FallDirectionError` naming the offending field."""
        if not isinstance(value, dict) or set(value) != {'inputs', 'bias', 'trees'}:
            raise FallDirectionError(f'{where}: expected an object with keys inputs, bias, trees')
        if value['inputs'] != list(DIRECTION_INPUT_NAMES):
            raise FallDirectionError(f'{where}.inputs: expected {list(DIRECTION_INPUT_NAMES)}, '
                                     f'got {value["inputs"]!r}')
        if not isinstance(value['trees'], list):
            raise FallDirectionError(f'{where}.trees: expected an array')
        try:
            trees = tuple(RegressionTree.from_json(raw, f'{where}.trees[{k}]',
                                                   len(DIRECTION_INPUT_NAMES))
                          for k, raw in enumerate(value['trees']))
            return cls(trees, value['bias'])
        except (TimeToFallError, FallDirectionError) as error:
            raise FallDirectionError(f'{where}: {error}' if not str(error).startswith(where)
                                     else str(error)) from error
