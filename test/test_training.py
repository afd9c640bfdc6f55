"""Training (fall_predictor.learning.training) and the CLI subcommands ``train`` and ``rules``.
Learner-level tests use synthetic trajectories; pipeline tests a small generated dataset."""
import dataclasses
import json
import math

import numpy as np
import pytest

from fall_predictor import cli
from fall_predictor.learning.learners import training_set
from fall_predictor.learning.metrics import evaluate_lists
from fall_predictor.learning.training import (fit_strided, load_dataset, make_learner,
                                              rules_summary, subsample, train_model)
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.decision_list import Condition, DecisionList, PerModeDecisionLists, Rule
from fall_predictor.monitor.model_file import load_model
from fall_predictor.monitor.records import BALANCED, FALLING, N_CONTACT_MODES

from learning_fixtures import fixture_dataset  # noqa: F401  (a pytest fixture)
from robot_datasets import write_robot_dataset
from synthetic_trajectories import (FALLING_MODE, LIN_MOM_Y, T_FALLEN_S, T_HEIGHT_DROP_S,
                                    make_dataset)


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


# -- learners, stride --------------------------------------------------------------------------
def test_make_learner_validates_name_params_and_values():
    assert make_learner('tree', {'max_depth': 3}).max_depth == 3
    assert make_learner('covering').get_params()['n_bins'] > 0
    with pytest.raises(ValueError, match='unknown learner'):
        make_learner('forest')
    with pytest.raises(ValueError, match='unknown hyper-parameter.*max_dept'):
        make_learner('tree', {'max_dept': 3})
    with pytest.raises(ValueError, match='max_depth'):
        make_learner('tree', {'max_depth': 0})


def test_subsample_keeps_every_kth_sample_and_the_hindsight_times():
    traj = make_dataset(1, 0, seed=0)[0]
    strided = subsample(traj, 10)
    assert np.array_equal(strided.t, traj.t[::10]) and np.array_equal(strided.X, traj.X[::10])
    assert strided.t_fallen == traj.t_fallen and strided.t_height_drop == traj.t_height_drop
    assert subsample(traj, 1) is traj
    with pytest.raises(ValueError, match='sample_stride'):
        subsample(traj, 0)


def test_stride_weights_keep_the_class_weight_per_unit_time():
    trajectories = make_dataset(3, 3, seed=1)
    _, y1, w1, _, _ = training_set(trajectories, 0.0)
    _, y10, w10, _, _ = training_set([subsample(t, 10) for t in trajectories], 0.0, 4.0 * 10, 1.0 * 10)
    for label in (BALANCED, FALLING):
        assert w10[y10 == label].sum() == pytest.approx(w1[y1 == label].sum(), rel=0.01)


@pytest.mark.parametrize('learner_name', ['tree', 'covering'])
def test_strided_training_recovers_the_synthetic_rule(learner_name):
    lists = fit_strided(make_dataset(12, 12, seed=2), 0.0, make_learner(learner_name), sample_stride=10)
    conditions = [c for rule in lists.lists[FALLING_MODE].rules for c in rule.conditions]
    assert any(c.feature == LIN_MOM_Y and c.op == '>' and 3.0 < c.threshold < 5.5 for c in conditions)
    # A 3 ms window suppresses lone noise samples beyond a threshold learned from every 10th
    # sample (the covering learner puts it at the largest balanced value it saw).
    result = evaluate_lists(make_dataset(5, 5, seed=3), lists, (0.003,))[0.003]
    assert result.fpr == 0.0 and result.n_missed == 0
    assert result.tau_lead_s == pytest.approx(T_FALLEN_S - T_HEIGHT_DROP_S - 0.003, abs=0.02)


def test_rules_summary_counts_comparisons_and_rules():
    rule = Rule((Condition(2, '<=', 0.4), Condition(4, '>', 5.0)), FALLING)
    lists = PerModeDecisionLists((DecisionList((rule, Rule((Condition(0, '>', 1.0),), FALLING))),)
                                 + tuple(DecisionList() for _ in range(N_CONTACT_MODES - 1)))
    summary = rules_summary(lists)
    assert summary['modes'][0]['rule_size'] == 3 and summary['modes'][0]['depth'] == 2
    assert summary['mean_rule_size'] == pytest.approx(3 / 16)
    assert summary['mean_depth'] == 2.0 and summary['max_depth'] == 2
    assert 'if footContactMode = LR-INSIDE then' in summary['modes'][0]['text']


