"""Features from the true or the estimated state (``--state``, data/dataset.py).

The estimated path must be what the robot runs: the state estimator fed one sensor sample at a
time and the streaming feature extractor, as ``state_estimator_node`` and ``feature_node`` do.
"""
import json

import numpy as np
import pytest

from fall_predictor.cli import main
from fall_predictor.data.dataset import load_features, read_index, resolve_state
from fall_predictor.data.sensorbag import read_robot_description, read_sensor_messages
from fall_predictor.monitor.sensor_pipeline import SensorPipeline
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.monitor.features import FeatureSettings
from fall_predictor.monitor.model_file import ModelFileError, load_model
from fall_predictor.monitor.records import FEATURE_NAMES


@pytest.fixture(scope='module')
def sensor_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp('state') / 'data'
    assert main(['generate', '--trajectories', '2', '--seed', '0', '--out', str(out), '--horizon', '0.8',
                 '--sensor-noise', '1', '--json']) == 0
    return out


@pytest.fixture(scope='module')
def plain_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp('state') / 'plain'
    assert main(['generate', '--trajectories', '1', '--seed', '5', '--out', str(out), '--horizon', '0.2',
                 '--json']) == 0
    return out


def test_estimated_features_are_the_live_nodes_stream(sensor_dataset):
    report = load_features(sensor_dataset, progress=False, state='estimated')
    assert report.state == 'estimated' and report.note is None and not report.errors
    row = read_index(sensor_dataset)[0]
    traj = next(t for t in report.trajectories if t.trajectory_id == row.trajectory_id)
    # The live path, one message at a time: estimator node, then feature node.
    bag = sensor_dataset / row.bag
    layout = rm.PROFILE.sensor_layout()
    pipeline = SensorPipeline(layout.description(read_robot_description(bag)), layout.imu_frame)
    extractor = FeatureSettings().extractor()
    t, X, mode = [], [], []
    for stream, reading in read_sensor_messages(bag):
        estimates = (pipeline.joint_state(reading)[0] if stream == 'joints' else
                     pipeline.imu(reading) if stream == 'imu' else pipeline.wrench(stream, reading))
        for e in estimates:
            if e.measurement is None:
                continue
            x, k = extractor.update(e.measurement)
            t.append(e.stamp_ns / 1e9)
            X.append(x)
            mode.append(k)
    np.testing.assert_array_equal(traj.t, t)
    np.testing.assert_allclose(traj.X, np.array(X), rtol=1e-12, atol=1e-12, equal_nan=True)
    np.testing.assert_array_equal(traj.mode, mode)


def test_estimated_features_track_the_true_ones_and_are_cached_apart(sensor_dataset):
    true = load_features(sensor_dataset, progress=False, state='true')
    estimated = load_features(sensor_dataset, progress=False, state='estimated')
    assert true.state == 'true'
    cache = sensor_dataset / 'cache'
    for row in read_index(sensor_dataset):
        assert (cache / f'{row.trajectory_id}.npz').exists()
        assert (cache / f'{row.trajectory_id}.estimated.npz').exists()
    com_z = FEATURE_NAMES.index('com_z')
    for a, b in zip(true.trajectories, estimated.trajectories):
        by_t = {round(t * 1000): i for i, t in enumerate(a.t)}
        pairs = [(by_t[round(t * 1000)], j) for j, t in enumerate(b.t) if round(t * 1000) in by_t]
        assert len(pairs) >= 0.99 * len(a.t)
        i, j = np.array(pairs).T
        # CoM height above the support (a CoP-frame feature): the estimator's CoM error budget.
        assert np.median(np.abs(a.X[i, com_z] - b.X[j, com_z])) < 0.01
        assert np.mean(a.mode[i] == b.mode[j]) > 0.9
        assert not np.array_equal(a.X[i], b.X[j])            # they are not the same data
    again = load_features(sensor_dataset, progress=False, state='estimated')
    assert again.rebuilt == 0


def test_a_dataset_without_sensor_topics_falls_back_to_the_true_state_and_says_so(plain_dataset, capsys):
    state, note = resolve_state(plain_dataset, 'estimated')
    assert state == 'true' and 'without sensor topics' in note
    assert resolve_state(plain_dataset, 'true') == ('true', None)
    with pytest.raises(ValueError):
        resolve_state(plain_dataset, 'guessed')
    assert load_features(plain_dataset, progress=False, state='estimated').state == 'true'


def test_train_records_the_state_in_the_model_file(sensor_dataset, plain_dataset, tmp_path, capsys):
    out = tmp_path / 'm.json'
    if not any(r.fallen for r in read_index(sensor_dataset)):
        pytest.fail('the fixture needs a fall: pick another seed')
    assert main(['train', '--data', str(sensor_dataset), '--tau-plus=-0.25', '--out', str(out), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['state'] == 'estimated'
    assert json.loads(out.read_text())['training']['state'] == 'estimated'
    assert load_model(out)[1].state == 'estimated'
    assert main(['train', '--data', str(sensor_dataset), '--state', 'true', '--tau-plus=-0.25',
                 '--out', str(out), '--json']) == 0
    capsys.readouterr()
    assert load_model(out)[1].state == 'true'
    # evaluate reports both the data's state and the model's.
    assert main(['evaluate', '--data', str(sensor_dataset), '--model', str(out), '--tau-his', '0.02',
                 '--json']) == 0
    payload = json.loads(capsys.readouterr().out)
    assert (payload['state'], payload['model_state']) == ('estimated', 'true')


def test_a_model_file_with_an_unknown_state_is_refused(sensor_dataset, tmp_path, capsys):
    out = tmp_path / 'm.json'
    assert main(['train', '--data', str(sensor_dataset), '--state', 'true', '--tau-plus=-0.25',
                 '--out', str(out), '--json']) == 0
    document = json.loads(out.read_text())
    document['training']['state'] = 'guessed'
    out.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match='training.state'):
        load_model(out)
    del document['training']['state']                  # files before the field: the true state
    out.write_text(json.dumps(document))
    assert load_model(out)[1].state == 'true'
