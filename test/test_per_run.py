"""``evaluate --per-run``: one row per run, from the same alarms as the summary
(fall_predictor/learning/per_run.py), on hand-made datasets whose alarms are known from geometry.

The CoM guard alone decides (empty decision lists), with the G1's guard, 0.55 m, and the CoM
moving at 1 m/s. A dip from 0.60 m to 0.53 m and back, starting at ``t0``, is below the guard
from ``t0 + 0.051`` to ``t0 + 0.089`` s (1 ms samples): 38 ms, so a history window of 60 ms
never alarms on it and one of 0 ms alarms at ``t0 + 0.051``.
"""
import csv
import dataclasses
import json

import numpy as np
import pytest

from fall_predictor import cli
from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.data.dataset import FORMAT, PUSH_UNKNOWN, IndexRow, trajectory_id, write_index_csv
from fall_predictor.learning.evaluation import evaluate_model
from fall_predictor.monitor.decision_list import PerModeDecisionLists
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.model_file import ModelMetadata, save_model
from fall_predictor.monitor.records import Measurement
from fall_predictor.profiles.profile import load_profile

DT_S = 0.001
DURATION_S = 1.0
T_PUSH_S = 0.5
#: Dips (start times [s]) of the walking run: two before the push, one after.
DIPS_S = (0.1, 0.3, 0.6)
#: The falling run sinks from here at 1 m/s (below 0.55 m from 0.751 s) and is down at T_FALLEN_S.
T_SINK_S, T_FALLEN_S = 0.7, 0.8


def com_height_m(k: int, kind: str) -> float:
    """The CoM height [m] of a run at sample ``k`` (in whole millimetres: no round-off at the
    guard)."""
    if kind == 'dips':
        starts = [round(t0 * 1000) for t0 in DIPS_S]
        return min([600] + [530 + abs(k - (k0 + 70)) for k0 in starts if k0 <= k <= k0 + 140]) / 1000
    if kind == 'falls':
        return (600 - max(0, k - round(T_SINK_S * 1000))) / 1000
    return 0.60


def _feet(y: float) -> np.ndarray:
    return np.array([[x, y + dy, 100.0] for x in (-0.08, 0.08) for dy in (-0.03, 0.03)])


def write_dataset(out, kinds=('dips', 'falls', 'stands'), push_sources=(None, None, None)):
    """One run per kind (module docs) of the G1, each pushed at T_PUSH_S (or, with push source
    'unknown', as a robot's recording imported without a push time: t_push its start)."""
    profile = load_profile('g1')
    (out / 'index').mkdir(parents=True)
    (out / 'dataset.json').write_text(json.dumps({
        'format': FORMAT, 'robot': {'name': profile.name, 'profile': 'g1',
                                    'total_mass_kg': profile.total_mass_kg}}))
    rows = []
    for i, (kind, source) in enumerate(zip(kinds, push_sources)):
        ms = [Measurement(t=round(k * DT_S, 6), com=np.array([0.0, 0.0, com_height_m(k, kind)]),
                          lin_mom=np.zeros(3), ang_mom=np.zeros(3), heading=0.0, cop=np.zeros(3),
                          left_contacts=_feet(0.1), right_contacts=_feet(-0.1),
                          left_foot=np.array([0.0, 0.1, 0.0]), right_foot=np.array([0.0, -0.1, 0.0]),
                          non_foot_contact=False) for k in range(int(round(DURATION_S / DT_S)))]
        fallen = kind == 'falls'
        t_push = 0.0 if source == PUSH_UNKNOWN else T_PUSH_S
        row = IndexRow(trajectory_id(i), f'bags/{trajectory_id(i)}', 100.0, 90.0, 0.1, t_push,
                       t_push + 0.1, fallen, T_FALLEN_S if fallen else None,
                       T_SINK_S if fallen else None, None, 0.0, ms[-1].t, len(ms), push_source=source)
        with BagWriter(out / row.bag) as writer:
            for m in ms:
                writer.write_measurement(m)
        (out / 'index' / f'{row.trajectory_id}.json').write_text(json.dumps(dataclasses.asdict(row)))
        rows.append(row)
    write_index_csv(out, rows)
    return out


def _model(path, tau_his_s):
    save_model(path, PerModeDecisionLists.empty(), ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={}, dataset_fingerprint='other', recommended_tau_his_s=tau_his_s,
        feature_settings=FeatureSettings(guard_com_height_m=0.55)))
    return path


