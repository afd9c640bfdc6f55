"""Decision lists (method §8, Fig. 8 of the paper): the learned fall predictor's model.

A :class:`DecisionList` is an ordered list of if-then rules; each rule is a conjunction of
threshold comparisons on the 15 real features (:data:`~fall_predictor.monitor.records.FEATURE_NAMES`)
and the first rule whose conditions all hold decides the class; if none holds, the list's
default class (balanced) does. A :class:`PerModeDecisionLists` holds one list per foot contact
mode (16, :data:`~fall_predictor.monitor.records.CONTACT_MODE_NAMES`).

Comparisons follow IEEE semantics: a NaN feature value satisfies neither ``<=`` nor ``>``, so a
condition on a NaN feature never holds (a rule without conditions still matches). The scalar
path (:meth:`DecisionList.predict_one`) and the vectorised path (:meth:`DecisionList.predict`)
agree on every input, NaN included.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable, Literal, Sequence

import numpy as np

from fall_predictor.monitor.boosted_trees import BoostedTrees
from fall_predictor.monitor.records import (BALANCED, CLASS_NAMES, CONTACT_MODE_NAMES, FALLING,
                                    FEATURE_NAMES, N_CONTACT_MODES, N_FEATURES)

#: Comparison operators a condition may use: ``feature <= threshold`` or ``feature > threshold``.
ComparisonOp = Literal['<=', '>']
COMPARISON_OPS: tuple[str, ...] = ('<=', '>')
#: Classes a rule or a default may predict (FALLEN is a state class, never a prediction).
PREDICTED_CLASSES: tuple[int, ...] = (BALANCED, FALLING)


@dataclass(frozen=True, slots=True)
class Condition:
    """One threshold comparison ``X[feature] <op> threshold`` (units: those of the feature)."""

    feature: int                #: column index into :data:`FEATURE_NAMES`
    op: ComparisonOp            #: ``'<='`` or ``'>'``
    threshold: float

    def __post_init__(self) -> None:
        if isinstance(self.feature, bool) or not isinstance(self.feature, (int, np.integer)):
            raise TypeError(f'feature index must be an int, got {self.feature!r}')
        if not 0 <= self.feature < N_FEATURES:
            raise ValueError(f'feature index {self.feature} outside [0, {N_FEATURES})')
        if self.op not in COMPARISON_OPS:
            raise ValueError(f'unknown comparison operator {self.op!r}; expected one of {COMPARISON_OPS}')
        if not math.isfinite(self.threshold):
            raise ValueError(f'threshold must be finite, got {self.threshold!r}')
        object.__setattr__(self, 'feature', int(self.feature))
        object.__setattr__(self, 'threshold', float(self.threshold))

    def holds(self, X: np.ndarray) -> np.ndarray:
        """Boolean mask over the rows of ``X`` (N, 15) where the comparison holds."""
        column = X[:, self.feature]
        return column <= self.threshold if self.op == '<=' else column > self.threshold

    def format(self, feature_names: Sequence[str] = FEATURE_NAMES) -> str:
        """Human-readable form, e.g. ``com_z <= 0.35``."""
        return f'{feature_names[self.feature]} {self.op} {self.threshold:.4g}'


@dataclass(frozen=True, slots=True)
class Rule:
    """``if all conditions hold then class <- label``; no conditions means always."""

    conditions: tuple[Condition, ...]
    label: int

    def __post_init__(self) -> None:
        object.__setattr__(self, 'conditions', tuple(self.conditions))
        for condition in self.conditions:
            if not isinstance(condition, Condition):
                raise TypeError(f'rule conditions must be Condition, got {condition!r}')
        if self.label not in PREDICTED_CLASSES:
            raise ValueError(f'rule label must be BALANCED or FALLING, got {self.label!r}')

    @property
    def size(self) -> int:
        """Number of comparisons in the rule."""
        return len(self.conditions)

    def matches(self, X: np.ndarray) -> np.ndarray:
        """Boolean mask over the rows of ``X`` (N, 15) where every condition holds."""
        mask = np.ones(X.shape[0], dtype=bool)
        for condition in self.conditions:
            mask &= condition.holds(X)
        return mask


def simplify_conditions(conditions: Sequence[Condition]) -> tuple[Condition, ...]:
    """Merge redundant comparisons on the same feature and direction.

    Several ``<=`` comparisons on one feature reduce to the smallest threshold, several ``>``
    to the largest. The result keeps the order in which each (feature, op) pair first occurs
    and holds on exactly the same inputs as the conjunction of ``conditions``.
    """
    tightest: dict[tuple[int, str], float] = {}
    for condition in conditions:
        key = (condition.feature, condition.op)
        if key not in tightest:
            tightest[key] = condition.threshold
        elif condition.op == '<=':
            tightest[key] = min(tightest[key], condition.threshold)
        else:
            tightest[key] = max(tightest[key], condition.threshold)
    return tuple(Condition(feature, op, threshold) for (feature, op), threshold in tightest.items())


@dataclass(frozen=True)
class DecisionList:
    """An ordered decision list: the first matching rule wins, else ``default``.

    ``rule_size`` counts comparisons (method §8: the paper's "rule size"), ``depth`` counts rules.
    """

    rules: tuple[Rule, ...] = ()
    default: int = BALANCED
    #: The scalar path, :meth:`predict_one`, as Python code made from ``rules`` (derived from
    #: them, not part of the value; see :func:`_compile_predict_one`).
    _predict_one: Callable[[Sequence[float]], int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'rules', tuple(self.rules))
        for rule in self.rules:
            if not isinstance(rule, Rule):
                raise TypeError(f'decision list rules must be Rule, got {rule!r}')
        if self.default not in PREDICTED_CLASSES:
            raise ValueError(f'default class must be BALANCED or FALLING, got {self.default!r}')
        object.__setattr__(self, '_predict_one', _compile_predict_one(self.rules, self.default))

    def __reduce__(self):
        # The compiled function is not picklable; it is made again from the rules.
        return DecisionList, (self.rules, self.default)

    @property
    def rule_size(self) -> int:
        """Number of comparisons in the whole list (method §8)."""
        return sum(rule.size for rule in self.rules)

    @property
    def depth(self) -> int:
        """Number of rules (the default does not count)."""
        return len(self.rules)

    def predict_one(self, x: Sequence[float]) -> int:
        """Class of one feature vector ``x`` (15 values, or more: a model's inputs begin with the
        15 features; a list of floats is fastest)."""
        return self._predict_one(x)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Classes of the rows of ``X`` (N, 15 or more: the 15 features first) as an int8 array (N,)."""
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] < N_FEATURES:
            raise ValueError(f'X must have shape (N, {N_FEATURES} or more), got {X.shape}')
        out = np.full(X.shape[0], self.default, dtype=np.int8)
        undecided = np.ones(X.shape[0], dtype=bool)
        for rule in self.rules:
            fires = undecided & rule.matches(X)
            out[fires] = rule.label
            undecided &= ~fires
        return out

    def format(self, feature_names: Sequence[str] = FEATURE_NAMES, mode_name: str | None = None) -> str:
        """The list in the paper's Fig. 8 form (``>``/``<=`` as stored, thresholds to 4 digits).

        With ``mode_name`` the rules are nested under ``if footContactMode = <mode_name> then``.
        """
        lines: list[str] = []
        indent = ''
        if mode_name is not None:
            lines.append(f'if footContactMode = {mode_name} then')
            indent = '  '
        for index, rule in enumerate(self.rules):
            keyword = 'if' if index == 0 else 'else if'
            condition_text = ' and '.join(c.format(feature_names) for c in rule.conditions) or 'true'
            lines.append(f'{indent}{keyword} {condition_text} then')
            lines.append(f'{indent}  class <- {CLASS_NAMES[rule.label]}.')
        if self.rules:
            lines.append(f'{indent}else')
            lines.append(f'{indent}  class <- {CLASS_NAMES[self.default]}.')
        else:
            lines.append(f'{indent}class <- {CLASS_NAMES[self.default]}.')
        return '\n'.join(lines)


