"""A robot's own recordings as a dataset (data/robot_import.py): falls found from the
estimated state, features only from the estimated state, the robot read from its URDF.

The "robot recordings" are generated bags cut down to what ``ros2 bag record`` of a robot's
standard topics holds (no push topic, no true state); the simulator's own labels of the same
runs are the independent answer the import is checked against.
"""
import json

import pytest

from fall_predictor.cli import main
from fall_predictor.data.bag_writer import BagWriter
from fall_predictor.data.bagio import iter_messages
from fall_predictor.data.dataset import dataset_robot, read_index, read_manifest, robot_total_mass_kg
from fall_predictor.data.robot_import import is_robot_recording
from fall_predictor.contract.topics import ROBOT_DESCRIPTION, SENSOR_TOPICS
from fall_predictor.monitor.model_file import load_model
from fall_predictor.profiles import asimo_like_urdf as rm

SENSOR_NAMES = tuple(spec.name for spec in SENSOR_TOPICS)


def _robot_recording(source, target, keep_description=True):
    """``source`` with only the robot's sensor topics (what a robot's ``ros2 bag record`` holds)."""
    names = [n for n in SENSOR_NAMES if keep_description or n != ROBOT_DESCRIPTION.name]
    with BagWriter(target) as bag:
        for message in iter_messages(source, names):
            bag.write(message.topic, message.msg_type, message.t_ns, message.msg)
    return target


@pytest.fixture(scope='module')
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp('robot') / 'sim'
    assert main(['generate', '--trajectories', '2', '--seed', '0', '--out', str(out), '--horizon', '0.8',
                 '--sensor-noise', '1', '--json']) == 0
    return out


@pytest.fixture(scope='module')
def recordings(simulated, tmp_path_factory):
    where = tmp_path_factory.mktemp('robot') / 'recordings'
    where.mkdir(exist_ok=True)
    return [_robot_recording(simulated / row.bag, where / row.trajectory_id) for row in read_index(simulated)]


def test_falls_found_from_the_estimated_state_match_the_simulators_labels(simulated, recordings, tmp_path, capsys):
    assert all(is_robot_recording(bag) for bag in recordings)
    assert not is_robot_recording(simulated / read_index(simulated)[0].bag)
    out = tmp_path / 'robot_data'
    assert main(['import-bags', *map(str, recordings), '--out', str(out), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['imported'] == 2
    truth = read_index(simulated)
    rows = read_index(out)
    assert [r.fallen for r in rows] == [r.fallen for r in truth]
    assert any(r.fallen for r in rows)
    for got, expected in zip(rows, truth):
        assert got.t_start == pytest.approx(expected.t_start, abs=0.01)
        if expected.fallen:
            # Estimated CoM height and IMU tilt against the simulator's true fall time.
            assert got.t_fallen == pytest.approx(expected.t_fallen, abs=0.08)
            assert got.t_height_drop < got.t_fallen
    manifest = read_manifest(out)
    assert manifest['ground_truth'] is False
    # The robot's mass from its URDF (Pinocchio), against the simulator's own total.
    from fall_predictor.sim.trajectory import ROBOT_TOTAL_MASS_KG
    assert robot_total_mass_kg(out) == pytest.approx(ROBOT_TOTAL_MASS_KG, rel=1e-6)

    model = tmp_path / 'm.json'
    assert main(['train', '--data', str(out), '--tau-plus=-0.25', '--out', str(model), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['state'] == 'estimated'
    assert load_model(model)[1].state == 'estimated'
    # There is no true state in a robot's recordings: asking for it is one clear error.
    assert main(['train', '--data', str(out), '--state', 'true', '--tau-plus=-0.25',
                 '--out', str(tmp_path / 'x.json')]) == 2
    assert 'no true state' in capsys.readouterr().err
    assert main(['evaluate', '--data', str(out), '--model', str(model), '--tau-his', '0.02', '--json']) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload['n_trajectories'] == 2 and payload['direction_error_deg']['n'] == 0


def test_a_recording_without_description_needs_the_urdf(simulated, tmp_path, capsys):
    row = read_index(simulated)[0]
    bag = _robot_recording(simulated / row.bag, tmp_path / 'no_description', keep_description=False)
    assert main(['import-bags', str(bag), '--out', str(tmp_path / 'a'), '--json']) == 1
    assert 'robot_description' in json.loads(capsys.readouterr().out)['rejected'][str(bag)]
    # The robot's profile given as a file: recorded, and what later estimation of the data uses.
    profile = str(rm.PROFILE.source)
    assert main(['import-bags', str(bag), '--out', str(tmp_path / 'b'), '--urdf', str(rm.URDF_PATH),
                 '--robot', profile, '--json']) == 0
    capsys.readouterr()
    assert (tmp_path / 'b' / 'robot.urdf').read_text() == rm.URDF_PATH.read_text()
    assert read_manifest(tmp_path / 'b')['robot']['profile'] == profile
    assert dataset_robot(tmp_path / 'b') == profile
    assert row.fallen                   # one fallen recording is enough to train on
    assert main(['train', '--data', str(tmp_path / 'b'), '--tau-plus=-0.25', '--out',
                 str(tmp_path / 'm.json'), '--json']) == 0
    assert load_model(tmp_path / 'm.json')[1].state == 'estimated'


@pytest.mark.parametrize('robot, wrenches', [('asimo_like', True), ('g1', False)])
def test_a_recording_the_estimator_cannot_use_is_refused_naming_that_robots_topics(
        tmp_path, robot, wrenches):
    """An IMU and a description alone give no estimate: the refusal names the topics this robot
    needs, the foot wrenches only for a robot with foot F/T sensors (the G1 has none)."""
    from fall_predictor.contract import cdr
    from fall_predictor.contract.topics import IMU
    from fall_predictor.data.robot_import import robot_recording_row
    from fall_predictor.data.dataset import DatasetError
    from fall_predictor.data.sensorbag import write_robot_description
    from fall_predictor.monitor.sensor_records import ImuReading
    from fall_predictor.profiles import load_profile
    profile = load_profile(robot)
    bag = tmp_path / 'imu_only'
    with BagWriter(bag) as writer:
        write_robot_description(writer, 0.0, profile.urdf_xml())
        for k in range(20):
            reading = ImuReading(k * 1_000_000, profile.imu_frame, (0.0, 0.0, 0.0, 1.0),
                                 (0.0, 0.0, 0.0), (0.0, 0.0, 9.81))
            writer.write_raw(IMU.name, IMU.msg_type, k * 1_000_000, cdr.imu_cdr(reading))
    with pytest.raises(DatasetError, match=f'the {robot} robot needs') as refused:
        robot_recording_row(bag, 'traj_00000', robot=robot)
    assert '/joint_states, /imu/data' in str(refused.value)
    assert ('/left_foot/wrench' in str(refused.value)) is wrenches
