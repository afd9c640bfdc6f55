"""``train`` chooses the history window ``tau_his`` on its training data and stores it in the
model (fall_predictor/learning/window_choice.py); ``evaluate`` then runs the model with it.

Known answers come from the hand-made G1 dataset of ``robot_datasets`` trained with a
``tau_plus`` so late (10 s after the CoM starts to drop) that no state is labelled falling: the
lists stay empty and the G1's CoM guard (0.55 m) alone decides. From the geometry there: a fall
is below the guard from 0.251 s and down at 0.300 s (lead 0.049 s - tau_his, a miss from a
window of 0.049 s on); a squat is below it from 0.251 to 0.309 s, a run of 0.058 s, so every
window up to 0.044 s of the grid alarms on it (FPR 1) and none from 0.06 s does (FPR 0).
"""
import json

import pytest

from fall_predictor import cli
from fall_predictor.data.dataset import dataset_guard_com_height_m, read_index
from fall_predictor.learning.crossval import cross_validate_grid
from fall_predictor.learning.nested import nested_operating_point
from fall_predictor.learning.run_groups import disturbances, fold_groups
from fall_predictor.learning.training import load_dataset, make_learner
from fall_predictor.learning.window_choice import WindowSearch, choose_tau_his, train_choosing_window
from fall_predictor.monitor.model_file import load_model

from learning_fixtures import fixture_dataset  # noqa: F401  (a pytest fixture)
from robot_datasets import G1_GUARD_LEAD_S, write_robot_dataset

#: The sweep's choice: folds stratified by outcome, the budget checked on the pooled FPR.
SWEEPS_RULE = {'fpr_rule': 'point', 'folds_by': 'outcome'}

#: Falling states from t_height_drop + 10 s: none (module docs).
NO_FALLING_LABELS_TAU_PLUS_S = 10.0


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_the_guards_window_from_geometry(tmp_path):
    data = write_robot_dataset(tmp_path / 'g1', 'g1')
    trained = train_choosing_window(data, NO_FALLING_LABELS_TAU_PLUS_S)
    assert not any(trained.lists.depths)                          # the guard alone decides
    window = trained.window
    assert window.folds == 4                                      # one per trajectory
    for tau, figures in window.per_window.items():
        assert figures.fpr == (1.0 if tau <= 0.044 else 0.0), tau
        expected_lead = G1_GUARD_LEAD_S - tau if tau < G1_GUARD_LEAD_S else 0.0     # else a miss
        assert figures.tau_lead_s == pytest.approx(expected_lead, abs=1e-9), tau
    # FPR <= 0.06: only windows of 0.06 s and longer, all without lead: the smallest of them.
    # 0 false alarms in 2 runs do not show the budget holds (the 95 % upper bound is 0.58):
    # chosen as the lowest bound, not within the budget; on the point estimate, within it
    assert window.tau_his_s == 0.06 and not window.within_budget
    assert window.to_json()['chosen_fpr_bound'] == pytest.approx(1.6449 ** 2 / (2 + 1.6449 ** 2), abs=1e-4)
    assert trained.metadata.recommended_tau_his_s == 0.06
    point = train_choosing_window(data, NO_FALLING_LABELS_TAU_PLUS_S,
                                  search=WindowSearch(fpr_rule='point')).window
    assert point.tau_his_s == 0.06 and point.within_budget
    # any FPR: the longest lead, no window
    assert train_choosing_window(data, NO_FALLING_LABELS_TAU_PLUS_S,
                                 search=WindowSearch(max_fpr=1.0)).window.tau_his_s == 0.0
    # a window given is stored as given, nothing chosen
    given = train_choosing_window(data, NO_FALLING_LABELS_TAU_PLUS_S, tau_his_s=0.03)
    assert given.window is None and given.metadata.recommended_tau_his_s == 0.03


