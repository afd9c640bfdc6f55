"""Boosted regression trees: a contact mode's classifier as a sum of small trees (method §8a).

A decision list answers falling or balanced; boosted trees give a *score*, the log-odds of
falling, ``bias + sum(tree(x))``, and say falling when the score exceeds
``decision_threshold``. Raising the threshold trades lead for fewer false alarms more finely
than the history window ``tau_his`` alone, which is where the lists' low-FPR end fell short.

Each tree is a :class:`~fall_predictor.monitor.time_to_fall.RegressionTree` (parallel arrays,
node 0 the root, children after their parent; the walk goes left when ``x[feature] <=
threshold``): the time-to-fall trees' layout and validation, reused. A NaN feature goes right
(``NaN <= t`` is false), on both paths.

At 1 kHz the monitor calls :meth:`BoostedTrees.predict_one`: the trees as one generated Python
function of nested ``if``s on the features unpacked into locals (as the decision lists are run,
:func:`~fall_predictor.monitor.decision_list._compile_predict_one`); offline,
:meth:`BoostedTrees.score` walks all rows through each tree with numpy. Both add the leaves in
tree order, so they agree bit for bit. Plain Python and numpy: no scikit-learn at run time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from fall_predictor.monitor.records import BALANCED, FALLING, INPUT_NAMES_WITH_ATTITUDE, N_FEATURES
from fall_predictor.monitor.time_to_fall import RegressionTree, TimeToFallError


class BoostedTreesError(ValueError):
    """Boosted trees that are malformed (the message names the field)."""


def _tree_source(tree: RegressionTree, node: int, indent: str, lines: list[str]) -> None:
    feature = tree.feature[node]
    if feature == -1:
        lines.append(f'{indent}s += {float(tree.value[node])!r}')
        return
    lines.append(f'{indent}if x{feature} <= {float(tree.threshold[node])!r}:')
    _tree_source(tree, tree.left[node], indent + '    ', lines)
    lines.append(f'{indent}else:')
    _tree_source(tree, tree.right[node], indent + '    ', lines)


def compile_tree_sum(trees: Sequence[RegressionTree], bias: float
                     ) -> Callable[[Sequence[float]], float]:
    """``bias`` plus the trees' leaves for one input vector (the trees' ``n_inputs`` values; only
    those the trees read are looked at), as one Python function (validated numbers only: feature
    indices and ``repr`` of finite floats, which read back bit for bit)::

        def score_one(x):
            x3 = x[3]
            ...
            s = -2.31
            if x3 <= 0.12:
                s += 0.08
            else:
                ...
            return s
    """
    used = sorted({f for tree in trees for f in tree.feature if f != -1})
    lines = ['def score_one(x):',
             *(f'    x{i} = x[{i}]' for i in used),        # only the inputs the trees read
             f'    s = {float(bias)!r}']
    for tree in trees:
        _tree_source(tree, 0, '    ', lines)
    lines.append('    return s')
    namespace: dict = {}
    exec(compile('\n'.join(lines), '<boosted trees>', 'exec'), namespace)   # numbers only
    return namespace['score_one']


def checked_tree_sum(owner: object, n_inputs: int, what: str, error: type[ValueError]) -> None:
    """Check and freeze a frozen dataclass ``owner`` with fields ``trees`` and ``bias`` that runs
    as ``bias + sum(trees(x))``: every tree a :class:`RegressionTree` over ``n_inputs`` inputs
    (``what`` names them in the error), a finite bias; sets its ``_run`` to the compiled sum.
    Raises ``error``."""
    trees = tuple(owner.trees)
    for tree in trees:
        if not isinstance(tree, RegressionTree) or tree.n_inputs != n_inputs:
            raise error(f'{type(owner).__name__} trees read the {n_inputs} {what}, got '
                        f'{type(tree).__name__} over {getattr(tree, "n_inputs", "?")} inputs')
    bias = owner.bias
    if isinstance(bias, bool) or not isinstance(bias, (int, float)) or not math.isfinite(bias):
        raise error(f'bias must be a finite number, got {bias!r}')
    object.__setattr__(owner, 'trees', trees)
    object.__setattr__(owner, 'bias', float(bias))
    object.__setattr__(owner, '_run', compile_tree_sum(trees, float(bias)))


@dataclass(frozen=True)
class BoostedTrees:
    """One contact mode's boosted trees: falling when ``bias + sum(trees(x)) > decision_threshold``.

    ``rule_size`` counts comparisons (internal nodes), as a list's does; ``depth`` counts trees.
    The trees read ``n_inputs`` values (their ``n_inputs``: the 15 features, or the 19 inputs of
    a model that also reads the base's attitude, method §8c).
    """

    trees: tuple[RegressionTree, ...]
    bias: float                          #: the score before any tree [log-odds]
    decision_threshold: float = 0.0      #: falling when the score exceeds it [log-odds]
    _score_one: Callable[[Sequence[float]], float] = field(init=False, repr=False, compare=False)
    _arrays: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'trees', tuple(self.trees))
        for tree in self.trees:
            if not isinstance(tree, RegressionTree):
                raise TypeError(f'boosted trees must be RegressionTree, got {tree!r}')
        for name in ('bias', 'decision_threshold'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise BoostedTreesError(f'{name} must be a finite number, got {value!r}')
            object.__setattr__(self, name, float(value))
        sizes = {tree.n_inputs for tree in self.trees}
        if len(sizes) > 1:
            raise BoostedTreesError(f'trees over different numbers of inputs: {sorted(sizes)}')
        object.__setattr__(self, '_score_one', compile_tree_sum(self.trees, self.bias))
        object.__setattr__(self, '_arrays', tuple(
            tuple(np.asarray(getattr(tree, k)) for k in ('feature', 'threshold', 'left', 'right', 'value'))
            for tree in self.trees))

    def __reduce__(self):
        # The compiled function is not picklable; it is made again from the trees.
        return BoostedTrees, (self.trees, self.bias, self.decision_threshold)

    @property
    def n_inputs(self) -> int:
        """Length of the input vector the trees read."""
        return self.trees[0].n_inputs if self.trees else N_FEATURES

    @property
    def rule_size(self) -> int:
        """Number of comparisons over all trees (internal nodes)."""
        return sum(sum(1 for f in tree.feature if f != -1) for tree in self.trees)

    @property
    def depth(self) -> int:
        """Number of trees."""
        return len(self.trees)

    def score_one(self, x: Sequence[float]) -> float:
        """The log-odds of falling for one input vector (:attr:`n_inputs` values)."""
        return self._score_one(x)

    def predict_one(self, x: Sequence[float]) -> int:
        """FALLING when :meth:`score_one` exceeds the decision threshold, else BALANCED."""
        return FALLING if self._score_one(x) > self.decision_threshold else BALANCED

    def score(self, X: np.ndarray) -> np.ndarray:
        """The log-odds of the rows of ``X`` (N, :attr:`n_inputs`), (N,) floats."""
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.n_inputs:
            raise ValueError(f'X must have shape (N, {self.n_inputs}), got {X.shape}')
        rows = np.arange(X.shape[0])
        total = np.full(X.shape[0], self.bias)
        for feature, threshold, left, right, value in self._arrays:
            node = np.zeros(X.shape[0], dtype=np.intp)
            inner = feature[node] != -1
            while inner.any():
                f = feature[node]
                go_left = X[rows, np.where(inner, f, 0)] <= threshold[node]
                node = np.where(inner, np.where(go_left, left[node], right[node]), node)
                inner = feature[node] != -1
            total += value[node]
        return total

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Classes (int8, (N,)) of the rows of ``X`` (N, :attr:`n_inputs`)."""
        return np.where(self.score(X) > self.decision_threshold, FALLING, BALANCED).astype(np.int8)

    def format(self, feature_names: Sequence[str] = INPUT_NAMES_WITH_ATTITUDE,
               mode_name: str | None = None) -> str:
        """A summary (the trees themselves are in the model file); the inputs named as a model's
        (the 15 features first, then the base's attitude)."""
        head = f'if footContactMode = {mode_name} then\n  ' if mode_name is not None else ''
        used = sorted({feature_names[f] for tree in self.trees for f in tree.feature if f != -1})
        return (f'{head}class <- falling if {self.bias:.4g} + the sum of {len(self.trees)} trees '
                f'({self.rule_size} comparisons on {", ".join(used) or "no feature"}) > '
                f'{self.decision_threshold:g}, else balanced.')

    def to_json(self) -> dict[str, Any]:
        return {'bias': self.bias, 'decision_threshold': self.decision_threshold,
                'trees': [tree.to_json() for tree in self.trees]}

    @classmethod
    def from_json(cls, value: Any, n_inputs: int = N_FEATURES) -> BoostedTrees:
        """Validated, trees over ``n_inputs`` inputs: raises :class:`BoostedTreesError` naming the
        offending field."""
        if not isinstance(value, dict) or set(value) != {'bias', 'decision_threshold', 'trees'}:
            raise BoostedTreesError('expected an object with keys bias, decision_threshold, trees')
        if not isinstance(value['trees'], list):
            raise BoostedTreesError('trees: expected an array')
        trees = []
        for index, raw in enumerate(value['trees']):
            try:
                trees.append(RegressionTree.from_json(raw, f'trees[{index}]', n_inputs))
            except TimeToFallError as error:
                raise BoostedTreesError(str(error)) from error
        try:
            return cls(tuple(trees), value['bias'], value['decision_threshold'])
        except (TypeError, BoostedTreesError) as error:
            raise BoostedTreesError(str(error)) from error


#: ``time_to_fall.kind`` of boosted time-to-fall trees in a model file.
BOOSTED_TIME_TO_FALL = 'boosted'


@dataclass(frozen=True)
class BoostedTimeToFall:
    """The time left until fallen [s] as ``bias + sum(trees(x))`` over the 15 features, never
    negative: the regressor fitted from each trigger to fallen (method §8d), in place of the
    per-mode trees of :class:`~fall_predictor.monitor.time_to_fall.TimeToFallRegressor` (the
    same ``predict_one(x, mode)``; the contact mode is not read). Run as one generated function,
    as the classifiers' trees are."""

    trees: tuple[RegressionTree, ...]
    bias: float
    _run: Callable[[Sequence[float]], float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        checked_tree_sum(self, N_FEATURES, 'features', BoostedTreesError)

    def __reduce__(self):
        # The compiled function is not picklable; it is made again from the trees.
        return BoostedTimeToFall, (self.trees, self.bias)

    def predict_one(self, x: Sequence[float], mode: int = 0) -> float:
        """Seconds until fallen for one sample (the 15 features ``x``), never negative."""
        return max(0.0, self._run(x))

    def to_json(self) -> dict[str, Any]:
        return {'kind': BOOSTED_TIME_TO_FALL, 'bias': self.bias,
                'trees': [tree.to_json() for tree in self.trees]}

    @classmethod
    def from_json(cls, value: Any, where: str = 'time_to_fall') -> BoostedTimeToFall:
        """Validated: raises :class:`BoostedTreesError` naming the offending field."""
        if (not isinstance(value, dict) or set(value) != {'kind', 'bias', 'trees'}
                or value['kind'] != BOOSTED_TIME_TO_FALL):
            raise BoostedTreesError(f'{where}: expected an object with keys kind '
                                    f'("{BOOSTED_TIME_TO_FALL}"), bias, trees')
        if not isinstance(value['trees'], list):
            raise BoostedTreesError(f'{where}.trees: expected an array')
        try:
            trees = tuple(RegressionTree.from_json(raw, f'{where}.trees[{k}]')
                          for k, raw in enumerate(value['trees']))
        except TimeToFallError as error:
            raise BoostedTreesError(str(error)) from error
        try:
            return cls(trees, value['bias'])
        except BoostedTreesError as error:
            raise BoostedTreesError(f'{where}: {error}') from error