# -- the generated fixture dataset -----------------------------------------------------------
def test_train_model_on_the_fixture(fixture_dataset):
    lists, metadata = train_model(fixture_dataset, -0.25, 'tree', {'max_depth': 4}, sample_stride=10,
                                  recommended_tau_his_s=0.06)
    assert metadata.tau_plus_s == -0.25 and metadata.recommended_tau_his_s == 0.06
    assert metadata.learner_name == 'TreeListLearner' and metadata.learner_params['max_depth'] == 4
    assert metadata.dataset_fingerprint == load_dataset(fixture_dataset).fingerprint
    # The features were computed with the default settings: the model must say so.
    assert metadata.feature_settings == FeatureSettings()
    assert any(lists.depths), 'some contact mode should have learned a falling rule'
    with pytest.raises(ValueError, match='tau_plus'):
        train_model(fixture_dataset, math.inf)


def test_cli_train_and_rules(fixture_dataset, tmp_path, capsys):
    model = tmp_path / 'model.json'
    code, out, err = run_cli(capsys, 'train', '--data', str(fixture_dataset), '--tau-plus', '-0.25',
                             '--out', str(model), '--tau-his-recommended', '0.06', '--json')
    assert code == 0, err
    trained = json.loads(out)
    lists, metadata = load_model(model)
    assert trained['mean_rule_size'] == pytest.approx(lists.mean_rule_size)
    assert trained['sample_stride'] == 10 and metadata.recommended_tau_his_s == 0.06
    stored = json.loads(model.read_text())['features']
    assert stored['rate_window_s'] == FeatureSettings().rate_window_s
    assert stored['guard_com_height_m'] == FeatureSettings().guard_com_height_m

    code, out, err = run_cli(capsys, 'rules', str(model), '--json')
    assert code == 0, err
    rules = json.loads(out)
    assert [m['rule_size'] for m in rules['modes']] == list(lists.rule_sizes)
    code, out, _ = run_cli(capsys, 'rules', str(model))
    assert code == 0 and 'if footContactMode = OUTSIDE then' in out and 'mean rule size' in out


def test_cli_trains_boosted_trees_that_evaluate_from_their_file_as_in_memory(fixture_dataset, tmp_path, capsys):
    model = tmp_path / 'boosted.json'
    code, out, err = run_cli(capsys, 'train', '--data', str(fixture_dataset), '--tau-plus', '-0.25',
                             '--learner', 'boosting', '--param', 'max_iter=20',
                             '--param', 'decision_threshold=0.5', '--tau-his', '0', '--out', str(model),
                             '--json')
    assert code == 0, err
    lists, metadata = load_model(model)
    assert lists.boosted and metadata.learner_name == 'BoostedTreesLearner'
    assert metadata.learner_params['decision_threshold'] == 0.5
    trajectories = load_dataset(fixture_dataset, state='estimated').trajectories
    in_memory = fit_strided(trajectories, -0.25, make_learner('boosting', {'max_iter': 20,
                                                                           'decision_threshold': 0.5}))
    assert lists == in_memory
    from_file = evaluate_lists(trajectories, lists, (0.0, 0.03))
    assert from_file == evaluate_lists(trajectories, in_memory, (0.0, 0.03))
    assert from_file[0.0].n_fallen > 0 and from_file[0.0].n_missed < from_file[0.0].n_fallen
    code, out, _ = run_cli(capsys, 'rules', str(model))
    assert code == 0 and 'the sum of 20 trees' in out
    # The threshold moved at evaluation: as the same trees trained with that threshold.
    code, out, err = run_cli(capsys, 'evaluate', '--data', str(fixture_dataset), '--model', str(model),
                             '--tau-his', '0', '--decision-threshold', '2.5', '--json')
    assert code == 0, err
    payload = json.loads(out)
    expected = evaluate_lists(trajectories, lists.with_decision_threshold(2.5), (0.0,))[0.0]
    assert payload['decision_threshold'] == 2.5
    assert (payload['n_false_positives'], payload['n_missed']) == (expected.n_false_positives,
                                                                   expected.n_missed)
    assert expected.n_false_positives < from_file[0.0].n_false_positives  # higher: fewer alarms


