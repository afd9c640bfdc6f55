"""Learning boosted trees: the exported trees score as scikit-learn's classifier does."""
import numpy as np
import pytest
from sklearn.base import clone

from fall_predictor.learning.boosting import BoostedTreesLearner
from fall_predictor.learning.training import make_learner
from fall_predictor.monitor.boosted_trees import BoostedTrees
from fall_predictor.monitor.decision_list import DecisionList
from fall_predictor.monitor.records import BALANCED, FALLING, N_FEATURES


def samples(n: int, seed: int):
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, N_FEATURES))
    y = np.where(X[:, 2] + 0.5 * X[:, 5] ** 2 + 0.3 * rng.normal(size=n) > 1.0, FALLING, BALANCED)
    return X, y.astype(np.int8), rng.uniform(0.5, 2.0, n)


def test_exported_trees_score_exactly_as_the_fitted_classifier():
    X, y, w = samples(4000, 0)
    learner = BoostedTreesLearner(max_iter=30, max_depth=3).fit(X, y, w)
    trees = learner.classifier_
    assert isinstance(trees, BoostedTrees) and trees.depth == 30
    X_test = samples(1000, 1)[0]
    reference = learner.estimator_.decision_function(X_test)
    assert np.array_equal(trees.score(X_test), reference)
    assert np.array_equal([trees.score_one(list(x)) for x in X_test], reference)
    # Depth 3: at most 7 comparisons a tree.
    assert trees.rule_size <= 30 * 7


def test_it_learns_a_known_boundary_and_the_threshold_trades_alarms():
    X, y, w = samples(6000, 2)
    X_test, y_test, _ = samples(3000, 3)
    even = BoostedTreesLearner().fit(X, y, w).predict(X_test)
    assert (even == y_test).mean() > 0.9
    strict = BoostedTreesLearner(decision_threshold=2.0).fit(X, y, w).predict(X_test)
    # A higher threshold: fewer falling calls, each of them one the even odds also made.
    assert (strict == FALLING).sum() < (even == FALLING).sum()
    assert not ((strict == FALLING) & (even == BALANCED)).any()


def test_one_class_gives_a_constant_classifier():
    X, _, w = samples(100, 4)
    learner = BoostedTreesLearner().fit(X, np.full(100, BALANCED, dtype=np.int8), w)
    assert learner.classifier_ == DecisionList((), BALANCED)


@pytest.mark.parametrize('params', [{'max_iter': 0}, {'max_depth': 0}, {'learning_rate': 0.0},
                                    {'max_bins': 256}, {'decision_threshold': float('nan')}])
def test_invalid_hyper_parameters_are_rejected(params):
    with pytest.raises(ValueError):
        make_learner('boosting', params)


def test_it_is_a_scikit_learn_estimator():
    learner = make_learner('boosting', {'decision_threshold': 1.5})
    assert clone(learner).get_params() == learner.get_params()
    assert learner.get_params()['decision_threshold'] == 1.5
    with pytest.raises(RuntimeError, match='not fitted'):
        learner.classifier_


def test_trees_over_the_features_and_the_attitude_read_input_17_and_export_19_inputs():
    """Falling decided by the base's roll rate (input 17 of the 19): the trees learn it, read
    19 inputs, and score as scikit-learn does; the decision-list learners take 15 only."""
    from fall_predictor.learning.learners import TreeListLearner
    rng = np.random.default_rng(7)
    X = rng.normal(size=(4000, 19))
    y = np.where(X[:, 17] > 0.8, FALLING, BALANCED).astype(np.int8)
    learner = BoostedTreesLearner(max_iter=20, max_depth=2).fit(X, y)
    trees = learner.classifier_
    assert trees.n_inputs == 19 and all(t.n_inputs == 19 for t in trees.trees)
    assert {f for t in trees.trees for f in t.feature if f != -1} >= {17}
    X_test = rng.normal(size=(500, 19))
    assert np.array_equal(trees.score(X_test), learner.estimator_.decision_function(X_test))
    assert np.array_equal([trees.score_one(list(x)) for x in X_test], trees.score(X_test))
    assert (trees.predict(X_test) == np.where(X_test[:, 17] > 0.8, FALLING, BALANCED)).mean() > 0.97
    with pytest.raises(ValueError, match=r'shape \(N, 19\)'):
        trees.score(X_test[:, :15])
    assert 'base_angular_velocity_x' in trees.format(mode_name='L-INSIDE')
    with pytest.raises(ValueError, match=r'shape \(N, 15\)'):
        TreeListLearner().fit(X, y)
