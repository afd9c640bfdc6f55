import numpy as np
import pytest
from sklearn.base import clone

from fall_predictor.monitor.decision_list import Condition
from fall_predictor.learning.learners import (CoveringListLearner, TreeListLearner, fit_predictor,
                                     float32_threshold_as_float64, learner_description,
                                     training_set)
from fall_predictor.learning.metrics import evaluate_lists
from fall_predictor.monitor.records import BALANCED, FALLING, N_CONTACT_MODES, N_FEATURES

from synthetic_trajectories import FALLING_MODE, LIN_MOM_Y, make_dataset

LEARNERS = [TreeListLearner(), CoveringListLearner()]


def conjunction_data(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Uniform features; falling iff x0 > 0.6 and x2 <= 0.3; weights 4:1."""
    rng = np.random.default_rng(seed)
    X = rng.random((n, N_FEATURES))
    y = ((X[:, 0] > 0.6) & (X[:, 2] <= 0.3)).astype(np.int8)
    return X, y, np.where(y == BALANCED, 4.0, 1.0)


@pytest.mark.parametrize('learner', LEARNERS, ids=lambda learner: type(learner).__name__)
def test_learner_recovers_a_conjunction(learner):
    X, y, w = conjunction_data(20000, seed=0)
    fitted = clone(learner).fit(X, y, w)
    rules = fitted.decision_list_.rules
    assert len(rules) == 1 and rules[0].label == FALLING
    by_feature = {(c.feature, c.op): c.threshold for c in rules[0].conditions}
    assert set(by_feature) == {(0, '>'), (2, '<=')}
    assert by_feature[(0, '>')] == pytest.approx(0.6, abs=0.01)
    assert by_feature[(2, '<=')] == pytest.approx(0.3, abs=0.01)
    X_test, y_test, _ = conjunction_data(5000, seed=1)
    assert (fitted.predict(X_test) == y_test).mean() > 0.99


@pytest.mark.parametrize('learner', LEARNERS, ids=lambda learner: type(learner).__name__)
def test_fit_predictor_recovers_the_threshold_rule_of_one_mode(learner):
    trajectories = make_dataset(n_fallen=10, n_balanced=10, seed=3, duration_s=1.6)
    lists = fit_predictor(trajectories, tau_plus_s=0.0, learner=learner)
    for mode in range(N_CONTACT_MODES):
        if mode != FALLING_MODE:
            assert lists.lists[mode].depth == 0, mode       # no falling data: empty list
    rules = lists.lists[FALLING_MODE].rules
    assert len(rules) == 1
    (condition,) = rules[0].conditions
    assert (condition.feature, condition.op) == (LIN_MOM_Y, '>')
    assert 3.5 <= condition.threshold <= 5.0
    assert lists.mean_rule_size == pytest.approx(1 / 16)
    # On fresh trajectories: no false positive, falls predicted at t_height_drop (lead 0.5 s).
    result = evaluate_lists(make_dataset(5, 5, seed=4, duration_s=1.6), lists, (0.0, 0.005))
    assert result[0.0].fpr == 0.0
    assert result[0.005].tau_lead_s == pytest.approx(0.495)


def test_tree_list_predicts_exactly_what_the_tree_predicts():
    rng = np.random.default_rng(5)
    X = rng.normal(size=(6000, N_FEATURES))
    y = ((X[:, 0] + X[:, 1] * X[:, 4] + rng.normal(scale=0.7, size=6000)) > 0.8).astype(np.int8)
    w = np.where(y == BALANCED, 4.0, 1.0)
    learner = TreeListLearner(max_depth=None, min_samples_leaf=1).fit(X, y, w)
    tree = learner.estimator_
    assert learner.decision_list_.depth > 20
    # Paths of a deep tree revisit features; the rules hold one comparison per feature/direction.
    assert all(len({(c.feature, c.op) for c in rule.conditions}) == rule.size
               for rule in learner.decision_list_.rules)
    assert max(rule.size for rule in learner.decision_list_.rules) < tree.get_depth()
    # Unseen data, plus values right at every threshold, where float32 rounding matters.
    thresholds = tree.tree_.threshold[tree.tree_.feature >= 0]
    features = tree.tree_.feature[tree.tree_.feature >= 0]
    probes = np.repeat(rng.normal(size=(1, N_FEATURES)), 3 * thresholds.size, axis=0)
    for i, (f, thr) in enumerate(zip(features, thresholds)):
        for j, value in enumerate((thr, np.nextafter(thr, np.inf), np.nextafter(thr, -np.inf))):
            probes[3 * i + j, f] = value
    for data in (X, rng.normal(size=(20000, N_FEATURES)), probes):
        assert np.array_equal(learner.predict(data), tree.predict(data))


def test_tree_list_merges_a_falling_subtree_into_one_rule():
    # Falling iff x0 > 0.5, with some balanced noise where x1 > 0.9: the tree splits the
    # falling side on x1 into two leaves that both predict falling; the list keeps one rule.
    rng = np.random.default_rng(6)
    X = rng.random((4000, N_FEATURES))
    y = (X[:, 0] > 0.5).astype(np.int8)
    y[(X[:, 0] > 0.5) & (X[:, 1] > 0.9) & (rng.random(4000) < 0.3)] = BALANCED
    learner = TreeListLearner(max_depth=2, min_samples_leaf=1).fit(X, y, np.ones(4000))
    tree = learner.estimator_.tree_
    falling_leaves = [node for node in range(tree.node_count)
                      if tree.children_left[node] == -1 and np.argmax(tree.value[node]) == FALLING]
    assert len(falling_leaves) == 2
    (rule,) = learner.decision_list_.rules
    assert [(c.feature, c.op) for c in rule.conditions] == [(0, '>')]
    assert np.array_equal(learner.predict(X), learner.estimator_.predict(X))


def test_float32_threshold_conversion_is_exact():
    rng = np.random.default_rng(7)
    for threshold in np.concatenate([rng.normal(size=500) * 10.0 ** rng.integers(-6, 6, 500),
                                     [0.0, -0.0, 1.0, 0.1, 3.4e38]]):
        t64 = float32_threshold_as_float64(float(threshold))
        probes = np.array([t64, np.nextafter(t64, np.inf), np.nextafter(t64, -np.inf), threshold])
        assert np.array_equal(probes <= t64, probes.astype(np.float32) <= threshold)


@pytest.mark.parametrize('learner', LEARNERS, ids=lambda learner: type(learner).__name__)
def test_single_class_data(learner):
    X, _, _ = conjunction_data(500, seed=8)
    balanced_only = clone(learner).fit(X, np.zeros(500, dtype=np.int8))
    assert balanced_only.decision_list_.depth == 0
    falling_only = clone(learner).fit(X, np.ones(500, dtype=np.int8))
    assert (falling_only.predict(X) == FALLING).all()


@pytest.mark.parametrize('learner, bad', [
    (TreeListLearner(max_depth=0), 'max_depth'),
    (TreeListLearner(criterion='mse'), 'criterion'),
    (TreeListLearner(ccp_alpha=-1.0), 'ccp_alpha'),
    (TreeListLearner(min_weight_fraction_leaf=0.7), 'min_weight_fraction_leaf'),
    (CoveringListLearner(n_bins=1000), 'n_bins'),
    (CoveringListLearner(prune_fraction=1.0), 'prune_fraction'),
    (CoveringListLearner(min_precision=float('nan')), 'min_precision'),
    (CoveringListLearner(max_rules=True), 'max_rules'),
])
def test_hyper_parameters_are_stored_verbatim_and_checked_in_fit(learner, bad):
    X, y, w = conjunction_data(200, seed=9)
    assert learner_description(learner)['params'][bad] is getattr(learner, bad)
    with pytest.raises(ValueError, match=bad):
        learner.fit(X, y, w)


def test_fit_rejects_bad_input():
    X, y, w = conjunction_data(200, seed=10)
    X_nan = X.copy()
    X_nan[3, 4] = np.nan
    with pytest.raises(ValueError, match='NaN'):
        TreeListLearner().fit(X_nan, y, w)
    with pytest.raises(ValueError, match='labels'):
        TreeListLearner().fit(X, np.full(200, 2), w)
    with pytest.raises(ValueError, match='sample_weight'):
        CoveringListLearner().fit(X, y, -w)
    with pytest.raises(ValueError, match='shape'):
        CoveringListLearner().fit(X[:, :3], y, w)
    with pytest.raises(RuntimeError):
        TreeListLearner().predict(X)


def test_training_set_weights_and_groups():
    trajectories = make_dataset(n_fallen=1, n_balanced=1, seed=11, duration_s=1.6)
    X, y, w, modes, groups = training_set(trajectories, tau_plus_s=0.25)
    fallen_rows = groups == 0
    # Fallen trajectory: 500 balanced samples before the push, falling [1.25, 1.5) = 250.
    assert (y[fallen_rows] == BALANCED).sum() == 500
    assert (y[fallen_rows] == FALLING).sum() == 250
    assert set(w[y == BALANCED]) == {4.0} and set(w[y == FALLING]) == {1.0}
    assert (groups == 1).sum() == 1600
    assert X.shape == (2350, N_FEATURES) and modes.shape == (2350,)


def test_covering_learner_holds_out_whole_trajectories():
    # With groups, no rule is accepted if it only fits the noise of the grow trajectories:
    # pure-noise labels (falling on random trajectories) yield no rule.
    rng = np.random.default_rng(12)
    groups = np.repeat(np.arange(40), 200)
    X = rng.normal(size=(groups.size, N_FEATURES))
    y = (groups % 2 == 0).astype(np.int8)        # label depends on the trajectory only
    w = np.where(y == BALANCED, 4.0, 1.0)
    learner = CoveringListLearner(min_coverage=5.0).fit(X, y, w, groups=groups)
    assert learner.decision_list_.depth == 0
    # The same rule-free answer regardless of the random split.
    assert CoveringListLearner(min_coverage=5.0, random_state=1).fit(
        X, y, w, groups=groups).decision_list_.depth == 0


def test_conditions_use_threshold_values_of_the_data():
    X, y, w = conjunction_data(3000, seed=13)
    learner = CoveringListLearner(n_bins=16).fit(X, y, w)
    for rule in learner.decision_list_.rules:
        for condition in rule.conditions:
            assert isinstance(condition, Condition)
            assert condition.threshold in set(X[:, condition.feature].tolist())
