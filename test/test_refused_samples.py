"""Samples the feature extractor refuses are holes in every offline tool, as onboard
(monitor/chain.py: a DEGRADED state), never a traceback; the history window spans a short hole and
restarts after a long one, as the onboard monitor's does.

The datasets are the hand-made ones of ``robot_datasets`` (known measurements, no simulation),
with a glitch written into some trajectories: for ``GLITCH_SAMPLES`` samples before the push the
CoM reads ``GLITCH_COM_M`` (0.20 m below where it stands, in 1 ms: 200 m/s, ten times what the
plausibility check allows), then reads right again. Each glitch sample is a jump from the last
accepted one (0.20 m in 1, 2, 3 ms), so all three are refused and the next is accepted. Had the
glitch been taken, the ASIMO-like robot's CoM guard (0.48 m) would have fired on it.
"""
import dataclasses
import json
import shutil

import numpy as np
import pytest

from fall_predictor import cli
from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.data.dataset import RefusedSamples, load_features, read_index
from fall_predictor.learning.evaluation import evaluate_model, evaluation_json
from fall_predictor.learning.metrics import MAX_GAP_S, evaluate_atomic
from fall_predictor.monitor.decision_list import DecisionList, PerModeDecisionLists
from fall_predictor.monitor.fall_monitor import FallenConfig, FallMonitor
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.model_file import ModelMetadata, save_model
from fall_predictor.monitor.plausibility import ImplausibleSample
from fall_predictor.monitor.records import FALLING, N_CONTACT_MODES, N_FEATURES, TrajectoryFeatures

from robot_datasets import measurements, write_robot_dataset

GLITCH_START_S = 0.05
GLITCH_SAMPLES = 3
GLITCH_COM_M = 0.40


def glitched(fallen: bool):
    """The measurements of ``robot_datasets`` with the glitch (module docs)."""
    ms = measurements(fallen)
    first = int(round(GLITCH_START_S / 0.001))
    for k in range(first, first + GLITCH_SAMPLES):
        ms[k] = dataclasses.replace(ms[k], com=np.array([0.0, 0.0, GLITCH_COM_M]))
    return ms


def write_glitched_dataset(out, robot='asimo_like'):
    """``robot_datasets``' dataset (2 fallen, 2 balanced) with the glitch in trajectories 0 and 2."""
    data = write_robot_dataset(out, robot)
    for row in read_index(data):
        index = int(row.trajectory_id.split('_')[1])
        if index in (0, 2):
            shutil.rmtree(data / row.bag)
            with BagWriter(data / row.bag) as writer:
                for m in glitched(row.fallen):
                    writer.write_measurement(m)
    return data


def test_the_glitch_is_what_the_extractor_refuses():
    """The premise: fed whole, the glitch stops the feature extraction (what the offline tools
    did before: a traceback)."""
    from fall_predictor.monitor.features import extract_features
    with pytest.raises(ImplausibleSample, match='jump'):
        extract_features(glitched(False))


def test_refused_samples_are_left_out_and_counted(tmp_path):
    data = write_glitched_dataset(tmp_path / 'data')
    report = load_features(data, progress=False)
    assert report.errors == {}
    assert set(report.refused) == {'traj_00000', 'traj_00002'}
    for tid, refused in report.refused.items():
        assert (refused.estimator, refused.features) == (0, GLITCH_SAMPLES)
        assert refused.first.startswith(f'{GLITCH_START_S:.3f} s: measurement refused: jump')
    clean = {t.trajectory_id: t for t in load_features(write_robot_dataset(tmp_path / 'clean'),
                                                        progress=False).trajectories}
    for traj in report.trajectories:
        expected = clean[traj.trajectory_id]
        if traj.trajectory_id in report.refused:
            # exactly the glitch's samples are missing; the others are the clean ones
            kept = ~np.isin(np.round(expected.t * 1000), 50 + np.arange(GLITCH_SAMPLES))
            np.testing.assert_array_equal(traj.t, expected.t[kept])
            np.testing.assert_allclose(traj.X, expected.X[kept], atol=1e-12)
        else:
            np.testing.assert_array_equal(traj.t, expected.t)
    assert report.refused_total == RefusedSamples(0, 2 * GLITCH_SAMPLES)


