"""Time-to-fall trees and the fall-direction ground truth (item 7)."""
import dataclasses
import json
import math

import numpy as np
import pytest
from sklearn.tree import DecisionTreeRegressor

from fall_predictor.learning.time_to_fall_training import (export_tree, falling_states,
                                                           fit_time_to_fall)
from fall_predictor.learning.when_where import (actual_direction, summary, time_to_fall_errors,
                                                trigger_indices)
from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.model_file import ModelFileError, load_model, save_model
from fall_predictor.monitor.records import N_CONTACT_MODES, N_FEATURES
from fall_predictor.monitor.time_to_fall import (RegressionTree, TimeToFallError,
                                                 TimeToFallRegressor)
from synthetic_trajectories import FALLING_MODE, T_FALLEN_S, T_PUSH_S, make_dataset
from test_model_file import example_lists, example_metadata


def test_exported_tree_walk_equals_sklearn_predict():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(2000, N_FEATURES))
    y = np.sin(X[:, 2]) + X[:, 7] ** 2
    model = DecisionTreeRegressor(max_depth=7, min_samples_leaf=5).fit(X, y)
    tree = export_tree(model)
    Q = rng.normal(size=(500, N_FEATURES))
    ours = np.array([tree.predict_one(q.tolist()) for q in Q])
    np.testing.assert_array_equal(ours, model.predict(Q))
    assert tree.depth == model.get_depth()


def with_time_to_fall_feature(trajectories):
    """Feature 0 carries the true time to fall on the falling states (a learnable target)."""
    for traj in trajectories:
        if traj.fallen:
            falling = (traj.t >= traj.t_push) & (traj.t < traj.t_fallen)
            traj.X[falling, 0] = traj.t_fallen - traj.t[falling]
    return trajectories


def test_fit_recovers_a_learnable_time_to_fall():
    train = with_time_to_fall_feature(make_dataset(6, 2, seed=1))
    test = with_time_to_fall_feature(make_dataset(3, 0, seed=2))
    regressor = fit_time_to_fall(train, sample_stride=5)
    # Only the mode after the push (L-LEFT) has falling states: its own tree, others fall back.
    assert regressor.trees[FALLING_MODE] is not None
    assert sum(t is not None for t in regressor.trees) == 1
    X, mode, ttf = falling_states(test, sample_stride=7)
    assert ttf.max() == pytest.approx(T_FALLEN_S - T_PUSH_S) and ttf.min() > 0.0
    errors = np.abs([regressor.predict_one(x.tolist(), int(m)) - y for x, m, y in zip(X, mode, ttf)])
    # Leaves hold >= 20 samples: 6 trajectories x stride 5 ms make a leaf ~17 ms wide, so
    # errors stay within about half that (a constant prediction would err by 0.25 s median).
    assert np.median(errors) < 0.012 and errors.max() < 0.03
    # Triggers at known samples: the error is measured against t_fallen - t.
    k = int(np.searchsorted(test[0].t, 1.2))
    err = time_to_fall_errors(test[:1], [k], regressor)
    assert err[0] == pytest.approx(abs(regressor.predict_one(test[0].X[k].tolist(), FALLING_MODE)
                                       - (T_FALLEN_S - test[0].t[k])))
    assert err[0] < 0.03


def test_predictions_are_never_negative_and_unknown_modes_use_the_fallback():
    leaf = RegressionTree((-1,), (0.0,), (-1,), (-1,), (-0.5,))
    other = RegressionTree((-1,), (0.0,), (-1,), (-1,), (0.25,))
    trees = [None] * N_CONTACT_MODES
    trees[3] = leaf
    regressor = TimeToFallRegressor(tuple(trees), fallback=other)
    assert regressor.predict_one([0.0] * N_FEATURES, 3) == 0.0
    assert regressor.predict_one([0.0] * N_FEATURES, 4) == 0.25


def test_model_file_v3_round_trip_and_v2_still_loads(tmp_path):
    regressor = fit_time_to_fall(with_time_to_fall_feature(make_dataset(3, 1, seed=4)), 10)
    metadata = dataclasses.replace(example_metadata(), robot_mass_kg=42.1, time_to_fall=regressor)
    path = tmp_path / 'model.json'
    save_model(path, example_lists(), metadata)
    _, loaded = load_model(path)
    assert loaded.robot_mass_kg == 42.1
    assert loaded.time_to_fall == regressor
    # A version-2 file (no mass, no time to fall) still loads, with both None.
    document = json.loads(path.read_text())
    document['schema_version'] = 2
    del (document['robot_mass_kg'], document['time_to_fall'], document['fall_direction'],
         document['input_names'])
    old = tmp_path / 'v2.json'
    old.write_text(json.dumps(document))
    _, v2 = load_model(old)
    assert v2.robot_mass_kg is None and v2.time_to_fall is None
    # Version 3 requires both keys; a tree whose child points backwards is refused.
    document['schema_version'] = 3
    old.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match='missing key'):
        load_model(old)
    document = json.loads(path.read_text())
    document['time_to_fall']['fallback']['left'][0] = 0
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match='time_to_fall.fallback'):
        load_model(path)


