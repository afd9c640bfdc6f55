"""Learning decision lists (method §8): two rule learners and the per-mode training entry point.

Both learners are scikit-learn style estimators: ``__init__`` stores the hyper-parameters
verbatim, :meth:`fit` validates them and learns, the fitted state lives in attributes ending
with ``_`` (``decision_list_``, ``n_features_in_``, ``classes_``), so ``sklearn.base.clone``,
``get_params`` and ``set_params`` work. Each learns one :class:`DecisionList` for the falling
class (default balanced) from weighted samples:

* :class:`TreeListLearner` grows a weighted CART tree (scikit-learn) and rewrites it as a
  decision list, one rule per falling region, predicting exactly what the tree predicts;
* :class:`CoveringListLearner` is a RIPPER-like sequential-covering learner: grow a conjunctive
  rule by FOIL gain over quantile-binned thresholds, prune it on held-out trajectories, remove
  the samples it covers, repeat.

:func:`fit_predictor` builds the weighted training set of method §8 from trajectories and trains
one list per foot contact mode.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin, clone
from sklearn.tree import DecisionTreeClassifier

from fall_predictor.learning.labels import training_mask_and_weights
from fall_predictor.monitor.decision_list import (Condition, DecisionList, PerModeDecisionLists,
                                                  Rule, simplify_conditions)
from fall_predictor.monitor.records import (BALANCED, FALLING, N_CONTACT_MODES, N_FEATURES,
                                            TrajectoryFeatures)


def _check_int(name: str, value: object, minimum: int, allow_none: bool = False) -> None:
    if value is None and allow_none:
        return
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f'{name} must be an int >= {minimum}{" or None" if allow_none else ""}, got {value!r}')


def _check_float(name: str, value: object, low: float, high: float = math.inf,
                 low_inclusive: bool = True, high_inclusive: bool = True) -> None:
    is_number = (isinstance(value, (int, float, np.integer, np.floating))
                 and not isinstance(value, bool))
    v = float(value) if is_number else math.nan
    in_range = ((v >= low if low_inclusive else v > low)
                and (v <= high if high_inclusive else v < high))
    if not (is_number and math.isfinite(v) and in_range):
        interval = f'{"[" if low_inclusive else "("}{low}, {high}{"]" if high_inclusive else ")"}'
        raise ValueError(f'{name} must be a finite number in {interval}, got {value!r}')


class RuleListLearner(ClassifierMixin, BaseEstimator):
    """Base of the decision-list learners: input validation, prediction, fitted attributes.

    Subclasses implement :meth:`check_params` and :meth:`_learn_rules`.
    """

    #: Widths of ``X`` a learner takes: the 15 features (decision lists read only those).
    input_sizes: tuple[int, ...] = (N_FEATURES,)

    def fit(self, X: np.ndarray, y: np.ndarray, sample_weight: Optional[np.ndarray] = None,
            groups: Optional[np.ndarray] = None) -> RuleListLearner:
        """Learn a decision list for FALLING (default BALANCED).

        ``X`` (N, 15) finite features, ``y`` (N,) labels BALANCED/FALLING, ``sample_weight``
        (N,) non-negative weights (default 1), ``groups`` (N,) trajectory identifiers of the
        samples (used by learners that hold out data, so that a held-out set never shares a
        trajectory with the data it checks; ignored by the others).
        """
        self.check_params()
        X = np.asarray(X, dtype=float)
        y = np.asarray(y)
        if X.ndim != 2 or X.shape[1] not in self.input_sizes:
            raise ValueError(f'X must have shape (N, {" or ".join(map(str, self.input_sizes))}), '
                             f'got {X.shape}')
        if y.shape != (X.shape[0],):
            raise ValueError(f'y must have shape ({X.shape[0]},), got {y.shape}')
        if X.shape[0] == 0:
            raise ValueError('cannot fit on zero samples')
        if not np.isfinite(X).all():
            raise ValueError('X contains NaN or infinite values')
        if not np.isin(y, (BALANCED, FALLING)).all():
            raise ValueError('y must contain only BALANCED and FALLING labels')
        w = np.ones(X.shape[0]) if sample_weight is None else np.asarray(sample_weight, dtype=float)
        if w.shape != y.shape or not np.isfinite(w).all() or (w < 0).any():
            raise ValueError('sample_weight must be finite, non-negative and of shape (N,)')
        if groups is not None and np.shape(groups) != y.shape:
            raise ValueError(f'groups must have shape ({X.shape[0]},)')
        keep = w > 0                  # zero-weight samples carry no information
        if not keep.any():
            raise ValueError('every sample has zero weight')
        self.n_features_in_ = X.shape[1]
        self.classes_ = np.array([BALANCED, FALLING])
        self._fit_model(X[keep], y[keep].astype(np.int8), w[keep],
                        None if groups is None else np.asarray(groups)[keep])
        return self

    @property
    def classifier_(self) -> DecisionList:
        """The fitted mode classifier :func:`fit_predictor` collects (here: the list)."""
        if not hasattr(self, 'decision_list_'):
            raise RuntimeError(f'{type(self).__name__} is not fitted')
        return self.decision_list_

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Classes (int8, (N,)) of the rows of ``X`` (N, 15) by the learned list."""
        if not hasattr(self, 'decision_list_'):
            raise RuntimeError(f'{type(self).__name__} is not fitted')
        return self.decision_list_.predict(X)

    def check_params(self) -> None:
        raise NotImplementedError

    def _fit_model(self, X: np.ndarray, y: np.ndarray, w: np.ndarray,
                   groups: Optional[np.ndarray]) -> None:
        raise NotImplementedError