def test_the_window_is_the_sweeps_choice_over_its_folds(fixture_dataset):
    """The same cross-validation through the sweep's own nested selection
    (:func:`~fall_predictor.learning.nested.nested_operating_point`): the window ``train``
    chooses is the one the sweep selects over all its folds, at every budget."""
    trajectories = load_dataset(fixture_dataset).trajectories
    learner = make_learner('tree')
    guard = dataset_guard_com_height_m(fixture_dataset)
    fits = cross_validate_grid(trajectories, learner, (-0.25,), WindowSearch().tau_his_values_s,
                               folds=8, seed=0, guard_com_height_m=guard)
    for budget in (0.0, 0.06, 0.5):
        chosen = choose_tau_his(trajectories, learner, -0.25,
                                WindowSearch(max_fpr=budget, **SWEEPS_RULE), guard_com_height_m=guard)
        assert chosen.folds == 8
        assert (-0.25, chosen.tau_his_s) == nested_operating_point(fits, budget).selected_in_hindsight


def test_cli_train_stores_the_window_and_evaluate_uses_it(tmp_path, capsys):
    data = write_robot_dataset(tmp_path / 'g1', 'g1')
    model = tmp_path / 'model.json'
    code, out, err = run_cli(capsys, 'train', '--data', str(data), '--tau-plus=10', '--out', str(model),
                             '--json')
    assert code == 0, err
    trained = json.loads(out)
    assert trained['recommended_tau_his_s'] == 0.06 and trained['tau_his_chosen']['max_fpr'] == 0.06
    assert trained['tau_his_chosen']['chosen']['fpr'] == 0.0
    assert load_model(model)[1].recommended_tau_his_s == 0.06
    code, out, err = run_cli(capsys, 'train', '--data', str(data), '--tau-plus=10', '--out', str(model))
    assert code == 0 and 'tau_his 0.060 s chosen by 4-fold cross-validation' in out, err
    # evaluate runs the model with its window: no false alarm on the squats (all falls missed)
    code, out, err = run_cli(capsys, 'evaluate', '--data', str(data), '--model', str(model), '--json')
    assert code == 0, err
    evaluation = json.loads(out)
    assert evaluation['tau_his_s'] == 0.06
    assert (evaluation['n_false_positives'], evaluation['n_missed']) == (0, 2)
    # --max-fpr moves the choice; --tau-his fixes the window
    code, out, err = run_cli(capsys, 'train', '--data', str(data), '--tau-plus=10', '--max-fpr', '1',
                             '--out', str(model), '--json')
    assert code == 0 and json.loads(out)['recommended_tau_his_s'] == 0.0, err
    # --tau-his-grid: the choice among the given windows only (the smallest at that budget)
    code, out, err = run_cli(capsys, 'train', '--data', str(data), '--tau-plus=10', '--max-fpr', '1',
                             '--tau-his-grid', '0.2,0.03', '--out', str(model), '--json')
    assert code == 0, err
    chosen = json.loads(out)['tau_his_chosen']
    assert [w['tau_his_s'] for w in chosen['per_window']] == [0.03, 0.2]
    assert json.loads(out)['recommended_tau_his_s'] == 0.03 == load_model(model)[1].recommended_tau_his_s
    with pytest.raises(SystemExit) as refused:                 # argparse's usage error
        cli.main(['train', '--data', str(data), '--tau-plus=10', '--tau-his-grid=0.1,-0.05',
                  '--out', str(model)])
    assert refused.value.code == 2 and "'-0.05' must be >= 0" in capsys.readouterr().err
    code, out, err = run_cli(capsys, 'train', '--data', str(data), '--tau-plus=10', '--tau-his', '0.03',
                             '--out', str(model), '--json')
    assert code == 0, err
    assert json.loads(out)['recommended_tau_his_s'] == 0.03 and json.loads(out)['tau_his_chosen'] is None
    assert load_model(model)[1].recommended_tau_his_s == 0.03
    code, _, err = run_cli(capsys, 'train', '--data', str(data), '--tau-plus=10', '--max-fpr', '2',
                           '--out', str(model))
    assert code == 2 and 'max_fpr' in err