def _compile_predict_one(rules: Sequence[Rule], default: int) -> Callable[[Sequence[float]], int]:
    """The list as one Python function, an ``if`` per rule on the features unpacked into locals:

        def predict_one(x):
            x2 = x[2]
            x9 = x[9]
            if x2 <= 0.5123 and x9 > -1.25: return 1
            ...
            return 0

    It runs 5x faster than a loop over the rules' conditions (0.35 against 1.85 us a sample for
    the default model's lists on a pushed walk) and compares exactly as :meth:`DecisionList.predict`
    does (NaN fails both operators). The source holds only numbers the rules validated (feature
    indices, ``repr`` of finite floats, which reads back bit for bit, and the class labels).
    """
    tests = []
    for rule in rules:
        test = ' and '.join(f'x{c.feature} {c.op} {float(c.threshold)!r}' for c in rule.conditions)
        tests.append(f'    if {test or "True"}: return {int(rule.label)}')
    # Only the features the rules read, by index: faster than unpacking all 15, and a longer
    # input vector (a model's inputs begin with the 15 features) reads the same.
    used = sorted({c.feature for rule in rules for c in rule.conditions})
    source = '\n'.join(['def predict_one(x):',
                        *(f'    x{i} = x[{i}]' for i in used),
                        *tests, f'    return {int(default)}'])
    namespace: dict = {}
    exec(compile(source, '<decision list>', 'exec'), namespace)     # numbers only: see above
    return namespace['predict_one']


