"""Boosted trees as plain data: known answers, the scalar and vectorised paths, the file form."""
import json
import math
import pickle

import numpy as np
import pytest

from fall_predictor.monitor.boosted_trees import BoostedTrees, BoostedTreesError
from fall_predictor.monitor.records import BALANCED, FALLING, FEATURE_NAMES, N_FEATURES
from fall_predictor.monitor.time_to_fall import RegressionTree

COM_Z = FEATURE_NAMES.index('com_z')
LIN_MOM_X = FEATURE_NAMES.index('lin_mom_x')


def stump(feature: int, threshold: float, left: float, right: float) -> RegressionTree:
    return RegressionTree((feature, -1, -1), (threshold, 0.0, 0.0), (1, -1, -1), (2, -1, -1),
                          (0.0, left, right))


def example() -> BoostedTrees:
    """Score -1 + (momentum > 20: +2.5 else -0.5) + (CoM height <= 0.5: +1.0 else 0.0)."""
    return BoostedTrees((stump(LIN_MOM_X, 20.0, -0.5, 2.5), stump(COM_Z, 0.5, 1.0, 0.0)),
                        bias=-1.0, decision_threshold=1.0)


def features(lin_mom_x: float, com_z: float) -> list[float]:
    x = [0.0] * N_FEATURES
    x[LIN_MOM_X], x[COM_Z] = lin_mom_x, com_z
    return x


@pytest.mark.parametrize('lin_mom_x, com_z, score', [
    (0.0, 0.6, -1.5), (25.0, 0.6, 1.5), (0.0, 0.4, -0.5), (25.0, 0.4, 2.5),
    (20.0, 0.5, -0.5),                       # on a threshold: left (<=) in both trees
    (math.nan, 0.6, 1.5),                    # NaN goes right: NaN <= t is false
])
def test_the_score_is_the_bias_plus_one_leaf_per_tree(lin_mom_x, com_z, score):
    trees = example()
    x = features(lin_mom_x, com_z)
    assert trees.score_one(x) == score
    assert trees.score(np.array([x]))[0] == score
    assert trees.predict_one(x) == (FALLING if score > 1.0 else BALANCED)
    assert trees.predict(np.array([x]))[0] == trees.predict_one(x)


def test_falling_needs_the_score_strictly_above_the_threshold():
    trees = BoostedTrees((stump(LIN_MOM_X, 20.0, 0.0, 1.0),), bias=0.0, decision_threshold=1.0)
    assert trees.predict_one(features(30.0, 0.6)) == BALANCED        # score 1.0, not > 1.0
    assert BoostedTrees(trees.trees, 0.0, 0.999).predict_one(features(30.0, 0.6)) == FALLING


def test_a_models_decision_threshold_moves_for_its_boosted_modes_only():
    from fall_predictor.monitor.decision_list import DecisionList, PerModeDecisionLists
    from fall_predictor.monitor.fall_monitor import FallenConfig, FallMonitor
    model = PerModeDecisionLists((example(),) * 2 + (DecisionList(),) * 14)
    assert model.decision_threshold == 1.0
    x = features(25.0, 0.6)                               # score 1.5
    lowered, raised = model.with_decision_threshold(1.4), model.with_decision_threshold(1.5)
    assert lowered.decision_threshold == 1.4 and lowered.lists[2:] == model.lists[2:]
    assert (lowered.predict_one(x, 1), raised.predict_one(x, 1)) == (FALLING, BALANCED)
    with pytest.raises(BoostedTreesError, match='decision_threshold'):
        model.with_decision_threshold(math.inf)
    lists_only = PerModeDecisionLists.empty()
    assert lists_only.decision_threshold is None
    with pytest.raises(ValueError, match='decision lists, which have no decision threshold'):
        lists_only.with_decision_threshold(0.0)
    # At run time: effective from the next step; the history window's run goes on.
    monitor = FallMonitor(raised, 0.002, FallenConfig(0.2, 0.3), guard_com_height_m=0.1)
    x_array = np.array(x)
    assert not monitor.step(0.000, x_array, 1)[0].atomic
    monitor.decision_threshold = 1.4
    assert monitor.decision_threshold == 1.4
    states = [monitor.step(t, x_array, 1)[0] for t in (0.001, 0.002, 0.003)]
    assert [s.atomic for s in states] == [True, True, True]
    assert [s.falling for s in states] == [False, False, True]   # 2 ms after the run began
    with pytest.raises(ValueError, match='no decision threshold'):
        FallMonitor(lists_only, 0.0, FallenConfig(0.2, 0.3)).decision_threshold = 0.0


def test_sizes_count_comparisons_and_trees():
    trees = example()
    assert (trees.rule_size, trees.depth) == (2, 2)
    assert 'sum of 2 trees' in trees.format(mode_name='LR-INSIDE')


def test_deep_trees_agree_on_both_paths_bit_for_bit():
    rng = np.random.default_rng(3)
    # A random complete tree of depth 4 per estimator (nodes in pre-order: children follow parents).
    def random_tree(depth: int) -> RegressionTree:
        feature, threshold, left, right, value = [], [], [], [], []
        def grow(level: int) -> int:
            i = len(feature)
            for array in (feature, threshold, left, right, value):
                array.append(0)
            if level == depth:
                feature[i], threshold[i], left[i], right[i], value[i] = -1, 0.0, -1, -1, float(rng.normal())
                return i
            feature[i], threshold[i] = int(rng.integers(N_FEATURES)), float(rng.normal())
            left[i] = grow(level + 1)
            right[i] = grow(level + 1)
            return i
        grow(0)
        return RegressionTree(tuple(feature), tuple(threshold), tuple(left), tuple(right), tuple(value))
    trees = BoostedTrees(tuple(random_tree(4) for _ in range(30)), bias=0.3)
    X = rng.normal(size=(500, N_FEATURES))
    X[::7, 3] = np.nan
    assert np.array_equal(trees.score(X), [trees.score_one(list(x)) for x in X])


def test_file_form_round_trips_and_pickles():
    trees = example()
    again = BoostedTrees.from_json(json.loads(json.dumps(trees.to_json())))
    assert again == trees and again.score_one(features(25.0, 0.4)) == 2.5
    assert pickle.loads(pickle.dumps(trees)).score_one(features(25.0, 0.4)) == 2.5


@pytest.mark.parametrize('change, message', [
    (lambda d: d.pop('bias'), 'expected an object with keys'),
    (lambda d: d.update(bias=math.inf), 'bias must be a finite number'),
    (lambda d: d.update(decision_threshold='1'), 'decision_threshold must be a finite number'),
    (lambda d: d.update(trees={}), 'trees: expected an array'),
    (lambda d: d['trees'][1]['feature'].__setitem__(0, N_FEATURES), 'trees[1]'),
    (lambda d: d['trees'][0]['left'].__setitem__(0, 0), 'trees[0]'),       # a loop: never a leaf
])
def test_malformed_trees_are_rejected_naming_the_field(change, message):
    document = example().to_json()
    change(document)
    with pytest.raises(BoostedTreesError, match=message.replace('[', r'\[').replace(']', r'\]')):
        BoostedTrees.from_json(document)
