"""The figures a deployer reads (fall_predictor.learning.deployment): per cause, per hour of
undisturbed walking, per push impulse band; and ``evaluate`` giving them on a hand-made dataset
of several causes (test/robot_datasets.py: the G1's CoM guard alone decides every run)."""
import dataclasses
import json

import numpy as np
import pytest

from fall_predictor import cli
from fall_predictor.data.dataset import IndexRow, read_index
from fall_predictor.learning.deployment import (deployment_figures, deployment_lines, walking_line,
                                                impulse_band_figures, run_outcomes)
from fall_predictor.learning.evaluation import evaluate_model, evaluation_json
from fall_predictor.learning.intervals import garwood_interval, wilson_interval
from fall_predictor.learning.metrics import TrajectoryAlarms
from fall_predictor.learning.run_groups import RunDisturbance
from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.model_file import ModelMetadata, save_model
from fall_predictor.monitor.records import TrajectoryFeatures

from robot_datasets import G1_GUARD_LEAD_S, T_FALLEN_S, T_PUSH_S, write_robot_dataset


def _traj(tid: str, fallen: bool, t_push: float = 1.0, t_fallen: float = 2.0,
          duration_s: float = 3.0) -> TrajectoryFeatures:
    t = np.arange(0.0, duration_s, 0.001)
    return TrajectoryFeatures(tid, t, np.zeros((t.size, 15)), np.zeros(t.size, int), fallen,
                              t_push, t_push + 0.1, t_fallen if fallen else None,
                              t_fallen - 0.2 if fallen else None)


def _alarm(first=None, after=None, before=False, onsets=0) -> TrajectoryAlarms:
    return TrajectoryAlarms(first, after, before, int(before), onsets)


def test_fpr_per_impulse_band_of_survived_pushes():
    """Pushes of 5, 15, 15, 25, 25, 25 N s: the survived ones of each 10 N s band and their
    false alarms make each band's FPR; a band's fall fraction counts every push in it."""
    spec = [(5.0, False, True), (15.0, False, False), (15.0, True, None), (25.0, False, True),
            (25.0, False, False), (25.0, False, False)]
    trajs, alarms, runs = [], [], {}
    for i, (impulse, fallen, false_alarm) in enumerate(spec):
        trajs.append(_traj(f'r{i}', fallen))
        alarms.append(_alarm(1.5, 1.5, onsets=1) if false_alarm or fallen else _alarm())
        runs[f'r{i}'] = RunDisturbance('push', 1.0, impulse)
    bands = impulse_band_figures(run_outcomes(trajs, alarms, runs), 10.0)
    assert [(b['low_ns'], b['n_pushes']) for b in bands] == [(0.0, 1), (10.0, 2), (20.0, 3)]
    assert [(b['fpr']['k'], b['fpr']['n']) for b in bands] == [(1, 1), (0, 1), (1, 3)]
    assert bands[1]['fall_fraction'] == 0.5
    assert bands[2]['fpr']['ci95'] == list(wilson_interval(1, 3))


def test_per_cause_figures_and_false_alarms_per_hour_of_walking():
    """A push caught 0.5 s ahead, a trip missed, a fault alarmed before its onset, two survived
    slips (one alarmed), and two hour-long walks with 1 and 2 alarm episodes: 3 per 2 h."""
    trajs = [_traj('push', True), _traj('trip', True), _traj('fault', False),
             _traj('slip0', False), _traj('slip1', False),
             _traj('walk0', False, 0.0, duration_s=3600.0), _traj('walk1', False, 0.0, duration_s=3.0)]
    trajs[-2] = dataclasses.replace(trajs[-2], t=np.array([0.0, 3600.0]))
    alarms = [_alarm(1.5, 1.5, onsets=1), _alarm(), _alarm(0.5, 1.1, True, 2),
              _alarm(1.2, 1.2, onsets=1), _alarm(), _alarm(10.0, 10.0, onsets=1),
              _alarm(0.2, 0.2, onsets=2)]
    runs = {'push': RunDisturbance('push', 1.0, 30.0), 'trip': RunDisturbance('trip', 1.0, None),
            'fault': RunDisturbance('fault', 1.0, None), 'slip0': RunDisturbance('slip', 1.0, None),
            'slip1': RunDisturbance('slip', 1.0, None), 'walk0': RunDisturbance('walk', None, None),
            'walk1': RunDisturbance('walk', None, None)}
    figures = deployment_figures(run_outcomes(trajs, alarms, runs))
    by_cause = figures['by_cause']
    assert list(by_cause) == ['push', 'trip', 'slip', 'fault', 'walk']
    push, trip = by_cause['push'], by_cause['trip']
    assert (push['falls_caught']['k'], push['lead_median_s'], push['onset_to_fall_median_s']) == \
        (1, pytest.approx(0.5), pytest.approx(1.0))
    assert push['lead_fraction_median'] == pytest.approx(0.5)
    assert (trip['falls_caught']['k'], trip['falls_caught']['n'], trip['lead_median_s']) == (0, 1, 0.0)
    assert by_cause['fault']['alarms_before_onset'] == {'k': 1, 'n': 1}
    assert (by_cause['slip']['fpr']['k'], by_cause['slip']['fpr']['n']) == (1, 2)
    assert by_cause['walk']['alarms_before_onset'] == {'k': 0, 'n': 0}   # no onset on a walk
    walking = figures['walking']
    hours = (3600.0 + 2.999) / 3600.0
    assert (walking['alarm_episodes'], walking['n_walks'], walking['walks_alarmed']) == (3, 2, 2)
    assert walking['hours'] == pytest.approx(hours)
    assert walking['per_hour_ci95'] == pytest.approx(list(garwood_interval(3, hours)))
    text = '\n'.join(deployment_lines(figures))
    assert '| trip | 0/1 |' in text and '3 false alarm episodes in 1.00 h (2 walks)' in text
    one = {**figures['walking'], 'n_walks': 1}
    assert '(1 walk):' in walking_line(one)