def test_cli_rejects_unusable_models_and_datasets(fixture_dataset, tmp_path, capsys):
    malformed = tmp_path / 'malformed.json'
    malformed.write_text('{"schema": "fall_predictor.decision_lists", "schema_version": 1, "lists": [')
    wrong = tmp_path / 'wrong.json'
    wrong.write_text(json.dumps({'schema': 'something else'}))
    for model in (malformed, wrong, tmp_path / 'missing.json'):
        for argv in (('rules', str(model)),
                     ('evaluate', '--data', str(fixture_dataset), '--model', str(model), '--tau-his', '0')):
            code, out, err = run_cli(capsys, *argv)
            assert code == 2 and str(model) in err and 'Traceback' not in err, (argv, err)
    lists_model = tmp_path / 'lists.json'
    code, _, err = run_cli(capsys, 'train', '--data', str(fixture_dataset), '--tau-plus', '0',
                           '--out', str(lists_model))
    assert code == 0, err
    code, _, err = run_cli(capsys, 'evaluate', '--data', str(fixture_dataset), '--model',
                           str(lists_model), '--tau-his', '0', '--decision-threshold', '1')
    assert code == 2 and 'decision lists, which have no decision threshold' in err
    code, _, err = run_cli(capsys, 'train', '--data', str(tmp_path), '--tau-plus', '0',
                           '--out', str(tmp_path / 'm.json'))
    assert code == 2 and 'not a dataset directory' in err
    code, _, err = run_cli(capsys, 'train', '--data', str(fixture_dataset), '--tau-plus', '0',
                           '--out', str(tmp_path / 'm.json'), '--param', 'max_depth=-1')
    assert code == 2 and 'max_depth' in err
    with pytest.raises(SystemExit) as exit_info:              # argparse: invalid value
        cli.main(['train', '--data', str(fixture_dataset), '--tau-plus', 'nan', '--out', 'm.json'])
    assert exit_info.value.code == 2
    assert not (tmp_path / 'm.json').exists()


# -- the robot's CoM guard -------------------------------------------------------------------
@pytest.mark.parametrize('robot, guard_m', [('g1', 0.55), ('asimo_like', 0.48)])
def test_a_model_records_the_guard_of_its_datasets_robot(tmp_path, capsys, robot, guard_m):
    """A tiny hand-made dataset of each robot (test/robot_datasets.py): the model file says the
    robot profile's guard (0.55 m for the G1, not the ASIMO-like robot's 0.48 m), and the other
    feature settings are still those the features were computed with."""
    data = write_robot_dataset(tmp_path / robot, robot)
    _, metadata = train_model(data, 0.0)
    assert metadata.feature_settings.guard_com_height_m == guard_m
    assert metadata.feature_settings == dataclasses.replace(FeatureSettings(), guard_com_height_m=guard_m)
    model = tmp_path / 'model.json'
    code, out, err = run_cli(capsys, 'train', '--data', str(data), '--tau-plus', '0',
                             '--out', str(model), '--json')
    assert code == 0, err
    assert json.loads(out)['guard_com_height_m'] == guard_m
    assert json.loads(model.read_text())['features']['guard_com_height_m'] == guard_m
    assert load_model(model)[1].feature_settings.guard_com_height_m == guard_m


def test_trajectories_not_settled_at_their_horizon_are_left_out_with_a_warning(fixture_dataset, monkeypatch):
    import fall_predictor.data.outcomes as outcomes
    from fall_predictor.learning.training import UnsettledTrajectories
    as_recorded = load_dataset(fixture_dataset)
    everything = as_recorded.trajectories
    assert not as_recorded.unsettled                            # the fixture's runs settle
    # With no margin over a zero walking level, every balanced run is "still moving".
    monkeypatch.setattr(outcomes, 'SETTLE_MOMENTUM_FACTOR', 0.0)
    monkeypatch.setattr(outcomes, 'SETTLE_MOMENTUM_FLOOR_MPS', 0.0)
    with pytest.warns(UnsettledTrajectories, match='left out, not settled'):
        report = load_dataset(fixture_dataset)
    balanced = {t.trajectory_id for t in everything if not t.fallen}
    assert balanced and set(report.unsettled) == balanced
    assert [t.trajectory_id for t in report.trajectories] == [t.trajectory_id for t in everything if t.fallen]