def test_too_few_falls_to_choose_a_window_say_so(tmp_path, capsys):
    """One fall: the fold holding it would train on none. The model is written without a
    window, the output says why, and evaluate asks for one as before."""
    data = write_robot_dataset(tmp_path / 'g1', 'g1', n_fallen=1, n_balanced=2)
    model = tmp_path / 'model.json'
    code, out, err = run_cli(capsys, 'train', '--data', str(data), '--tau-plus=10', '--out', str(model))
    assert code == 0, err
    assert 'no tau_his stored: tau_his cannot be chosen by cross-validation on 1 fallen' in out
    assert load_model(model)[1].recommended_tau_his_s is None
    code, _, err = run_cli(capsys, 'evaluate', '--data', str(data), '--model', str(model))
    assert code == 2 and 'recommends no tau_his' in err


def test_boosted_trees_choose_their_threshold_with_the_window(fixture_dataset):
    """With decision thresholds, each fold's model is scored once: its figures at threshold d are
    those of the same cross-validation of a learner whose own threshold is d (an independent
    computation, one cross-validation per threshold), and the pair chosen is the best of them by
    the rule; the model trained carries the chosen threshold."""
    trajectories = load_dataset(fixture_dataset).trajectories
    guard = dataset_guard_com_height_m(fixture_dataset)
    thresholds = (-2.0, 2.0)
    search = WindowSearch(max_fpr=0.2, folds=3, decision_thresholds=thresholds, **SWEEPS_RULE)
    learner = make_learner('boosting', {'max_iter': 5})
    chosen = choose_tau_his(trajectories, learner, -0.25, search, guard_com_height_m=guard)
    for d in thresholds:
        own = choose_tau_his(trajectories, make_learner('boosting', {'max_iter': 5,
                                                                      'decision_threshold': d}),
                             -0.25, WindowSearch(max_fpr=0.2, folds=3, **SWEEPS_RULE),
                             guard_com_height_m=guard)
        for tau, figures in own.per_window.items():
            assert chosen.per_setting[d, tau].fpr == figures.fpr, (d, tau)
            assert chosen.per_setting[d, tau].tau_lead_s == pytest.approx(figures.tau_lead_s), (d, tau)
    best = max((s for s, p in chosen.per_setting.items() if p.fpr <= 0.2),
               key=lambda s: (chosen.per_setting[s].tau_lead_s, -s[0], -s[1]))
    assert (chosen.decision_threshold, chosen.tau_his_s) == best
    trained = train_choosing_window(fixture_dataset, -0.25, 'boosting', {'max_iter': 5},
                                    search=search)
    assert trained.lists.decision_threshold == chosen.decision_threshold
    # The model file's training settings name the threshold it runs with, not the learner's default.
    assert trained.metadata.learner_params['decision_threshold'] == chosen.decision_threshold
    assert trained.metadata.recommended_tau_his_s == chosen.tau_his_s
    with pytest.raises(ValueError, match='boosted trees only'):
        train_choosing_window(fixture_dataset, -0.25, 'tree', search=search)


# -- several datasets ------------------------------------------------------------------------
def test_several_datasets_choose_the_window_over_all_their_runs(tmp_path):
    """Two copies of the G1 dataset: 8 runs, not 4 (the copies' ``traj_00000`` are two runs):
    one fold per trajectory, the pooled figures over 4 falls and 4 squats, the geometry's
    window; the model says where its trajectories came from."""
    import shutil
    first = write_robot_dataset(tmp_path / 'policy', 'g1')
    second = tmp_path / 'balance'
    shutil.copytree(first, second)
    trained = train_choosing_window([first, second], NO_FALLING_LABELS_TAU_PLUS_S)
    ids = [t.trajectory_id for t in trained.report.trajectories]
    assert len(ids) == len(set(ids)) == 8
    window = trained.window
    assert window.folds == 8
    assert {(f.n_fallen, f.n_balanced) for f in window.per_window.values()} == {(4, 4)}
    assert window.tau_his_s == 0.06 and trained.metadata.recommended_tau_his_s == 0.06
    assert [(p.data_dir, p.prefix, p.n_trajectories) for p in trained.datasets] == \
        [(first, 'policy', 4), (second, 'balance', 4)]