class TreeListLearner(RuleListLearner):
    """Weighted CART tree (``sklearn.tree.DecisionTreeClassifier``) rewritten as a decision list.

    Every leaf that predicts FALLING becomes one rule: the comparisons on its root-to-leaf path,
    with repeated comparisons on one feature and direction merged (:func:`simplify_conditions`).
    A subtree whose leaves all predict FALLING becomes a single rule at its root. Leaves are
    disjoint, so the rule order cannot change predictions; rules are ordered by weighted
    precision (falling weight / total weight in the region), then by falling weight covered,
    both descending. The default is BALANCED.

    Exactness: scikit-learn compares ``float32(x) <= t``; each threshold ``t`` is converted to
    the float64 threshold ``t'`` with ``x <= t'  <=>  float32(x) <= t`` for every float64 ``x``,
    so the list predicts what the tree predicts on every finite input (the fitted tree is kept
    as ``estimator_`` for checking).

    Hyper-parameters are those of ``DecisionTreeClassifier`` (see its documentation):
    ``criterion`` ('entropy' = information gain, as the paper's learners, or 'gini'),
    ``max_depth``, ``min_samples_leaf``, ``min_weight_fraction_leaf`` (a fraction of the total
    sample weight), ``max_leaf_nodes``, ``ccp_alpha`` (cost-complexity pruning), and
    ``random_state`` (tie breaking between equally good splits).
    """

    def __init__(self, criterion: str = 'entropy', max_depth: Optional[int] = 8,
                 min_samples_leaf: int = 20, min_weight_fraction_leaf: float = 0.0,
                 max_leaf_nodes: Optional[int] = None, ccp_alpha: float = 0.0,
                 random_state: int = 0) -> None:
        self.criterion = criterion
        self.max_depth = max_depth
        self.min_samples_leaf = min_samples_leaf
        self.min_weight_fraction_leaf = min_weight_fraction_leaf
        self.max_leaf_nodes = max_leaf_nodes
        self.ccp_alpha = ccp_alpha
        self.random_state = random_state

    def check_params(self) -> None:
        if self.criterion not in ('entropy', 'gini', 'log_loss'):
            raise ValueError(f"criterion must be 'entropy', 'gini' or 'log_loss', got {self.criterion!r}")
        _check_int('max_depth', self.max_depth, 1, allow_none=True)
        _check_int('min_samples_leaf', self.min_samples_leaf, 1)
        _check_float('min_weight_fraction_leaf', self.min_weight_fraction_leaf, 0.0, 0.5)
        _check_int('max_leaf_nodes', self.max_leaf_nodes, 2, allow_none=True)
        _check_float('ccp_alpha', self.ccp_alpha, 0.0)
        _check_int('random_state', self.random_state, 0)

    def _fit_model(self, X: np.ndarray, y: np.ndarray, w: np.ndarray,
                   groups: Optional[np.ndarray]) -> None:
        tree = DecisionTreeClassifier(
            criterion=self.criterion, max_depth=self.max_depth,
            min_samples_leaf=self.min_samples_leaf,
            min_weight_fraction_leaf=self.min_weight_fraction_leaf,
            max_leaf_nodes=self.max_leaf_nodes, ccp_alpha=self.ccp_alpha,
            random_state=self.random_state)
        tree.fit(X, y, sample_weight=w)
        self.estimator_ = tree
        self.decision_list_ = tree_to_decision_list(tree)


