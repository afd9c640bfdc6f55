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
from fall_predictor.learning.training import load_dataset
from fall_predictor.monitor.capture_point import capture_point_distances
from fall_predictor.monitor.decision_list import DecisionList, PerModeDecisionLists
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.model_file import ModelMetadata, save_model
from fall_predictor.monitor.records import FALLING, N_CONTACT_MODES

from learning_fixtures import fixture_dataset  # noqa: F401  (a pytest fixture)
from robot_datasets import G1_GUARD_LEAD_S, write_robot_dataset


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


def always_falling() -> PerModeDecisionLists:
    """Lists that say falling in every contact mode (no rules, default falling): rule size 0."""
    return PerModeDecisionLists(tuple(DecisionList(default=FALLING) for _ in range(N_CONTACT_MODES)))


def known_answers(dataset) -> dict:
    """method §5 figures of a predictor that says falling at every sample, from the dataset's
    index files as the generator wrote them: every balanced trajectory is a false positive, every
    trajectory has a pre-push alarm (the features start 0.5 s before the push, longer than any
    history window used here), and the lead of a fallen one is t_fallen - t_push (the first
    sample at or after the push), the oracle lead. Wilson's lower bound for k = n is
    n / (n + z^2), the upper 1."""
    rows = [json.loads(f.read_text()) for f in sorted((dataset / 'index').glob('traj_*.json'))]
    fallen = [r for r in rows if r['fallen']]
    n_balanced = len(rows) - len(fallen)
    assert fallen and n_balanced and all(r['t_push'] - r['t_start'] >= 0.5 - 1e-9 for r in rows)
    lead = sum(r['t_fallen'] - r['t_push'] for r in fallen) / len(fallen)
    return {'n_trajectories': len(rows), 'n_fallen': len(fallen), 'n_balanced': n_balanced,
            'n_false_positives': n_balanced, 'fpr': 1.0, 'tau_lead_s': lead, 'n_missed': 0,
            'n_pre_push_alarms': len(rows), 'oracle_lead_s': lead, 'lead_fraction': 1.0,
            'mean_rule_size': 0.0, 'fpr_ci95': [n_balanced / (n_balanced + 1.959964 ** 2), 1.0]}


def test_evaluate_model_with_baselines(fixture_dataset):
    expected = known_answers(fixture_dataset)
    evaluation = evaluate_model(fixture_dataset, always_falling(), 0.06, baselines=True)
    assert evaluation.unreadable == {}
    payload = evaluation_json(evaluation)
    json.dumps(payload, allow_nan=False)                       # NaN and infinity are null
    assert payload['tau_his_s'] == 0.06
    for key, value in expected.items():
        assert payload[key] == pytest.approx(value, abs=1e-6), key
    r = evaluation.result
    assert (r.n_pre_push_alarms_balanced, r.n_pre_push_alarms_fallen) == \
        (expected['n_balanced'], expected['n_fallen'])
    assert r.n_missed_lists_only == 0 and r.tau_lead_lists_only_s == pytest.approx(expected['tau_lead_s'])
    assert set(payload['baselines']) == {'com_height', 'momentum', 'capture_point'}
    assert all(payload['baselines'].values())
    # Lists that never say falling: with the CoM guard off every fall is missed.
    never = evaluate_model(fixture_dataset, PerModeDecisionLists.empty(), 0.06).result
    assert never.n_missed_lists_only == expected['n_fallen'] and never.tau_lead_lists_only_s == 0.0
    with pytest.raises(ValueError, match='tau_his'):
        evaluate_model(fixture_dataset, always_falling(), -0.01)


def test_cli_evaluate(fixture_dataset, tmp_path, capsys):
    expected = known_answers(fixture_dataset)
    model = tmp_path / 'model.json'
    save_model(model, always_falling(), ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={}, dataset_fingerprint=load_dataset(fixture_dataset).fingerprint,
        recommended_tau_his_s=0.06))
    code = cli.main(['evaluate', '--data', str(fixture_dataset), '--model', str(model), '--json'])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    evaluation = json.loads(captured.out)
    assert evaluation['tau_his_s'] == 0.06                     # the model's recommendation
    for key, value in expected.items():
        assert evaluation[key] == pytest.approx(value, abs=1e-6), key
    assert evaluation['trained_on_this_dataset'] is True       # same fingerprint in the model
    # method §11 figures: the lists alone are the same predictor here (always falling).
    assert evaluation['misses_lists_only'] == 0
    assert evaluation['tau_lead_lists_only'] == pytest.approx(expected['tau_lead_s'])
    lead_low, lead_high = evaluation['tau_lead_ci95']
    assert lead_low <= evaluation['tau_lead_s'] <= lead_high



