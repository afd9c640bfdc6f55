"""Learning boosted trees per contact mode (method §8a): scikit-learn's histogram gradient
boosting, exported to the plain-data :class:`~fall_predictor.monitor.boosted_trees.BoostedTrees`.

:class:`BoostedTreesLearner` is a learner like the decision-list learners (same ``fit``, same
weighted samples of method §8, ``clone``-able hyper-parameters): ``fit`` trains a
``HistGradientBoostingClassifier`` on the mode's samples and rewrites its trees as
:class:`~fall_predictor.monitor.time_to_fall.RegressionTree` arrays; the fitted
``classifier_`` scores exactly as the classifier's ``decision_function`` (kept as
``estimator_`` for checking). Early stopping is off: it would hold out samples at random,
splitting trajectories, and make the number of trees depend on the draw.

Small trees keep the monitor within its budget: 50 trees of depth 3 are at most 350
comparisons, of which one sample walks 150 (a few microseconds as generated code).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from fall_predictor.learning.learners import RuleListLearner, _check_float, _check_int
from fall_predictor.monitor.boosted_trees import BoostedTrees
from fall_predictor.monitor.decision_list import DecisionList
from fall_predictor.monitor.records import BALANCED, FALLING, N_FEATURES, N_INPUTS_WITH_ATTITUDE
from fall_predictor.monitor.time_to_fall import RegressionTree


def exported_tree(nodes: np.ndarray, n_inputs: int = N_FEATURES) -> RegressionTree:
    """One fitted HGB predictor's node array as a RegressionTree (leaf: feature -1) over
    ``n_inputs`` inputs."""
    leaf = nodes['is_leaf'].astype(bool)
    return RegressionTree(
        feature=tuple(-1 if leaf[i] else int(nodes['feature_idx'][i]) for i in range(len(nodes))),
        threshold=tuple(0.0 if leaf[i] else float(nodes['num_threshold'][i]) for i in range(len(nodes))),
        left=tuple(-1 if leaf[i] else int(nodes['left'][i]) for i in range(len(nodes))),
        right=tuple(-1 if leaf[i] else int(nodes['right'][i]) for i in range(len(nodes))),
        value=tuple(float(nodes['value'][i]) if leaf[i] else 0.0 for i in range(len(nodes))),
        n_inputs=n_inputs)


def exported_trees(model, n_inputs: int = N_FEATURES) -> tuple[float, tuple[RegressionTree, ...]]:
    """A fitted single-output HGB model (classifier or regressor) as its bias (the baseline
    prediction) and its trees over ``n_inputs`` inputs."""
    return (float(np.ravel(model._baseline_prediction)[0]),
            tuple(exported_tree(iteration[0].nodes, n_inputs) for iteration in model._predictors))


class BoostedTreesLearner(RuleListLearner):
    """Gradient-boosted trees (``sklearn.ensemble.HistGradientBoostingClassifier``) for falling.

    Hyper-parameters: ``max_iter`` (trees), ``max_depth`` (edges from root to leaf),
    ``learning_rate``, ``min_samples_leaf``, ``l2_regularization``, ``max_bins`` and
    ``random_state`` as in scikit-learn; ``decision_threshold`` [log-odds]: falling when the
    score exceeds it (0: the weighted classes' even odds; higher: fewer false alarms, less lead).
    Samples of one class only give a constant classifier: an empty list with that class.
    ``X`` holds the 15 features, or the 19 inputs with the base's attitude (method §8c).
    """

    input_sizes = (N_FEATURES, N_INPUTS_WITH_ATTITUDE)

    def __init__(self, max_iter: int = 50, max_depth: Optional[int] = 3, learning_rate: float = 0.1,
                 min_samples_leaf: int = 20, l2_regularization: float = 0.0, max_bins: int = 255,
                 decision_threshold: float = 0.0, random_state: int = 0) -> None:
        self.max_iter = max_iter
        self.max_depth = max_depth
        self.learning_rate = learning_rate
        self.min_samples_leaf = min_samples_leaf
        self.l2_regularization = l2_regularization
        self.max_bins = max_bins
        self.decision_threshold = decision_threshold
        self.random_state = random_state

    def check_params(self) -> None:
        _check_int('max_iter', self.max_iter, 1)
        _check_int('max_depth', self.max_depth, 1, allow_none=True)
        _check_float('learning_rate', self.learning_rate, 0.0, low_inclusive=False)
        _check_int('min_samples_leaf', self.min_samples_leaf, 1)
        _check_float('l2_regularization', self.l2_regularization, 0.0)
        _check_int('max_bins', self.max_bins, 2)
        if self.max_bins > 255:
            raise ValueError(f'max_bins must be <= 255, got {self.max_bins!r}')
        _check_float('decision_threshold', self.decision_threshold, -np.inf)
        _check_int('random_state', self.random_state, 0)

    @property
    def classifier_(self) -> BoostedTrees | DecisionList:
        if not hasattr(self, 'trees_'):
            raise RuntimeError(f'{type(self).__name__} is not fitted')
        return self.trees_

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Classes (int8, (N,)) of the rows of ``X`` (N, 15 or 19) by the exported trees."""
        return self.classifier_.predict(X)

    def _fit_model(self, X: np.ndarray, y: np.ndarray, w: np.ndarray,
                   groups: Optional[np.ndarray]) -> None:
        from sklearn.ensemble import HistGradientBoostingClassifier

        falling = y == FALLING
        if falling.all() or not falling.any():
            self.estimator_ = None
            self.trees_ = DecisionList((), FALLING if falling.all() else BALANCED)
            return
        model = HistGradientBoostingClassifier(
            max_iter=self.max_iter, max_depth=self.max_depth, learning_rate=self.learning_rate,
            min_samples_leaf=self.min_samples_leaf, l2_regularization=self.l2_regularization,
            max_bins=self.max_bins, early_stopping=False, random_state=self.random_state)
        model.fit(X, falling, sample_weight=w)
        self.estimator_ = model
        bias, trees = exported_trees(model, X.shape[1])
        self.trees_ = BoostedTrees(trees, bias, float(self.decision_threshold))