#: Why a model of decision lists takes no decision threshold (the CLI and the nodes say it).
NO_DECISION_THRESHOLD = ('the model holds decision lists, which have no decision threshold (their '
                         'operating point is the history window tau_his)')


@dataclass(frozen=True)
class PerModeDecisionLists:
    """One classifier per foot contact mode, indexed like :data:`CONTACT_MODE_NAMES`: a
    decision list, or boosted trees (:class:`~fall_predictor.monitor.boosted_trees.BoostedTrees`,
    which answer the same calls: ``predict_one``, ``predict``, ``rule_size``, ``depth``, ``format``).

    A mode without training data (or without falling training samples) holds an empty list,
    which says balanced everywhere.
    """

    lists: tuple[DecisionList | BoostedTrees, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, 'lists', tuple(self.lists))
        if len(self.lists) != N_CONTACT_MODES:
            raise ValueError(f'need {N_CONTACT_MODES} decision lists (one per contact mode), got {len(self.lists)}')
        for decision_list in self.lists:
            if not isinstance(decision_list, (DecisionList, BoostedTrees)):
                raise TypeError(f'expected DecisionList or BoostedTrees, got {decision_list!r}')

    @property
    def n_inputs(self) -> int:
        """Length of the input vector the classifiers read: 15 (the features), or 19 when boosted
        trees also read the base's attitude (method §8c)."""
        return max((c.n_inputs for c in self.lists if isinstance(c, BoostedTrees)), default=N_FEATURES)

    @property
    def reads_attitude(self) -> bool:
        """Whether the classifiers read the base's attitude after the features (method §8c)."""
        return self.n_inputs > N_FEATURES

    @property
    def boosted(self) -> bool:
        """Whether any mode's classifier is boosted trees."""
        return any(isinstance(c, BoostedTrees) for c in self.lists)

    @property
    def decision_threshold(self) -> float | None:
        """The boosted modes' decision threshold [log-odds] when they share one, else None (a model
        of decision lists, or boosted modes with thresholds of their own)."""
        found = {c.decision_threshold for c in self.lists if isinstance(c, BoostedTrees)}
        return found.pop() if len(found) == 1 else None

    def with_decision_threshold(self, threshold: float) -> PerModeDecisionLists:
        """The same classifiers, every boosted mode saying falling when its score exceeds
        ``threshold`` [log-odds] (the operating point of boosted trees beside ``tau_his``, method
        §8a). ValueError for a model without boosted trees: a decision list has no threshold."""
        if not self.boosted:
            raise ValueError(NO_DECISION_THRESHOLD)
        return PerModeDecisionLists(tuple(
            replace(c, decision_threshold=threshold) if isinstance(c, BoostedTrees) else c
            for c in self.lists))

    @classmethod
    def empty(cls) -> PerModeDecisionLists:
        """Lists that say balanced in every mode."""
        return cls(tuple(DecisionList() for _ in range(N_CONTACT_MODES)))

    @property
    def rule_sizes(self) -> tuple[int, ...]:
        """Rule size (number of comparisons) of each mode's list."""
        return tuple(decision_list.rule_size for decision_list in self.lists)

    @property
    def mean_rule_size(self) -> float:
        """Mean rule size over all 16 modes (method §8, the paper's "mean rule size").

        Every mode counts, including modes that had no (falling) training data: their empty
        list says balanced and counts with size 0. The paper averages over its 16 lists.
        """
        return sum(self.rule_sizes) / N_CONTACT_MODES

    @property
    def depths(self) -> tuple[int, ...]:
        """Number of rules of each mode's list."""
        return tuple(decision_list.depth for decision_list in self.lists)

    def predict_one(self, x: Sequence[float], mode: int) -> int:
        """Class of one feature vector ``x`` in contact mode index ``mode``."""
        if not 0 <= mode < N_CONTACT_MODES:
            raise ValueError(f'contact mode index {mode} outside [0, {N_CONTACT_MODES})')
        return self.lists[mode].predict_one(x)

    def predict(self, X: np.ndarray, modes: np.ndarray) -> np.ndarray:
        """Classes (int8, (N,)) of the rows of ``X`` (N, 15) with contact modes ``modes`` (N,)."""
        X = np.asarray(X, dtype=float)
        modes = np.asarray(modes)
        if modes.shape != (X.shape[0],):
            raise ValueError(f'modes must have shape ({X.shape[0]},), got {modes.shape}')
        if modes.size and (modes.min() < 0 or modes.max() >= N_CONTACT_MODES):
            raise ValueError(f'contact mode indices must lie in [0, {N_CONTACT_MODES})')
        out = np.full(X.shape[0], BALANCED, dtype=np.int8)
        for mode in np.unique(modes):
            rows = modes == mode
            out[rows] = self.lists[mode].predict(X[rows])
        return out

    def score(self, X: np.ndarray, modes: np.ndarray) -> np.ndarray:
        """Per row of ``X`` the score its mode's classifier thresholds (floats, (N,)): boosted
        trees' log-odds, a decision list's +inf (falling) or -inf (balanced); ``predict`` at any
        decision threshold ``d`` is ``score > d``, so a model's operating points come from one
        pass over the data."""
        X = np.asarray(X, dtype=float)
        modes = np.asarray(modes)
        out = np.empty(X.shape[0])
        for mode in np.unique(modes):
            rows = modes == mode
            classifier = self.lists[mode]
            if isinstance(classifier, BoostedTrees):
                out[rows] = classifier.score(X[rows])
            else:
                out[rows] = np.where(classifier.predict(X[rows]) == FALLING, np.inf, -np.inf)
        return out

    def format(self, feature_names: Sequence[str] = FEATURE_NAMES,
               mode_names: Sequence[str] = CONTACT_MODE_NAMES) -> str:
        """All 16 lists in Fig. 8 form, one block per mode."""
        return '\n'.join(decision_list.format(feature_names, mode_name)
                         for decision_list, mode_name in zip(self.lists, mode_names))
