"""The cross-validated sweep (fall_predictor.learning.sweep): its settings, and the CLI
subcommand ``sweep`` on a small generated dataset."""
import json
import math
import shutil

import pytest

from fall_predictor import cli
from fall_predictor.learning.sweep import SweepConfig

from learning_fixtures import fixture_dataset  # noqa: F401  (a pytest fixture)
from robot_datasets import G1_GUARD_LEAD_S, write_robot_dataset


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


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
    with pytest.raises(ValueError, match='sample_stride'):
        SweepConfig(sample_stride=0)
    quick = SweepConfig.quick(folds=3)
    assert quick.folds == 3 and len(quick.tau_plus_values_s) < len(SweepConfig().tau_plus_values_s)


def test_sweep_config_as_json_names_the_learner_and_its_parameters():
    settings = SweepConfig.quick(learner_params={'max_depth': 3}).as_json()
    json.dumps(settings, allow_nan=False)            # the infinite momentum threshold is null
    assert settings['learner']['class'] == 'TreeListLearner'
    assert settings['learner']['params']['max_depth'] == 3
    assert settings['baseline_grids']['momentum_sagittal'][-1] is None
    assert settings['balanced_weight'] == 4.0 and settings['falling_weight'] == 1.0


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
    # method §11: nested operating points (chosen on the other fold) with intervals
    nested = document['nested_selection']
    for entry in nested['nested']:
        outer = entry['outer']
        assert len(entry['chosen_per_fold']) == 2
        assert outer['n_balanced'] == document['dataset']['n_balanced']
        if outer['fpr'] is not None:
            assert outer['fpr_ci95'][0] <= outer['fpr'] <= outer['fpr_ci95'][1]
    assert nested['paper_settings_fixed']['FP-L1'] == {'setting': [-0.3, 0.016], 'in_grid': False}
    assert set(document['baselines_nested']) == {'com_height', 'momentum', 'capture_point'}
    for entries in document['baselines_nested'].values():
        assert {c['tau_his_s'] for e in entries for c in e['chosen_per_fold']} <= {0.0, 0.06}
    table = (out_dir / 'table.md').read_text()
    assert 'Table 2 analogue' in table and 'FP-L2 (paper)' in table
    assert 'best lead at FPR ≤ 0.06 (nested)' in table and 'FP-L2 settings (fixed)' in table
    for name in ('fig10_tradeoff.png', 'fig11_parameters.png', 'fig11_learning_curve.png',
                 'pareto_intervals.png'):
        assert (out_dir / name).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert sorted(p.name for p in out_dir.iterdir()) == sorted(     # no temporary file left
        ['sweep.json', 'table.md', 'fig10_tradeoff.png', 'fig11_parameters.png',
         'fig11_learning_curve.png', 'pareto_intervals.png'])


def test_sweep_rejects_bad_settings(fixture_dataset, tmp_path, capsys):
    code, _, err = run_cli(capsys, 'sweep', '--data', str(fixture_dataset), '--out', str(tmp_path),
                           '--learning-curve', '1')
    assert code == 2 and 'learning-curve' in err
    code, _, err = run_cli(capsys, 'sweep', '--data', str(fixture_dataset), '--out', str(tmp_path),
                           '--folds', '13')
    assert code == 2 and 'fewer than 13 folds' in err


def test_sweep_evaluates_the_chosen_predictors_on_a_held_out_dataset(fixture_dataset, tmp_path,
                                                                     capsys):
    # The "test dataset": a copy holding only the first 5 of the 8 trajectories (another
    # fingerprint). Refused when it is the sweep dataset itself.
    held_out = tmp_path / 'held_out'
    shutil.copytree(fixture_dataset, held_out)
    for row in sorted((held_out / 'index').glob('traj_*.json'))[5:]:
        row.unlink()
    out_dir = tmp_path / 'sweep'
    common = ('sweep', '--data', str(fixture_dataset), '--out', str(out_dir), '--folds', '2',
              '--tau-plus=-0.25,0', '--tau-his', '0,0.06', '--no-learning-curve',
              '--no-capture-point', '--quick', '--json')
    code, _, err = run_cli(capsys, *common, '--test-data', str(fixture_dataset))
    assert code == 2 and 'sweep dataset itself' in err
    code, out, err = run_cli(capsys, *common, '--test-data', str(held_out))
    assert code == 0, err
    document = json.loads((out_dir / 'test_set.json').read_text())
    assert json.loads(out)['test_set'] == document
    assert document['n_test_trajectories'] == 5
    by_name = {p['name']: p for p in document['predictors']}
    assert set(by_name) >= {'FP-L2 settings (fixed)', 'best lead at FPR <= 0.06'}
    # Every predictor is evaluated on the 5 held-out trajectories, whatever it predicts: their
    # outcomes and oracle lead (mean t_fallen - t_push) from the kept index files.
    rows = [json.loads(f.read_text()) for f in sorted((held_out / 'index').glob('traj_*.json'))]
    fallen = [r for r in rows if r['fallen']]
    assert len(rows) == 5 and document['n_test_fallen'] == len(fallen) >= 1
    oracle = sum(r['t_fallen'] - r['t_push'] for r in fallen) / len(fallen)
    for p in document['predictors']:
        assert (p['n_balanced'], p['n_fallen']) == (5 - len(fallen), len(fallen)), p['name']
        assert p['oracle_lead_s'] == pytest.approx(oracle, abs=1e-9), p['name']
        assert 0.0 <= p['tau_lead_s'] <= oracle + 1e-9
    # FP-L2 at the paper's settings: trained at tau_plus -0.25 s, run at tau_his 0.06 s.
    fp_l2 = by_name['FP-L2 settings (fixed)']
    assert (fp_l2['tau_plus_s'], fp_l2['tau_his_s']) == (-0.25, 0.06)
    assert fp_l2['fpr'] == fp_l2['n_false_positives'] / (5 - len(fallen))