def _write_causes(data) -> None:
    """Give the hand-made dataset's runs causes: fallen 0 a push, fallen 1 a trip; balanced 2 a
    push, 3 a trip, 4 and 5 long walks (no onset, their push time at their start)."""
    causes = ['push', 'trip', 'push', 'trip', 'walk', 'walk']
    for row, cause in zip(read_index(data), causes):
        path = data / 'index' / f'{row.trajectory_id}.json'
        fields = dict(cause=cause, force_n=100.0 if cause == 'push' else 0.0,
                      t_onset=None if cause == 'walk' else row.t_push)
        if cause == 'walk':
            fields.update(t_push=row.t_start, t_force_end=row.t_start)
        path.write_text(json.dumps(dataclasses.asdict(dataclasses.replace(row, **fields))))


def test_evaluate_gives_the_figures_per_cause(tmp_path, capsys):
    """The G1's guard (0.55 m) catches both falls 0.049 s ahead (0.2 s after the onset) and
    alarms once on every squat, walks included: each walk is one episode in its 0.5 s."""
    data = write_robot_dataset(tmp_path / 'g1', 'g1', n_fallen=2, n_balanced=4)
    _write_causes(data)
    evaluation = evaluate_model(data, PerModeDecisionLists.empty(), 0.0)
    figures = evaluation_json(evaluation)['deployment']
    assert [(r.cause, r.alarm_onsets) for r in evaluation.run_records()] == \
        [('push', 1), ('trip', 1), ('push', 1), ('trip', 1), ('walk', 1), ('walk', 1)]
    assert list(figures['by_cause']) == ['push', 'trip', 'walk']
    for cause in ('push', 'trip'):
        f = figures['by_cause'][cause]
        assert (f['falls_caught']['k'], f['fpr']['k'], f['fpr']['n']) == (1, 1, 1)
        assert f['lead_median_s'] == pytest.approx(G1_GUARD_LEAD_S, abs=1e-9)
        assert f['onset_to_fall_median_s'] == pytest.approx(T_FALLEN_S - T_PUSH_S)
        assert f['alarms_before_onset'] == {'k': 0, 'n': 2}
    walking = figures['walking']
    assert (walking['n_walks'], walking['alarm_episodes']) == (2, 2)
    assert walking['per_hour'] == pytest.approx(2 / (2 * 0.499 / 3600.0))
    assert [b['low_ns'] for b in figures['push_bands']] == [10.0]        # 100 N x 0.1 s
    assert figures['ambiguous_push_band'] is None                       # two pushes
    model = tmp_path / 'model.json'
    save_model(model, PerModeDecisionLists.empty(), ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={}, dataset_fingerprint='other', recommended_tau_his_s=0.0,
        feature_settings=FeatureSettings(guard_com_height_m=0.55)))
    assert cli.main(['evaluate', '--data', str(data), '--model', str(model), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['deployment'] == json.loads(json.dumps(figures))
    assert cli.main(['evaluate', '--data', str(data), '--model', str(model)]) == 0
    text = capsys.readouterr().out
    assert '| trip | 1/1 | 1.000' in text and 'undisturbed walking: 2 false alarm episodes' in text


def test_a_dataset_without_causes_reads_as_pushes(tmp_path):
    data = write_robot_dataset(tmp_path / 'g1', 'g1')
    figures = evaluate_model(data, PerModeDecisionLists.empty(), 0.0).deployment()
    assert list(figures['by_cause']) == ['push'] and figures['walking'] is None
    assert figures['by_cause']['push']['n_runs'] == 4