def test_cli_evaluate_refuses_an_estimated_state_model_on_a_dataset_without_sensors(
        fixture_dataset, tmp_path, capsys):
    """The dataset has no sensor topics, so its features would silently come from the true state:
    not what a model trained on the estimated state sees onboard. Refused, saying what to do;
    --state true evaluates it so on purpose."""
    model = tmp_path / 'estimated.json'
    save_model(model, always_falling(), ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={}, dataset_fingerprint='x', recommended_tau_his_s=0.06, state='estimated'))
    code = cli.main(['evaluate', '--data', str(fixture_dataset), '--model', str(model), '--json'])
    assert code == 2
    assert 'recorded without sensor topics' in capsys.readouterr().err
    code = cli.main(['evaluate', '--data', str(fixture_dataset), '--model', str(model), '--state',
                     'true', '--json'])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert json.loads(captured.out)['model_state'] == 'estimated'


# -- the CoM guard: the model's, else the dataset's robot's --------------------------------------
def test_evaluate_model_without_a_model_guard_uses_the_dataset_robots_guard(tmp_path):
    """Empty decision lists on the tiny G1 dataset (CoM between 0.48 and 0.55 m): the guard
    alone decides. The G1's 0.55 m predicts both falls 0.049 s ahead and alarms on both squats;
    the ASIMO-like robot's 0.48 m, passed explicitly, misses both falls and never alarms."""
    data = write_robot_dataset(tmp_path / 'g1', 'g1')
    evaluation = evaluate_model(data, PerModeDecisionLists.empty(), 0.0, baselines=True)
    r = evaluation.result
    assert evaluation.guard_com_height_m == 0.55 and evaluation_json(evaluation)['guard_com_height_m'] == 0.55
    assert (r.n_false_positives, r.n_balanced, r.n_missed, r.n_fallen) == (2, 2, 0, 2)
    assert r.tau_lead_s == pytest.approx(G1_GUARD_LEAD_S, abs=1e-9)
    # the baselines run with the same guard: "CoM below 0.40 m" is the guard alone
    below_040 = evaluation.baselines.com_height[0]
    assert below_040.threshold == pytest.approx(0.40)
    assert below_040.fpr == 1.0 and below_040.tau_lead_s == pytest.approx(G1_GUARD_LEAD_S, abs=1e-9)
    explicit = evaluate_model(data, PerModeDecisionLists.empty(), 0.0, guard_com_height_m=0.48)
    assert explicit.guard_com_height_m == 0.48
    assert (explicit.result.n_false_positives, explicit.result.n_missed) == (0, 2)
    assert explicit.result.tau_lead_s == 0.0


def test_the_asimo_like_robots_evaluation_keeps_its_guard(tmp_path):
    data = write_robot_dataset(tmp_path / 'asimo_like', 'asimo_like')
    evaluation = evaluate_model(data, PerModeDecisionLists.empty(), 0.0)
    assert evaluation.guard_com_height_m == 0.48
    assert (evaluation.result.n_false_positives, evaluation.result.n_missed) == (0, 2)


def test_cli_evaluate_uses_the_models_recorded_guard(tmp_path, capsys):
    """A model recording the G1's guard predicts the G1 dataset's falls by its guard; one
    recording 0.48 m (trained before models recorded their robot's guard) keeps its own, as the
    monitor would run it, and the evaluation says that it is not the robot's."""
    data = write_robot_dataset(tmp_path / 'g1', 'g1')
    results = {}
    for guard_m in (0.55, 0.48):
        model = tmp_path / f'model_{guard_m}.json'
        save_model(model, PerModeDecisionLists.empty(), ModelMetadata(
            tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
            learner_params={}, dataset_fingerprint='other', recommended_tau_his_s=0.0,
            feature_settings=FeatureSettings(guard_com_height_m=guard_m)))
        code = cli.main(['evaluate', '--data', str(data), '--model', str(model), '--json'])
        captured = capsys.readouterr()
        assert code == 0, captured.err
        results[guard_m] = json.loads(captured.out)
        assert results[guard_m]['guard_com_height_m'] == guard_m
        assert results[guard_m]['dataset_guard_com_height_m'] == 0.55
        assert cli.main(['evaluate', '--data', str(data), '--model', str(model)]) == 0
        text = capsys.readouterr().out
        assert (f"the model's CoM guard ({guard_m:g} m) is not the dataset's robot's" in text) \
            == (guard_m != 0.55)
    assert (results[0.55]['n_false_positives'], results[0.55]['n_missed']) == (2, 0)
    assert results[0.55]['tau_lead_s'] == pytest.approx(G1_GUARD_LEAD_S, abs=1e-9)
    assert (results[0.48]['n_false_positives'], results[0.48]['n_missed']) == (0, 2)