def test_the_sweep_and_its_test_set_use_the_dataset_robots_guard(tmp_path):
    """On the tiny G1 dataset (test/robot_datasets.py) the guard alone decides: with the G1's
    0.55 m every test fold's guard-alone lead is 0.049 s and every CoM-height threshold alarms on
    the squats; the ASIMO-like robot's 0.48 m, given explicitly, is kept and predicts nothing."""
    from fall_predictor.learning.heldout import evaluate_on_test_set
    from fall_predictor.learning.report import sweep_json
    from fall_predictor.learning.sweep import compute_sweep

    data = write_robot_dataset(tmp_path / 'g1', 'g1')
    settings = dict(folds=2, tau_plus_values_s=(-0.25, 0.0), tau_his_values_s=(0.0,),
                    learning_curve_sizes=())
    result = compute_sweep(data, SweepConfig.quick(**settings))
    assert result.config.guard_com_height_m == 0.55
    assert sweep_json(result)['settings']['guard_com_height_m'] == 0.55
    for point in result.points:
        assert [r.tau_lead_guard_only_s for r in point.per_fold] == \
            pytest.approx([G1_GUARD_LEAD_S] * 2, abs=1e-9)
    assert all(p.fpr == 1.0 for p in result.baselines.com_height)
    assert all(entry['outer']['fpr'] == 1.0 for entry in result.baselines_nested['com_height'])

    test_set = evaluate_on_test_set(result, sweep_json(result)['nested_selection'],
                                    write_robot_dataset(tmp_path / 'g1_test', 'g1', 1, 1))
    assert test_set['guard_com_height_m'] == 0.55 and test_set['predictors']
    for predictor in test_set['predictors']:
        assert predictor['tau_lead_guard_only_s'] == pytest.approx(G1_GUARD_LEAD_S, abs=1e-9)
        assert predictor['n_false_positives'] == 1 and predictor['n_missed'] == 0

    asimo_guard = compute_sweep(data, SweepConfig.quick(guard_com_height_m=0.48, **settings))
    assert asimo_guard.config.guard_com_height_m == 0.48
    for point in asimo_guard.points:
        assert [r.tau_lead_guard_only_s for r in point.per_fold] == [0.0, 0.0]
    assert asimo_guard.baselines.com_height[0].fpr == 0.0       # CoM below 0.40 m: never here
    with pytest.raises(ValueError, match='guard_com_height_m'):
        SweepConfig(guard_com_height_m=-0.1)


def test_the_mirror_setting_is_validated_and_recorded():
    assert SweepConfig(mirror=True).as_json()['mirror'] is True
    assert SweepConfig().as_json()['mirror'] is False
    with pytest.raises(ValueError, match='mirror'):
        SweepConfig(mirror='yes')


def test_a_sweep_without_nested_baselines_has_the_same_learned_points(fixture_dataset):
    """--no-nested-baselines drops only the baselines' nested selection: every learned point
    and the hindsight baseline curves equal the full sweep's."""
    from fall_predictor.learning.sweep import compute_sweep

    settings = dict(folds=2, tau_plus_values_s=(-0.5, 0.0), tau_his_values_s=(0.0, 0.06),
                    learning_curve_sizes=())
    full = compute_sweep(fixture_dataset, SweepConfig.quick(**settings))
    learned = compute_sweep(fixture_dataset, SweepConfig.quick(nested_baselines=False, **settings))
    assert full.baselines_nested and learned.baselines_nested is None
    assert learned.points == full.points and learned.baselines == full.baselines
    assert learned.config.as_json()['nested_baselines'] is False
