"""Time left until fallen: a per-contact-mode regression tree on the 15 features.

With every falling prediction the monitor can say how many seconds remain until the robot is
fallen (method §5's ``t_fallen``). The model is one binary regression tree per contact mode,
trained (:mod:`fall_predictor.learning.time_to_fall_training`) on the falling states of falling
trajectories, with the target ``t_fallen - t``; a mode with too few falling states uses the
tree fitted on all modes (``fallback``). At run time a prediction is a walk down one tree:
plain Python, no scikit-learn. A model may carry instead boosted trees fitted from each of its
triggers until fallen (method §8d; :class:`~fall_predictor.monitor.boosted_trees.BoostedTimeToFall`,
the same ``predict_one(x, mode)``).

A tree is stored as parallel arrays (JSON-friendly)::

    {"feature": [2, -1, -1], "threshold": [0.41, 0.0, 0.0], "left": [1, -1, -1],
     "right": [2, -1, -1], "value": [0.0, 0.31, 0.12]}

node ``i`` is a leaf when ``feature[i] == -1`` (its prediction is ``value[i]`` seconds), else
the walk goes to ``left[i]`` when ``x[feature[i]] <= threshold[i]`` and to ``right[i]``
otherwise. Node 0 is the root.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Optional, Sequence

from fall_predictor.monitor.records import N_CONTACT_MODES, N_FEATURES

_KEYS = ('feature', 'threshold', 'left', 'right', 'value')


class TimeToFallError(ValueError):
    """A time-to-fall model that is malformed (the message names the field)."""


@dataclass(frozen=True)
class RegressionTree:
    """One binary regression tree (see the module docstring for the layout)."""

    feature: tuple[int, ...]
    threshold: tuple[float, ...]
    left: tuple[int, ...]
    right: tuple[int, ...]
    value: tuple[float, ...]
    #: Length of the input vector a walk reads (feature indices must be below it): the 15
    #: features unless the tree reads other inputs (the learned fall direction's).
    n_inputs: int = field(default=N_FEATURES, compare=False)

    def __post_init__(self) -> None:
        n = len(self.feature)
        if n == 0 or any(len(getattr(self, k)) != n for k in _KEYS):
            raise TimeToFallError(f'tree arrays must be non-empty and of equal length, got '
                                  f'{[len(getattr(self, k)) for k in _KEYS]}')
        for i in range(n):
            f = self.feature[i]
            if not all(math.isfinite(v) for v in (self.threshold[i], self.value[i])):
                raise TimeToFallError(f'node {i}: non-finite threshold or value')
            if f == -1:
                continue
            if not 0 <= f < self.n_inputs:
                raise TimeToFallError(f'node {i}: feature index {f} not in [0, {self.n_inputs})')
            # Children come after their parent: the walk always ends, on a leaf.
            if not (i < self.left[i] < n and i < self.right[i] < n):
                raise TimeToFallError(f'node {i}: children {self.left[i]}, {self.right[i]} '
                                      f'must be in ({i}, {n})')

    def predict_one(self, x: Sequence[float]) -> float:
        """The leaf value [s] for one feature vector."""
        i = 0
        feature, threshold = self.feature, self.threshold
        while feature[i] != -1:
            i = self.left[i] if x[feature[i]] <= threshold[i] else self.right[i]
        return self.value[i]

    @property
    def depth(self) -> int:
        depths = [0] * len(self.feature)
        for i, f in enumerate(self.feature):
            if f != -1:
                depths[self.left[i]] = depths[self.right[i]] = depths[i] + 1
        return max(depths)

    def to_json(self) -> dict[str, list]:
        return {k: list(getattr(self, k)) for k in _KEYS}

    @classmethod
    def from_json(cls, doc: Any, where: str, n_inputs: int = N_FEATURES) -> 'RegressionTree':
        if not isinstance(doc, dict) or set(doc) != set(_KEYS):
            raise TimeToFallError(f'{where}: expected an object with keys {list(_KEYS)}')
        try:
            ints = {k: tuple(_int(v) for v in doc[k]) for k in ('feature', 'left', 'right')}
            floats = {k: tuple(_float(v) for v in doc[k]) for k in ('threshold', 'value')}
            return cls(**ints, **floats, n_inputs=n_inputs)
        except (TypeError, TimeToFallError) as error:
            raise TimeToFallError(f'{where}: {error}') from error


def _int(v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise TimeToFallError(f'expected an integer, got {v!r}')
    return v


def _float(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise TimeToFallError(f'expected a finite number, got {v!r}')
    return float(v)


@dataclass(frozen=True)
class TimeToFallRegressor:
    """Per-mode regression trees predicting the time [s] left until fallen.

    ``trees[mode]`` is None for a mode without its own tree; ``fallback`` serves it.
    """

    trees: tuple[Optional[RegressionTree], ...]
    fallback: RegressionTree

    def __post_init__(self) -> None:
        if len(self.trees) != N_CONTACT_MODES:
            raise TimeToFallError(f'expected {N_CONTACT_MODES} trees (one per contact mode, '
                                  f'null allowed), got {len(self.trees)}')

    def predict_one(self, x: Sequence[float], mode: int) -> float:
        """Seconds until fallen predicted for one sample (features ``x``, contact ``mode``),
        never negative."""
        tree = self.trees[mode] or self.fallback
        return max(0.0, tree.predict_one(x))

    def to_json(self) -> dict[str, Any]:
        return {'trees': [None if t is None else t.to_json() for t in self.trees],
                'fallback': self.fallback.to_json()}

    @classmethod
    def from_json(cls, doc: Any, where: str = 'time_to_fall') -> 'TimeToFallRegressor':
        if not isinstance(doc, dict) or set(doc) != {'trees', 'fallback'}:
            raise TimeToFallError(f'{where}: expected an object with keys trees, fallback')
        if not isinstance(doc['trees'], list):
            raise TimeToFallError(f'{where}.trees: expected an array')
        trees = tuple(None if t is None else RegressionTree.from_json(t, f'{where}.trees[{m}]')
                      for m, t in enumerate(doc['trees']))
        try:
            return cls(trees, RegressionTree.from_json(doc['fallback'], f'{where}.fallback'))
        except TimeToFallError as error:
            raise TimeToFallError(f'{where}: {error}') from error
