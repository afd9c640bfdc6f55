"""Experiments (fall_predictor.experiments) and their CLI subcommands: train, rules, evaluate,
sweep. Metric-level tests use synthetic trajectories; pipeline tests use a small generated
dataset (see :func:`fixture_dataset`)."""
import json
import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from fall_predictor import cli
from fall_predictor.decision_list import Condition, DecisionList, PerModeDecisionLists, Rule
from fall_predictor.experiments import (SweepConfig, SweepPoint, aggregate_folds,
                                        capture_point_distances_cached, cross_validate_grid,
                                        cross_validated_evaluation, fit_strided, load_dataset,
                                        make_learner, pareto_mean_lead, rules_summary,
                                        select_paper_analogues, subsample, train_model)
from fall_predictor.learning import training_set
from fall_predictor.metrics import evaluate_lists
from fall_predictor.model_file import load_model
from fall_predictor.records import BALANCED, FALLING, N_CONTACT_MODES

from synthetic_trajectories import (FALLING_MODE, LIN_MOM_Y, T_FALLEN_S, T_HEIGHT_DROP_S,
                                    make_dataset)

@pytest.fixture(scope='session')
def fixture_dataset(small_dataset, tmp_path_factory) -> Path:
    """A private copy of the session's generated dataset (caches are written into it)."""
    copy = tmp_path_factory.mktemp('data') / 'dataset'
    shutil.copytree(small_dataset, copy)    # copy2 keeps modification times, so cache entries stay valid
    return copy


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


# -- cross-validation and aggregation --------------------------------------------------------
def test_cross_validated_evaluation_has_the_known_fpr_and_lead():
    trajectories = make_dataset(6, 6, seed=4)
    points = cross_validated_evaluation(trajectories, make_learner('tree'), 0.0, (0.003, 0.05),
                                        folds=3, seed=0, sample_stride=10)
    lead = T_FALLEN_S - T_HEIGHT_DROP_S
    for point, tau_his in zip(points, (0.003, 0.05)):
        assert point.tau_his_s == tau_his and point.tau_plus_s == 0.0
        assert point.fpr == 0.0 and point.n_false_positives == 0 and point.n_balanced == 6
        assert point.n_missed == 0 and point.n_fallen == 6
        assert point.tau_lead_s == pytest.approx(lead - tau_his, abs=0.02)
        assert point.oracle_lead_s == pytest.approx(T_FALLEN_S - 0.5)
        assert point.n_train == 8.0 and len(point.per_fold) == 3
        assert point.mean_rule_size > 0


def test_cross_validation_in_parallel_processes_matches_one_process():
    trajectories = make_dataset(4, 4, seed=5)
    kwargs = dict(tau_plus_values=(-0.5, 0.0), tau_his_values=(0.0, 0.01), folds=2, seed=1,
                  sample_stride=20, train_sizes=(None, 3))
    serial = cross_validate_grid(trajectories, make_learner('tree'), jobs=1, **kwargs)
    parallel = cross_validate_grid(trajectories, make_learner('tree'), jobs=2, **kwargs)
    assert len(serial) == 2 * 2 * 2
    assert [(f.fold, f.tau_plus_s, f.train_size, f.n_train, f.rule_sizes, f.results)
            for f in serial] == [(f.fold, f.tau_plus_s, f.train_size, f.n_train, f.rule_sizes,
                                  f.results) for f in parallel]
    assert {f.n_train for f in serial if f.train_size == 3} == {3}


def test_aggregate_folds_means_rates_and_sums_counts():
    trajectories = make_dataset(4, 4, seed=6)
    fits = cross_validate_grid(trajectories, make_learner('tree'), (0.0,), (0.0,), folds=2,
                               sample_stride=20)
    point = aggregate_folds(fits, 0.0)
    assert point.n_fallen == 4 and point.n_balanced == 4
    assert point.fpr == pytest.approx(np.mean([f.results[0.0].fpr for f in fits]))
    assert point.mean_rule_size == pytest.approx(np.mean([f.mean_rule_size for f in fits]))
    with pytest.raises(ValueError, match='one tau_plus'):
        aggregate_folds(fits + cross_validate_grid(trajectories, make_learner('tree'), (0.3,),
                                                   (0.0,), folds=2, sample_stride=20), 0.0)