def test_cli_train_names_every_dataset_and_its_trajectories(tmp_path, capsys):
    first = write_robot_dataset(tmp_path / 'policy', 'g1')
    second = write_robot_dataset(tmp_path / 'balance', 'g1', n_fallen=3, n_balanced=1)
    model = tmp_path / 'model.json'
    argv = ['train', '--data', str(first), '--data', str(second), '--tau-plus=10', '--out', str(model)]
    code, out, err = run_cli(capsys, *argv, '--json')
    assert code == 0, err
    payload = json.loads(out)
    assert [(d['data'], d['trajectory_id_prefix'], d['n_trajectories'], d['n_fallen'])
            for d in payload['datasets']] == [(str(first), 'policy', 4, 2), (str(second), 'balance', 4, 3)]
    assert payload['n_trajectories'] == 8 and payload['tau_his_chosen']['folds'] == 8
    assert load_model(model)[1].dataset_fingerprint == payload['dataset_fingerprint']
    code, out, err = run_cli(capsys, *argv)
    assert code == 0, err
    assert (f'trained on 8 trajectories: 4 (2 fallen) from {first} as policy/...; '
            f'4 (3 fallen) from {second} as balance/...') in out


class _FrozenClock:
    """``model_file``'s clock at a fixed time, so that two model files can be compared byte for byte."""

    @staticmethod
    def now(tz=None):
        import datetime
        return datetime.datetime(2024, 1, 2, 3, 4, 5, tzinfo=tz)


def test_one_data_writes_the_single_dataset_paths_model_with_its_window(tmp_path, capsys, monkeypatch):
    """``train --data A`` choosing boosted trees' threshold and window writes, byte for byte,
    the model of the single-dataset path: ``load_dataset``, ``choose_tau_his`` with the
    dataset's guard, ``train_on_report``."""
    import fall_predictor.monitor.model_file as model_file
    from fall_predictor.learning.training import train_on_report
    monkeypatch.setattr(model_file, 'datetime', _FrozenClock)
    data = write_robot_dataset(tmp_path / 'g1', 'g1', n_fallen=3, n_balanced=2)
    model = tmp_path / 'model.json'
    code, out, err = run_cli(capsys, 'train', '--data', str(data), '--tau-plus=-0.1', '--learner',
                             'boosting', '--param', 'max_iter=5', '--decision-thresholds', '0,2',
                             '--folds', '2', '--out', str(model), '--json')
    assert code == 0, err
    report = load_dataset(data)
    learner = make_learner('boosting', {'max_iter': 5})
    search = WindowSearch(folds=2, decision_thresholds=(0, 2))
    groups = fold_groups([t.trajectory_id for t in report.trajectories],
                         disturbances(read_index(data)), search.folds)
    window = choose_tau_his(report.trajectories, learner, -0.1, search,
                            guard_com_height_m=dataset_guard_com_height_m(data), groups=groups)
    chosen = make_learner('boosting', {'max_iter': 5, 'decision_threshold': window.decision_threshold})
    lists, metadata = train_on_report(report, data, -0.1, chosen, recommended_tau_his_s=window.tau_his_s)
    assert any(lists.depths)
    expected = tmp_path / 'expected.json'
    model_file.save_model(expected, lists, metadata)
    assert model.read_bytes() == expected.read_bytes()
    assert [t.trajectory_id for t in report.trajectories] == \
        [f'traj_{i:05d}' for i in range(5)]                # ids as recorded: no prefix alone
    assert json.loads(out)['datasets'][0]['trajectory_id_prefix'] is None