def float32_threshold_as_float64(threshold: float) -> float:
    """The float64 ``t'`` with ``x <= t'  <=>  float32(x) <= threshold`` for all float64 ``x``.

    scikit-learn trees cast inputs to float32 before comparing them with float64 thresholds.
    Rounding to float32 is monotone, so ``float32(x) <= threshold`` holds exactly for ``x`` up
    to the rounding boundary between the largest float32 ``f <= threshold`` and the next
    float32 above it.
    """
    f = np.float32(threshold)
    if float(f) > threshold:
        f = np.nextafter(f, np.float32(-np.inf))
    above = np.nextafter(f, np.float32(np.inf))
    if not np.isfinite(above):       # f is the largest float32: everything finite rounds <= f
        return float(np.finfo(np.float64).max)
    boundary = (float(f) + float(above)) / 2.0   # exact in float64
    # The boundary itself rounds to even: to f, or to ``above``.
    return boundary if np.float32(boundary) == f else float(np.nextafter(boundary, -np.inf))


def tree_to_decision_list(tree: DecisionTreeClassifier) -> DecisionList:
    """Rewrite a fitted binary classification tree (classes within BALANCED/FALLING) as a list.

    See :class:`TreeListLearner` for the construction and the ordering of the rules.
    """
    structure = tree.tree_
    classes = tree.classes_
    left, right = structure.children_left, structure.children_right
    n_nodes = structure.node_count
    weight_fractions = structure.value[:, 0, :] / structure.value[:, 0, :].sum(axis=1, keepdims=True)
    node_label = classes[np.argmax(structure.value[:, 0, :], axis=1)]   # as tree.predict
    falling_column = int(np.flatnonzero(classes == FALLING)[0]) if FALLING in classes else None

    # Whether every leaf below each node predicts FALLING (children have larger indices).
    all_falling = np.zeros(n_nodes, dtype=bool)
    for node in range(n_nodes - 1, -1, -1):
        if left[node] == -1:
            all_falling[node] = node_label[node] == FALLING
        else:
            all_falling[node] = all_falling[left[node]] and all_falling[right[node]]

    scored_rules: list[tuple[float, float, Rule]] = []
    stack: list[tuple[int, tuple[Condition, ...]]] = [(0, ())]
    while stack:
        node, path = stack.pop()
        if all_falling[node]:
            precision = weight_fractions[node, falling_column]
            support = precision * structure.weighted_n_node_samples[node]
            scored_rules.append((precision, support, Rule(simplify_conditions(path), FALLING)))
            continue
        if left[node] == -1:
            continue                                       # a balanced leaf: the default
        feature = int(structure.feature[node])
        threshold = float32_threshold_as_float64(float(structure.threshold[node]))
        stack.append((int(right[node]), path + (Condition(feature, '>', threshold),)))
        stack.append((int(left[node]), path + (Condition(feature, '<=', threshold),)))
    scored_rules.sort(key=lambda item: (-item[0], -item[1]))
    return DecisionList(tuple(rule for _, _, rule in scored_rules), default=BALANCED)


