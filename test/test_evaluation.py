"""Evaluating a model on a dataset (fall_predictor.learning.evaluation), the baselines next to
it, the capture-point cache, and the CLI subcommand ``evaluate``, on a small generated dataset."""
import json
import math

import numpy as np
import pytest

from fall_predictor import cli
from fall_predictor.data.bagio import read_trajectory
from fall_predictor.data.dataset import read_index, robot_total_mass_kg
from fall_predictor.learning.evaluation import (capture_point_distances_cached, evaluate_model,
                                                evaluation_json, json_float)
from fall_predictor.learning.intervals import wilson_interval
from fall_predictor.learning.metrics import evaluate_lists
from fall_predictor.learning.training import load_dataset, train_model
from fall_predictor.monitor.capture_point import capture_point_distances
from fall_predictor.monitor.model_file import save_model

from learning_fixtures import fixture_dataset  # noqa: F401  (a pytest fixture)


def test_json_float_writes_nan_and_infinity_as_null():
    assert json_float(0.25) == 0.25 and json_float(3) == 3.0 and isinstance(json_float(3), float)
    assert json_float(math.nan) is None and json_float(-math.inf) is None and json_float(None) is None


def test_capture_point_distances_are_kept_in_the_feature_cache(fixture_dataset):
    trajectories = load_dataset(fixture_dataset).trajectories[:2]
    cache = fixture_dataset / 'cache' / f'{trajectories[0].trajectory_id}.npz'
    assert cache.exists()                                      # written by load_dataset
    stamp = cache.stat().st_mtime_ns
    first = capture_point_distances_cached(fixture_dataset, trajectories)
    second = capture_point_distances_cached(fixture_dataset, trajectories)
    assert cache.stat().st_mtime_ns == stamp                   # read from the cache, not the bag
    rows = {r.trajectory_id: r for r in read_index(fixture_dataset)}
    for a, b, traj in zip(first, second, trajectories):
        assert a.shape == traj.t.shape and np.array_equal(a, b)
        # Independent: straight from the bag's measurements.
        ms = read_trajectory(fixture_dataset / rows[traj.trajectory_id].bag).measurements
        np.testing.assert_array_equal(a, capture_point_distances(ms, robot_total_mass_kg(fixture_dataset)))


def test_evaluate_model_with_baselines(fixture_dataset):
    lists, metadata = train_model(fixture_dataset, -0.25, 'tree', {'max_depth': 4})
    evaluation = evaluate_model(fixture_dataset, lists, 0.06, baselines=True)
    trajectories = load_dataset(fixture_dataset).trajectories
    assert evaluation.result == evaluate_lists(trajectories, lists, (0.06,))[0.06]
    assert evaluation.dataset_fingerprint == metadata.dataset_fingerprint
    assert evaluation.unreadable == {}
    payload = evaluation_json(evaluation)
    json.dumps(payload, allow_nan=False)                       # NaN and infinity are null
    assert payload['tau_his_s'] == 0.06 and payload['n_pre_push_alarms'] == \
        evaluation.result.n_pre_push_alarms
    assert set(payload['baselines']) == {'com_height', 'momentum', 'capture_point'}
    assert all(payload['baselines'].values())
    with pytest.raises(ValueError, match='tau_his'):
        evaluate_model(fixture_dataset, lists, -0.01)


def test_cli_evaluate(fixture_dataset, tmp_path, capsys):
    lists, metadata = train_model(fixture_dataset, -0.25, recommended_tau_his_s=0.06)
    model = tmp_path / 'model.json'
    save_model(model, lists, metadata)
    code = cli.main(['evaluate', '--data', str(fixture_dataset), '--model', str(model), '--json'])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    evaluation = json.loads(captured.out)
    expected = evaluate_lists(load_dataset(fixture_dataset).trajectories, lists, (0.06,))[0.06]
    assert evaluation['tau_his_s'] == 0.06 and evaluation['fpr'] == pytest.approx(expected.fpr)
    assert evaluation['tau_lead_s'] == pytest.approx(expected.tau_lead_s)
    assert evaluation['trained_on_this_dataset'] is True
    for key in ('n_missed', 'n_pre_push_alarms', 'oracle_lead_s', 'lead_fraction', 'mean_rule_size'):
        assert key in evaluation
    # SPEC §11 figures: Wilson interval of the FPR counts, lists alone never better than with guard
    low, high = evaluation['fpr_ci95']
    assert low <= evaluation['fpr'] <= high
    assert [low, high] == pytest.approx(list(wilson_interval(expected.n_false_positives,
                                                             expected.n_balanced)))
    assert evaluation['misses_lists_only'] >= evaluation['n_missed']
    assert evaluation['tau_lead_lists_only'] <= evaluation['tau_lead_s'] + 1e-12
    lead_low, lead_high = evaluation['tau_lead_ci95']
    assert lead_low <= evaluation['tau_lead_s'] <= lead_high