# -- several datasets, one model -------------------------------------------------------------
def _with_manifest(data, **changes):
    """``data``'s manifest with its ``robot`` entries (or top-level keys) changed."""
    path = data / 'dataset.json'
    manifest = json.loads(path.read_text())
    for key, value in changes.items():
        if key in manifest['robot']:
            manifest['robot'][key] = value
        else:
            manifest[key] = value
    path.write_text(json.dumps(manifest))
    return data


def test_two_copies_train_one_model_on_twice_the_trajectories(tmp_path):
    """Two datasets are merged into one training set: every trajectory of each, its id prefixed
    with its dataset's name (two ``traj_00000`` stay two runs), the fingerprint that of both in
    order, the robot's mass and guard; the model is the one fitted on all of them."""
    import shutil
    from fall_predictor.data.dataset import robot_total_mass_kg
    from fall_predictor.learning.training import combined_fingerprint, load_training_data, train_on_data
    first = write_robot_dataset(tmp_path / 'session1', 'g1', n_fallen=2, n_balanced=2)
    second = tmp_path / 'session2'
    shutil.copytree(first, second)
    alone = load_dataset(first)
    data = load_training_data([first, second])
    ids = [t.trajectory_id for t in alone.trajectories]
    assert [t.trajectory_id for t in data.report.trajectories] == \
        [f'session1/{i}' for i in ids] + [f'session2/{i}' for i in ids]
    assert [(p.data_dir, p.n_trajectories, p.n_fallen) for p in data.parts] == [(first, 4, 2), (second, 4, 2)]
    assert data.report.fingerprint == combined_fingerprint([alone.fingerprint, alone.fingerprint])
    assert data.report.fingerprint != alone.fingerprint
    assert combined_fingerprint(['a', 'b']) != combined_fingerprint(['b', 'a'])
    learner = make_learner('boosting', {'max_iter': 5})
    lists, metadata = train_on_data(data, 0.0, learner, recommended_tau_his_s=0.03)
    assert lists == fit_strided(data.report.trajectories, 0.0, learner)
    assert metadata.dataset_fingerprint == data.report.fingerprint
    assert metadata.robot_mass_kg == robot_total_mass_kg(first)
    assert metadata.feature_settings.guard_com_height_m == 0.55
    # Directories of the same name: numbered by position.
    third = tmp_path / 'other' / 'session1'
    shutil.copytree(first, third)
    assert {t.trajectory_id.split('/')[0] for t in load_training_data([first, third]).report.trajectories} \
        == {'1-session1', '2-session1'}


def test_merged_datasets_keep_each_ones_refused_samples_and_settings(tmp_path):
    """The merged report counts every dataset's refused samples (keyed per dataset, not merged
    by trajectory id) and refuses datasets whose features were computed otherwise."""
    from fall_predictor.data.dataset import DatasetError, RefusedSamples
    from fall_predictor.learning.training import DatasetPart, _merged_report
    report = load_dataset(write_robot_dataset(tmp_path / 'g1', 'g1'))
    holes = dataclasses.replace(report, refused={'traj_00000': RefusedSamples(3, 1)},
                                errors={'traj_00009': 'truncated'})
    parts = [DatasetPart(tmp_path / name, name, holes, 0.55, 33.0) for name in ('a', 'b')]
    merged = _merged_report(parts)
    assert merged.refused_total.total == 8
    assert set(merged.refused) == {'a/traj_00000', 'b/traj_00000'}
    assert set(merged.errors) == {'a/traj_00009', 'b/traj_00009'}
    other = dataclasses.replace(report, settings=FeatureSettings(rate_window_s=0.02))
    parts[1] = dataclasses.replace(parts[1], report=other)
    with pytest.raises(DatasetError, match=r'different settings.*rate_window_s=0\.01.*rate_window_s=0\.02'):
        _merged_report(parts)