def point(fpr: float, lead: float, tau_plus: float = 0.0, tau_his: float = 0.0) -> SweepPoint:
    return SweepPoint(tau_plus, tau_his, 9.0, fpr, 0.0, lead, 0.0, lead / 2.0, 2.0, 1.0, 1.0,
                      10, 10, 0, 0, 0, 0, ())


def test_pareto_mean_lead_is_the_area_under_the_front():
    points = [point(0.0, 0.2), point(0.25, 0.6), point(0.3, 0.5), point(0.6, 0.9)]
    # best lead 0.2 on [0, 0.25), 0.6 on [0.25, 0.5]: (0.05 + 0.15) / 0.5
    assert pareto_mean_lead(points) == pytest.approx(0.4)
    assert pareto_mean_lead([point(0.1, 1.0)], max_fpr=0.5) == pytest.approx(0.8)
    assert pareto_mean_lead([]) == 0.0
    with pytest.raises(ValueError):
        pareto_mean_lead(points, max_fpr=0.0)


def test_paper_analogues_take_the_longest_lead_within_the_papers_fpr():
    points = [point(0.0, 0.3, 0.5), point(0.04, 0.7, 0.0), point(0.3, 0.9, -0.5),
              point(0.8, 1.2, -1.5), point(0.35, 0.8, -0.25)]
    chosen = {paper.name: p for paper, p in select_paper_analogues(points)}
    assert chosen['FP-L1'].tau_plus_s == -0.5        # FPR 0.3 <= 0.46, longest lead
    assert chosen['FP-L2'].tau_plus_s == 0.0         # FPR 0.04 <= 0.06
    assert chosen['FP-L3'].tau_plus_s == 0.5         # only FPR 0 <= 0.005
    high_fpr_only = [point(0.2, 0.5)]
    assert select_paper_analogues(high_fpr_only)[2][1].fpr == 0.2   # none qualifies: lowest FPR


def test_sweep_config_validates():
    with pytest.raises(ValueError, match='folds'):
        SweepConfig(folds=1)
    with pytest.raises(ValueError, match='tau_his'):
        SweepConfig(tau_his_values_s=(0.0, -0.01))
    with pytest.raises(ValueError, match='tau_plus'):
        SweepConfig(tau_plus_values_s=(math.nan,))
    with pytest.raises(ValueError, match='learning-curve'):
        SweepConfig(learning_curve_sizes=(1,))
    with pytest.raises(ValueError, match='unknown hyper-parameter'):
        SweepConfig(learner_params={'depth': 3})
    quick = SweepConfig.quick(folds=3)
    assert quick.folds == 3 and len(quick.tau_plus_values_s) < len(SweepConfig().tau_plus_values_s)


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
    assert any(lists.depths), 'some contact mode should have learned a falling rule'
    with pytest.raises(ValueError, match='tau_plus'):
        train_model(fixture_dataset, math.inf)


def test_capture_point_distances_are_cached_per_bag(fixture_dataset):
    trajectories = load_dataset(fixture_dataset).trajectories[:2]
    first = capture_point_distances_cached(fixture_dataset, trajectories)
    cache = fixture_dataset / 'cache' / f'cp_{trajectories[0].trajectory_id}.npz'
    assert cache.exists()
    stamp = cache.stat().st_mtime_ns
    second = capture_point_distances_cached(fixture_dataset, trajectories)
    assert cache.stat().st_mtime_ns == stamp                   # read from the cache
    for a, b, traj in zip(first, second, trajectories):
        assert a.shape == traj.t.shape and np.array_equal(a, b)