def test_evaluate_train_and_sweep_take_refused_samples_as_holes(tmp_path, capsys):
    """The ASIMO-like robot's guard (0.48 m) would have fired on the glitch (0.40 m) before the
    push; taken as a hole, it does not: no false alarm, no pre-push alarm, and the falls are
    missed exactly as on the clean dataset (its CoM stays above 0.48 m until t_fallen)."""
    data = write_glitched_dataset(tmp_path / 'data')
    evaluation = evaluate_model(data, PerModeDecisionLists.empty(), 0.0, baselines=True)
    payload = evaluation_json(evaluation)
    assert payload['refused_samples'] == payload['refused_samples_features'] == 2 * GLITCH_SAMPLES
    assert payload['refused_samples_estimator'] == 0
    assert payload['refused_by_trajectory']['traj_00000']['features'] == GLITCH_SAMPLES
    r = evaluation.result
    assert (r.n_false_positives, r.n_pre_push_alarms, r.n_missed) == (0, 0, 2)
    assert [record.refused_samples for record in evaluation.run_records()] == [3, 0, 3, 0]

    model = tmp_path / 'model.json'
    save_model(model, PerModeDecisionLists.empty(), ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={}, dataset_fingerprint='other', recommended_tau_his_s=0.0,
        feature_settings=FeatureSettings(guard_com_height_m=0.48)))
    assert cli.main(['evaluate', '--data', str(data), '--model', str(model), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['refused_samples'] == 2 * GLITCH_SAMPLES
    assert cli.main(['evaluate', '--data', str(data), '--model', str(model)]) == 0
    assert '6 samples refused (0 by the estimator, 6 by the feature extractor)' in capsys.readouterr().out
    assert cli.main(['train', '--data', str(data), '--tau-plus', '0', '--tau-his', '0',
                     '--out', str(tmp_path / 'trained.json'), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['refused_samples'] == 2 * GLITCH_SAMPLES
    assert cli.main(['sweep', '--data', str(data), '--out', str(tmp_path / 'sweep'), '--folds', '2',
                     '--tau-plus', '0', '--tau-his', '0,0.01', '--no-learning-curve',
                     '--no-capture-point', '--json']) == 0
    assert json.loads(capsys.readouterr().out)['n_trajectories'] == 4


# -- holes and the history window -----------------------------------------------------------------
def _always_falling() -> PerModeDecisionLists:
    return PerModeDecisionLists(tuple(DecisionList(default=FALLING) for _ in range(N_CONTACT_MODES)))


def _standing(t: np.ndarray) -> TrajectoryFeatures:
    """A balanced trajectory at the sample times ``t`` [s]: CoM at 0.6 m, both feet flat."""
    X = np.zeros((t.size, N_FEATURES))
    X[:, 2] = 0.6
    return TrajectoryFeatures('holes', t, X, np.zeros(t.size, dtype=np.int64), False, 10.0, 10.1)


def _onboard_first_alarm(traj: TrajectoryFeatures, tau_his_s: float):
    """The first falling state of the onboard monitor fed the same samples, with nothing
    between them (a hole is a sample it never got)."""
    monitor = FallMonitor(_always_falling(), tau_his_s, FallenConfig(0.33, 0.45))
    for t, x, mode in zip(traj.t, traj.X, traj.mode):
        state, _ = monitor.step(float(t), x, int(mode))
        if state.falling:
            return float(t)
    return None


@pytest.mark.parametrize('hole_s', [0.05, MAX_GAP_S, 0.101, 0.3])
def test_the_window_spans_a_short_hole_and_restarts_after_a_long_one_as_onboard(hole_s):
    """Falling throughout, with one hole 20 ms after the start; window 60 ms. A hole of at most
    0.1 s is spanned (the alarm 60 ms after the first sample, or at the first sample after the
    hole if that is later); after a longer one the window restarts (the alarm 60 ms after the
    hole). The offline evaluation gives the onboard monitor's time either way."""
    before = np.round(np.arange(0, 21) * 0.001, 6)
    after = np.round(0.020 + hole_s + np.arange(0, 200) * 0.001, 6)
    traj = _standing(np.concatenate([before, after]))
    tau_his_s = 0.06
    atomic = [np.ones(traj.t.size, dtype=bool)]
    result = evaluate_atomic([traj], atomic, (tau_his_s,), keep_alarms=True)[tau_his_s]
    first = result.alarms[0].first_alarm_t
    expected = (after[0] + tau_his_s if hole_s > MAX_GAP_S else max(after[0], tau_his_s))
    assert first == pytest.approx(expected, abs=1e-9)
    assert first == _onboard_first_alarm(traj, tau_his_s)