def test_each_runs_alarms_from_geometry(tmp_path):
    data = write_dataset(tmp_path / 'data')
    dips, falls, stands = evaluate_model(data, PerModeDecisionLists.empty(), 0.0).run_records()
    # the walking run alarmed twice before the push (its first alarm) and once after
    assert dips.first_alarm_s == pytest.approx(DIPS_S[0] + 0.051)
    assert dips.pre_push_alarm_onsets == 2 and dips.false_alarm is True
    assert dips.lead_s is None and dips.missed is None and dips.t_push_s == T_PUSH_S
    assert dips.first_alarm_after_push_s == pytest.approx(DIPS_S[2] + 0.051)
    # the fall: below 0.55 m from 0.751 s, down at 0.8 s: a lead of 49 ms
    assert falls.first_alarm_s == pytest.approx(0.751) and falls.lead_s == pytest.approx(0.049)
    assert falls.missed is False and falls.false_alarm is None and falls.pre_push_alarm_onsets == 0
    assert falls.t_fallen_s == T_FALLEN_S
    assert stands.first_alarm_s is None and stands.false_alarm is False
    assert stands.pre_push_alarm_onsets == 0
    # a window longer than a dip (38 ms): no alarm on the walking run; the fall alarms 60 ms later
    dips, falls, _ = evaluate_model(data, PerModeDecisionLists.empty(), 0.06).run_records()
    assert dips.first_alarm_s is None and dips.pre_push_alarm_onsets == 0
    assert falls.missed is True and falls.lead_s is None       # the alarm came after t_fallen


def test_the_rows_add_up_to_the_summary(tmp_path):
    data = write_dataset(tmp_path / 'data', kinds=('dips', 'falls', 'stands', 'dips', 'falls'),
                         push_sources=(None,) * 5)
    evaluation = evaluate_model(data, PerModeDecisionLists.empty(), 0.0)
    rows, r = evaluation.run_records(), evaluation.result
    assert sum(bool(x.false_alarm) for x in rows) == r.n_false_positives == 2
    assert sum(bool(x.pre_push_alarm_onsets) for x in rows) == r.n_pre_push_alarms == 2
    assert sum(bool(x.missed) for x in rows) == r.n_missed == 0
    assert np.mean([x.lead_s or 0.0 for x in rows if x.fallen]) == pytest.approx(r.tau_lead_s)


def test_cli_per_run_csv_and_json(tmp_path, capsys):
    data = write_dataset(tmp_path / 'data')
    model = _model(tmp_path / 'model.json', 0.0)
    table = tmp_path / 'runs.csv'
    assert cli.main(['evaluate', '--data', str(data), '--model', str(model), '--per-run', str(table),
                     '--json']) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload['per_run'] == str(table) and payload['n_pre_push_alarms'] == 1
    rows = list(csv.DictReader(table.open()))
    assert [r['trajectory_id'] for r in rows] == ['traj_00000', 'traj_00001', 'traj_00002']
    assert rows[0]['pre_push_alarm_onsets'] == '2' and rows[0]['false_alarm'] == '1'
    assert float(rows[0]['first_alarm_s']) == pytest.approx(0.151)
    assert rows[1]['lead_s'] and float(rows[1]['lead_s']) == pytest.approx(0.049)
    assert rows[1]['false_alarm'] == '' and rows[2]['first_alarm_s'] == ''
    document = tmp_path / 'runs.json'
    assert cli.main(['evaluate', '--data', str(data), '--model', str(model), '--per-run',
                     str(document)]) == 0
    text = capsys.readouterr().out
    assert 'pre-push false alarms: 1 runs alarmed before their push' in text
    runs = json.loads(document.read_text())
    assert runs['format'] == 'fall_predictor/per-run/v1' and runs['tau_his_s'] == 0.0
    assert [r['pre_push_alarm_onsets'] for r in runs['runs']] == [2, 0, 0]
    assert runs['runs'][1]['lead_s'] == pytest.approx(0.049) and runs['runs'][2]['first_alarm_s'] is None


def test_runs_without_a_push_time_say_so(tmp_path, capsys):
    """A robot's recordings imported without push times: t_push is the recording's start, so
    nothing is "before the push"; the rows leave the push time and the count empty and the
    summary counts those runs."""
    data = write_dataset(tmp_path / 'data', push_sources=(PUSH_UNKNOWN, 'push_times_file', PUSH_UNKNOWN))
    model = _model(tmp_path / 'model.json', 0.0)
    table = tmp_path / 'runs.json'
    assert cli.main(['evaluate', '--data', str(data), '--model', str(model), '--per-run', str(table),
                     '--json']) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload['n_runs_push_time_unknown'] == 2 and payload['n_pre_push_alarms'] == 0
    dips, falls, stands = json.loads(table.read_text())['runs']
    assert dips['push_source'] == 'unknown' and dips['t_push_s'] is None
    assert dips['pre_push_alarm_onsets'] is None and dips['false_alarm'] is True
    assert falls['push_source'] == 'push_times_file' and falls['t_push_s'] == T_PUSH_S
    assert cli.main(['evaluate', '--data', str(data), '--model', str(model)]) == 0
    assert '2 runs without a push time' in capsys.readouterr().out