def test_cli_train_rules_evaluate(fixture_dataset, tmp_path, capsys):
    model = tmp_path / 'model.json'
    code, out, err = run_cli(capsys, 'train', '--data', str(fixture_dataset), '--tau-plus', '-0.25',
                             '--out', str(model), '--tau-his-recommended', '0.06', '--json')
    assert code == 0, err
    trained = json.loads(out)
    lists, metadata = load_model(model)
    assert trained['mean_rule_size'] == pytest.approx(lists.mean_rule_size)
    assert trained['sample_stride'] == 10 and metadata.recommended_tau_his_s == 0.06

    code, out, err = run_cli(capsys, 'rules', str(model), '--json')
    assert code == 0, err
    rules = json.loads(out)
    assert [m['rule_size'] for m in rules['modes']] == list(lists.rule_sizes)
    code, out, _ = run_cli(capsys, 'rules', str(model))
    assert code == 0 and 'if footContactMode = OUTSIDE then' in out and 'mean rule size' in out

    code, out, err = run_cli(capsys, 'evaluate', '--data', str(fixture_dataset), '--model', str(model),
                             '--json')
    assert code == 0, err
    evaluation = json.loads(out)
    expected = evaluate_lists(load_dataset(fixture_dataset).trajectories, lists, (0.06,))[0.06]
    assert evaluation['tau_his_s'] == 0.06 and evaluation['fpr'] == pytest.approx(expected.fpr)
    assert evaluation['tau_lead_s'] == pytest.approx(expected.tau_lead_s)
    assert evaluation['trained_on_this_dataset'] is True
    for key in ('n_missed', 'n_pre_push_alarms', 'oracle_lead_s', 'lead_fraction', 'mean_rule_size'):
        assert key in evaluation


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


def test_tiny_sweep_writes_json_table_and_figures(fixture_dataset, tmp_path, capsys):
    out_dir = tmp_path / 'sweep'
    code, out, err = run_cli(capsys, 'sweep', '--data', str(fixture_dataset), '--out', str(out_dir),
                             '--folds', '2', '--tau-plus=-0.5,0', '--tau-his', '0,0.06',
                             '--learning-curve', '3', '--quick', '--json')
    assert code == 0, err
    summary = json.loads(out)
    assert len(summary['selected']) == 3
    document = json.loads((out_dir / 'sweep.json').read_text())
    assert document['command'].startswith('fall-predictor sweep')
    assert document['settings']['folds'] == 2 and document['settings']['sample_stride'] == 10
    assert {(p['tau_plus_s'], p['tau_his_s']) for p in document['points']} == \
        {(-0.5, 0.0), (-0.5, 0.06), (0.0, 0.0), (0.0, 0.06)}
    for p in document['points']:
        assert len(p['per_fold']) == 2
        for key in ('fpr', 'tau_lead_s', 'n_missed', 'n_pre_push_alarms', 'oracle_lead_s',
                    'lead_fraction', 'mean_rule_size', 'pareto'):
            assert key in p
    # The 8-trajectory dataset split in 2 folds trains on 4: the curve's last point is the full fold.
    assert [p['n_train'] for p in document['learning_curve']] == [3.0, 4.0]
    assert len(document["trainings"]) == 2 * 2 + 2 * 2    # sweep + the curve (tau_plus -0.25 is not swept)
    assert set(document['baselines']) == {'com_height', 'momentum', 'capture_point'}
    assert all(document['baselines'].values())
    assert document["timing"]["n_fits"] == 8
    table = (out_dir / 'table.md').read_text()
    assert 'Table 2 analogue' in table and 'FP-L2 (paper)' in table
    for name in ('fig10_tradeoff.png', 'fig11_parameters.png', 'fig11_learning_curve.png'):
        assert (out_dir / name).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_sweep_rejects_bad_settings(fixture_dataset, tmp_path, capsys):
    code, _, err = run_cli(capsys, 'sweep', '--data', str(fixture_dataset), '--out', str(tmp_path),
                           '--learning-curve', '1')
    assert code == 2 and 'learning-curve' in err
    code, _, err = run_cli(capsys, 'sweep', '--data', str(fixture_dataset), '--out', str(tmp_path),
                           '--folds', '13')
    assert code == 2 and 'fewer than 13 folds' in err