def test_datasets_that_cannot_share_a_model_are_refused_in_words(tmp_path, capsys):
    """Another robot's guard, another robot's mass (more than 5 % apart), another state, the
    same dataset twice: refused, naming the datasets and their values; masses within 5 %:
    their mean in the model."""
    import shutil
    g1 = write_robot_dataset(tmp_path / 'g1', 'g1')
    asimo = write_robot_dataset(tmp_path / 'asimo', 'asimo_like')
    model = tmp_path / 'model.json'

    def train(*data, state='estimated'):
        argv = ['train', '--tau-plus', '0', '--tau-his', '0.03', '--out', str(model), '--json',
                '--state', state]
        for d in data:
            argv += ['--data', str(d)]
        return run_cli(capsys, *argv)

    code, _, err = train(g1, asimo)
    assert code == 2 and 'different CoM guards' in err and f'{g1}: 0.55 m' in err \
        and f'{asimo}: 0.48 m' in err, err
    heavier = _with_manifest(shutil.copytree(g1, tmp_path / 'heavier'), total_mass_kg=40.0)
    code, _, err = train(g1, heavier)
    mass = json.loads((g1 / 'dataset.json').read_text())['robot']['total_mass_kg']
    assert code == 2 and f'{mass:g} kg ({g1})' in err and f'40 kg ({heavier})' in err \
        and 'within 5 %' in err, err
    near = _with_manifest(shutil.copytree(g1, tmp_path / 'near'), total_mass_kg=mass * 1.04)
    code, out, err = train(g1, near)
    assert code == 0, err
    assert load_model(model)[1].robot_mass_kg == pytest.approx(mass * 1.02)
    assert json.loads(out)['robot_mass_kg'] == pytest.approx(mass * 1.02)
    # A dataset with sensor topics gives the estimated state, one without the true state.
    sensed = _with_manifest(shutil.copytree(g1, tmp_path / 'sensed'), sensors={'noise_scale': 1.0})
    code, _, err = train(g1, sensed)
    assert code == 2 and 'different states' in err and f'{g1}: true' in err \
        and f'{sensed}: estimated' in err, err
    code, out, err = train(g1, sensed, state='true')
    assert code == 0 and json.loads(out)['state'] == 'true', err
    code, _, err = train(g1, g1)
    assert code == 2 and 'the same dataset given twice' in err, err


class _FrozenClock:
    """``model_file``'s clock at a fixed time, so that two model files can be compared byte for byte."""

    @staticmethod
    def now(tz=None):
        import datetime
        return datetime.datetime(2024, 1, 2, 3, 4, 5, tzinfo=tz)


def test_one_data_trains_the_single_dataset_paths_model(fixture_dataset, tmp_path, capsys, monkeypatch):
    """``train --data A`` writes, byte for byte, the model of the single-dataset path
    (``load_dataset`` + ``train_on_report``, the dataset's own guard and mass)."""
    import fall_predictor.monitor.model_file as model_file
    from fall_predictor.learning.training import train_on_report
    monkeypatch.setattr(model_file, 'datetime', _FrozenClock)
    model = tmp_path / 'model.json'
    code, out, err = run_cli(capsys, 'train', '--data', str(fixture_dataset), '--tau-plus', '-0.25',
                             '--tau-his', '0.06', '--out', str(model), '--json')
    assert code == 0, err
    report = load_dataset(fixture_dataset, state='estimated')
    lists, metadata = train_on_report(report, fixture_dataset, -0.25, make_learner('tree'),
                                      recommended_tau_his_s=0.06)
    assert any(lists.depths)
    expected = tmp_path / 'expected.json'
    model_file.save_model(expected, lists, metadata)
    assert model.read_bytes() == expected.read_bytes()
    payload = json.loads(out)
    assert payload['datasets'] == [{
        'data': str(fixture_dataset), 'trajectory_id_prefix': None,
        'n_trajectories': len(report.trajectories), 'n_fallen': sum(t.fallen for t in report.trajectories),
        'unreadable': 0, 'unsettled': 0, 'dataset_fingerprint': report.fingerprint, 'state': report.state,
        'guard_com_height_m': metadata.feature_settings.guard_com_height_m,
        'robot_mass_kg': metadata.robot_mass_kg}]
    assert payload['dataset_fingerprint'] == report.fingerprint