def test_tree_validation():
    with pytest.raises(TimeToFallError, match='feature index'):
        RegressionTree((N_FEATURES, -1, -1), (0.0,) * 3, (1, -1, -1), (2, -1, -1), (0.0,) * 3)
    with pytest.raises(TimeToFallError, match='non-finite'):
        RegressionTree((-1,), (0.0,), (-1,), (-1,), (math.nan,))


def test_actual_direction_is_in_the_heading_frame_at_the_trigger():
    t = np.arange(100) * 0.01
    # The CoM moves along world +y; the robot faces world +y (heading 90 deg): forward, +x.
    com = np.column_stack([np.zeros(100), 0.3 * t])
    heading = np.full(100, math.pi / 2)
    np.testing.assert_allclose(actual_direction(com, heading, t, 10, 0.8), [1.0, 0.0], atol=1e-12)
    # Facing world +x, the same motion is to the robot's left (+y).
    np.testing.assert_allclose(actual_direction(com, 0 * heading, t, 10, 0.8), [0.0, 1.0],
                               atol=1e-12)


def test_summary():
    s = summary([3.0, 1.0, math.nan, 2.0])
    assert s == {'median': 2.0, 'p90': pytest.approx(2.8), 'max': 3.0, 'n': 3}
    assert summary([])['median'] is None


def test_momentum_direction_is_the_horizontal_momentum():
    from fall_predictor.monitor.fall_direction import momentum_direction
    x = [0.0] * N_FEATURES
    x[3], x[4], x[5] = 3.0, -4.0, 7.0
    np.testing.assert_allclose(momentum_direction(x, 42.0), [0.6, -0.8, 0.0])
    x[3] = x[4] = 0.0
    assert np.isnan(momentum_direction(x, 42.0)).all()
    with pytest.raises(ValueError):
        momentum_direction(x, 0.0)


def test_triggers_come_from_the_given_guard():
    """Empty lists: only the CoM guard triggers. The synthetic CoM stands at 0.59 +- 0.005 m, so a
    0.60 m guard triggers on the fallen trajectory at the push (sample 500); the default guard
    only at t_fallen, too late to be a trigger. Balanced trajectories never have one."""
    trajectories = make_dataset(1, 1, seed=4)
    empty = PerModeDecisionLists.empty()
    assert trigger_indices(trajectories, empty, 0.0, guard_com_height_m=0.60) == \
        [int(round(T_PUSH_S * 1000)), None]
    assert trigger_indices(trajectories, empty, 0.0) == [None, None]


def test_boosted_time_to_fall_at_triggers_recovers_a_learnable_target_and_runs_as_sklearn():
    """Fitted on the samples from each trigger until fallen (method §8d), on a target that
    feature 0 carries: errors at held-out triggers well under a constant's, and the exported
    trees predict what scikit-learn's model predicts."""
    from sklearn.ensemble import HistGradientBoostingRegressor

    from fall_predictor.learning.time_to_fall_training import (TIME_TO_FALL_LEARNER_PARAMS,
                                                               fit_time_to_fall_at_triggers,
                                                               time_left_after_triggers)
    train = with_time_to_fall_feature(make_dataset(12, 2, seed=5))
    test = with_time_to_fall_feature(make_dataset(4, 1, seed=6))
    rng = np.random.default_rng(7)
    # Triggers anywhere from the push to 0.2 s before the fall; none on the balanced runs.
    def triggers(trajs):
        return [int(np.searchsorted(t.t, rng.uniform(T_PUSH_S, T_FALLEN_S - 0.2))) if t.fallen
                else None for t in trajs]
    train_triggers, test_triggers = triggers(train), triggers(test)
    X, _, left, at_trigger = time_left_after_triggers(train, train_triggers)
    assert at_trigger.sum() == 12 and left.min() > 0.0
    assert left[at_trigger] == pytest.approx([T_FALLEN_S - t.t[k] for t, k in
                                              zip(train, train_triggers) if k is not None])
    boosted = fit_time_to_fall_at_triggers(train, train_triggers)
    assert len(boosted.trees) == TIME_TO_FALL_LEARNER_PARAMS['max_iter']
    X_test, _, left_test, at_test = time_left_after_triggers(test, test_triggers)
    ours = np.array([boosted.predict_one(x.tolist()) for x in X_test])
    # Over every 10th sample from the test triggers until fallen (0.2-1 s left).
    assert at_test.sum() == 4 and np.median(np.abs(ours - left_test)) < 0.02
    constant = np.median(left[at_trigger])
    assert np.median(np.abs(constant - left_test)) > 0.1
    sklearn = HistGradientBoostingRegressor(**TIME_TO_FALL_LEARNER_PARAMS, random_state=0).fit(X, left)
    np.testing.assert_allclose(ours, np.maximum(sklearn.predict(X_test), 0.0), atol=1e-12)