class CoveringListLearner(RuleListLearner):
    """RIPPER-like sequential covering for the FALLING class, with sample weights.

    Candidate thresholds per feature are quantiles of the feature, taken separately over the
    falling and over the balanced samples (``n_bins // 2`` levels each, including both classes'
    minimum and maximum), so class boundaries in the tails get thresholds too. Then, until the
    falling weight left in the grow set is zero or below ``min_coverage``, ``max_rules`` is
    reached, or a rule fails its check:

    1. *grow* a conjunctive rule on the grow set, adding each time the comparison
       (``<= q`` or ``> q``) with the largest weighted FOIL gain
       ``p1 * (log2(p1 / (p1 + n1)) - log2(p0 / (p0 + n0)))`` (p, n: falling and balanced weight
       covered before (0) and after (1) the comparison), among comparisons that keep at least
       ``min_coverage`` falling weight; stop when the rule covers no balanced weight, no
       comparison gains, or it has ``max_conditions`` comparisons (if the grow set has no
       balanced weight left the rule has no comparison: it says falling everywhere);
    2. *prune* it on the prune set: keep the prefix of its comparisons that maximises
       ``(p - n) / (p + n)`` (weighted; ties go to the shorter prefix);
    3. *check* it on the prune set: accept it only if its Laplace-corrected weighted precision
       ``(p + 1) / (p + n + 2)`` exceeds ``min_precision``; otherwise stop;
    4. remove every sample the rule covers (both classes) from the grow and prune sets.

    The prune set is a random ``prune_fraction`` of the trajectories given by ``groups`` in
    :meth:`fit` (of the samples if ``groups`` is None), drawn with ``random_state``. If either
    part would hold no falling sample, the rules are grown, pruned and checked on all data.
    Repeated comparisons on one feature and direction are merged. The default is BALANCED.

    Hyper-parameters: ``n_bins`` candidate thresholds per feature (at most 254);
    ``max_rules``; ``max_conditions`` per rule; ``min_coverage`` falling weight a rule must
    cover on the grow set (with falling weight 1 per sample: samples, i.e. milliseconds of
    falling states at 1 kHz); ``min_precision`` in [0, 1); ``prune_fraction`` in (0, 1);
    ``random_state`` seeds the grow/prune split.
    """

    def __init__(self, n_bins: int = 64, max_rules: int = 20, max_conditions: int = 8,
                 min_coverage: float = 20.0, min_precision: float = 0.5,
                 prune_fraction: float = 1 / 3, random_state: int = 0) -> None:
        self.n_bins = n_bins
        self.max_rules = max_rules
        self.max_conditions = max_conditions
        self.min_coverage = min_coverage
        self.min_precision = min_precision
        self.prune_fraction = prune_fraction
        self.random_state = random_state

    def check_params(self) -> None:
        _check_int('n_bins', self.n_bins, 4)
        if self.n_bins > 254:
            raise ValueError(f'n_bins must be at most 254 (codes are uint8), got {self.n_bins}')
        _check_int('max_rules', self.max_rules, 1)
        _check_int('max_conditions', self.max_conditions, 1)
        _check_float('min_coverage', self.min_coverage, 0.0)
        _check_float('min_precision', self.min_precision, 0.0, 1.0, high_inclusive=False)
        _check_float('prune_fraction', self.prune_fraction, 0.0, 1.0, low_inclusive=False,
                     high_inclusive=False)
        _check_int('random_state', self.random_state, 0)

    def _fit_model(self, X: np.ndarray, y: np.ndarray, w: np.ndarray,
                   groups: Optional[np.ndarray]) -> None:
        falling = y == FALLING
        edges = self._candidate_thresholds(X, falling)
        # codes[f, i] = number of thresholds of feature f below X[i, f]; so
        # X[i, f] <= edges[f][k]  <=>  codes[f, i] <= k.
        codes = np.empty((N_FEATURES, X.shape[0]), dtype=np.uint8)
        for f in range(N_FEATURES):
            codes[f] = np.searchsorted(edges[f], X[:, f], side='left')
        w_falling = np.where(falling, w, 0.0)
        w_balanced = np.where(falling, 0.0, w)
        in_prune = self._prune_split(falling, w, groups)
        grow_set = ~in_prune if in_prune.any() else np.ones_like(in_prune)
        prune_set = in_prune if in_prune.any() else np.ones_like(in_prune)

        rules: list[Rule] = []
        while len(rules) < self.max_rules:
            grow_rows = np.flatnonzero(grow_set)
            falling_left = w_falling[grow_rows].sum()
            if falling_left <= 0.0 or falling_left < self.min_coverage:
                break
            coded = self._grow_rule(codes, w_falling, w_balanced, grow_rows, edges)
            if not coded and w_balanced[grow_rows].sum() > 0.0:
                break                     # nothing separates the falling samples left
            prune_rows = np.flatnonzero(prune_set)
            coded = self._prune_rule(coded, codes, w_falling, w_balanced, prune_rows)
            covered = self._covers(coded, codes, prune_rows)
            p, n = w_falling[prune_rows[covered]].sum(), w_balanced[prune_rows[covered]].sum()
            if (p + 1.0) / (p + n + 2.0) <= self.min_precision:
                break
            conditions = simplify_conditions(
                [Condition(f, op, float(edges[f][k])) for f, op, k in coded])
            rules.append(Rule(conditions, FALLING))
            prune_set[prune_rows[covered]] = False
            grow_set[grow_rows[self._covers(coded, codes, grow_rows)]] = False
        self.decision_list_ = DecisionList(tuple(rules), default=BALANCED)

    def _candidate_thresholds(self, X: np.ndarray, falling: np.ndarray) -> list[np.ndarray]:
        """Per feature: sorted unique quantiles of the falling and of the balanced samples."""
        levels = np.linspace(0.0, 1.0, self.n_bins // 2)
        edges = []
        for f in range(N_FEATURES):
            parts = [np.quantile(X[rows, f], levels, method='lower')
                     for rows in (falling, ~falling) if rows.any()]
            edges.append(np.unique(np.concatenate(parts)))
        return edges

    def _prune_split(self, falling: np.ndarray, w: np.ndarray,
                     groups: Optional[np.ndarray]) -> np.ndarray:
        """Mask of the prune set; all False when a part would hold no falling weight."""
        rng = np.random.default_rng(self.random_state)
        if groups is None:
            in_prune = rng.random(falling.size) < self.prune_fraction
        else:
            unique_groups, group_index = np.unique(groups, return_inverse=True)
            n_prune = int(round(self.prune_fraction * unique_groups.size))
            prune_groups = np.zeros(unique_groups.size, dtype=bool)
            prune_groups[rng.permutation(unique_groups.size)[:n_prune]] = True
            in_prune = prune_groups[group_index]
        positive = falling & (w > 0)
        if not (positive & in_prune).any() or not (positive & ~in_prune).any():
            return np.zeros_like(in_prune)
        return in_prune

    def _grow_rule(self, codes: np.ndarray, w_falling: np.ndarray, w_balanced: np.ndarray,
                   rows: np.ndarray, edges: list[np.ndarray]) -> list[tuple[int, str, int]]:
        """Greedy FOIL-gain growth; returns comparisons as (feature, op, threshold index)."""
        coded: list[tuple[int, str, int]] = []
        for _ in range(self.max_conditions):
            p0, n0 = w_falling[rows].sum(), w_balanced[rows].sum()
            if n0 <= 0.0 or p0 <= 0.0:
                break
            log_precision0 = math.log2(p0 / (p0 + n0))
            rows_falling, rows_balanced = w_falling[rows], w_balanced[rows]
            best_gain, best = 0.0, None
            for f in range(N_FEATURES):
                n_edges = edges[f].size
                column = codes[f, rows]
                # Weight at or below threshold k: cumulative sums over codes 0..k.
                p_le = np.cumsum(np.bincount(column, rows_falling, n_edges + 1))[:n_edges]
                n_le = np.cumsum(np.bincount(column, rows_balanced, n_edges + 1))[:n_edges]
                for op, p1, n1 in (('<=', p_le, n_le), ('>', p0 - p_le, n0 - n_le)):
                    p1 = np.maximum(p1, 0.0)          # cumulative round-off
                    n1 = np.maximum(n1, 0.0)
                    valid = (p1 > 0.0) & (p1 >= self.min_coverage) & ((p1 < p0) | (n1 < n0))
                    with np.errstate(divide='ignore', invalid='ignore'):
                        gain = np.where(valid, p1 * (np.log2(p1 / (p1 + n1)) - log_precision0), -np.inf)
                    k = int(np.argmax(gain))
                    if gain[k] > best_gain + 1e-12 * p0:
                        best_gain, best = float(gain[k]), (f, op, k)
            if best is None:
                break
            coded.append(best)
            rows = rows[self._covers([best], codes, rows)]
        return coded

    def _prune_rule(self, coded: list[tuple[int, str, int]], codes: np.ndarray,
                    w_falling: np.ndarray, w_balanced: np.ndarray,
                    rows: np.ndarray) -> list[tuple[int, str, int]]:
        """Keep the prefix of ``coded`` with the best weighted ``(p - n) / (p + n)`` on ``rows``."""
        best_length, best_value = len(coded), -math.inf
        covered = np.ones(rows.size, dtype=bool)
        values = []
        for condition in coded:
            covered &= self._covers([condition], codes, rows)
            p, n = w_falling[rows[covered]].sum(), w_balanced[rows[covered]].sum()
            values.append((p - n) / (p + n) if p + n > 0 else -1.0)
        for length, value in enumerate(values, start=1):
            if value > best_value:
                best_length, best_value = length, value
        return coded[:best_length]

    @staticmethod
    def _covers(coded: Sequence[tuple[int, str, int]], codes: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Mask over ``rows`` of the samples satisfying every coded comparison."""
        mask = np.ones(rows.size, dtype=bool)
        for f, op, k in coded:
            column = codes[f, rows]
            mask &= column <= k if op == '<=' else column > k
        return mask


def learner_description(learner: RuleListLearner) -> dict:
    """``{'name': class name, 'params': hyper-parameters}`` for model files and reports."""
    return {'name': type(learner).__name__, 'params': learner.get_params()}


def training_set(trajectories: Sequence[TrajectoryFeatures], tau_plus_s: float,
                 balanced_weight: float = 4.0, falling_weight: float = 1.0
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The weighted training samples of method §8 from all ``trajectories``.

    Returns ``X`` (M, 15), ``y`` (M,) BALANCED/FALLING, ``w`` (M,) weights, ``modes`` (M,)
    contact mode indices and ``groups`` (M,) the index of each sample's trajectory, over the
    samples selected by :func:`fall_predictor.learning.labels.training_mask_and_weights`.
    """
    parts = []
    for index, traj in enumerate(trajectories):
        mask, y, w = training_mask_and_weights(traj, tau_plus_s, balanced_weight, falling_weight)
        parts.append((traj.X[mask], y[mask], w[mask], traj.mode[mask],
                      np.full(int(mask.sum()), index, dtype=np.int64)))
    if not parts:
        raise ValueError('no trajectories to train on')
    X, y, w, modes, groups = (np.concatenate(columns) for columns in zip(*parts))
    return X, y.astype(np.int8), w, modes.astype(np.int64), groups


def fit_predictor(trajectories: Sequence[TrajectoryFeatures], tau_plus_s: float,
                  learner: RuleListLearner, balanced_weight: float = 4.0,
                  falling_weight: float = 1.0) -> PerModeDecisionLists:
    """Train one decision list per contact mode on the method §8 training set.

    ``tau_plus_s`` [s] withholds falling states before ``t_height_drop + tau_plus_s``;
    ``balanced_weight``/``falling_weight`` weigh the classes (the paper: 4 to 1). Each mode gets
    a fresh clone of ``learner`` fitted on its samples (``groups`` = trajectory index); a mode
    without falling training samples gets the empty list (always balanced).
    """
    _check_float('balanced_weight', balanced_weight, 0.0, low_inclusive=False)
    _check_float('falling_weight', falling_weight, 0.0, low_inclusive=False)
    _check_float('tau_plus_s', tau_plus_s, -math.inf)
    X, y, w, modes, groups = training_set(trajectories, tau_plus_s, balanced_weight, falling_weight)
    lists = []
    for mode in range(N_CONTACT_MODES):
        rows = modes == mode
        if not (y[rows] == FALLING).any():
            lists.append(DecisionList())
            continue
        mode_learner = clone(learner).fit(X[rows], y[rows], w[rows], groups=groups[rows])
        lists.append(mode_learner.classifier_)
    return PerModeDecisionLists(tuple(lists))
