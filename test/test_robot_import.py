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
    from fall_predictor.profiles.profile import load_profile
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


# -- push times -----------------------------------------------------------------------------------
def _with_push(source, target):
    """``source``'s robot recording with the package's push topic too (a robot whose push device
    publishes on it)."""
    from fall_predictor.contract.topics import PUSH
    with BagWriter(target) as bag:
        for message in iter_messages(source, [*SENSOR_NAMES, PUSH.name]):
            bag.write(message.topic, message.msg_type, message.t_ns, message.msg)
    return target


@pytest.fixture(scope='module')
def recordings_with_push(simulated, tmp_path_factory):
    where = tmp_path_factory.mktemp('robot') / 'with_push'
    where.mkdir(exist_ok=True)
    return [_with_push(simulated / row.bag, where / row.trajectory_id) for row in read_index(simulated)]


def _always_falling_model(path, tau_his_s=0.0):
    from fall_predictor.monitor.decision_list import DecisionList, PerModeDecisionLists
    from fall_predictor.monitor.model_file import ModelMetadata, save_model
    from fall_predictor.monitor.records import FALLING, N_CONTACT_MODES
    lists = PerModeDecisionLists(tuple(DecisionList(default=FALLING) for _ in range(N_CONTACT_MODES)))
    save_model(path, lists, ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={}, dataset_fingerprint='none', recommended_tau_his_s=tau_his_s))
    return path


def test_push_times_from_the_push_topic_or_a_file_are_the_simulators(simulated, recordings,
                                                                      recordings_with_push, tmp_path, capsys):
    """The push onset of each recording, from its push message or from a push-times file (one by
    its path in seconds, one by its directory name in nanoseconds), is the simulator's own; with
    it, a predictor that always says falling alarms before the push on every run (the
    recordings start a second before it), without it on none."""
    truth = read_index(simulated)
    out = tmp_path / 'from_topic'
    assert main(['import-bags', *map(str, recordings_with_push), '--out', str(out), '--json']) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload['push_times'] == {'push_topic': 2, 'push_times_file': 0, 'unknown': 0}
    for got, expected in zip(read_index(out), truth):
        assert got.push_source == 'push_topic' and got.t_push == expected.t_push
        assert got.t_force_end == pytest.approx(expected.t_force_end, abs=1e-9)
        assert got.force_n == pytest.approx(expected.force_n, rel=1e-9)
        # the estimated heading against the simulator's
        assert abs((got.angle_deg - expected.angle_deg + 180.0) % 360.0 - 180.0) < 2.0

    table = tmp_path / 'push_times.csv'
    table.write_text(f'bag,t_push_s,t_push_ns\n{recordings[0]},{truth[0].t_push!r},\n'
                     f'{recordings[1].name},,{round(truth[1].t_push * 1e9)}\n')
    from_file = tmp_path / 'from_file'
    assert main(['import-bags', *map(str, recordings), '--push-times', str(table), '--out',
                 str(from_file), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['without_push_time'] == []
    assert [(r.push_source, r.t_push) for r in read_index(from_file)] == \
        [('push_times_file', expected.t_push) for expected in truth]

    unknown = tmp_path / 'unknown'
    assert main(['import-bags', *map(str, recordings), '--out', str(unknown)]) == 0
    assert '2 recordings without a push time' in capsys.readouterr().out
    assert all(r.push_source == 'unknown' and r.t_push == r.t_start for r in read_index(unknown))

    model = _always_falling_model(tmp_path / 'always.json')
    for data, pre_push, unknown_runs in ((from_file, 2, 0), (out, 2, 0), (unknown, 0, 2)):
        assert main(['evaluate', '--data', str(data), '--model', str(model), '--json']) == 0
        evaluation = json.loads(capsys.readouterr().out)
        assert (evaluation['n_pre_push_alarms'], evaluation['n_runs_push_time_unknown']) == \
            (pre_push, unknown_runs), data


def test_a_push_time_that_cannot_be_is_refused_with_the_reason(simulated, recordings, recordings_with_push,
                                                               tmp_path, capsys):
    truth = read_index(simulated)
    table = tmp_path / 'outside.csv'
    table.write_text(f'bag,t_push_s\n{recordings[0].name},{truth[0].t_end + 5.0}\n')
    assert main(['import-bags', str(recordings[0]), '--push-times', str(table), '--out',
                 str(tmp_path / 'a'), '--json']) == 1
    assert 'is outside the recording' in json.loads(capsys.readouterr().out)['rejected'][str(recordings[0])]
    table.write_text(f'bag,t_push_s\n{recordings_with_push[0].name},{truth[0].t_push + 0.5}\n')
    assert main(['import-bags', str(recordings_with_push[0]), '--push-times', str(table), '--out',
                 str(tmp_path / 'b'), '--json']) == 1
    assert 'the push-times file says' in json.loads(capsys.readouterr().out)['rejected'][
        str(recordings_with_push[0])]
    table.write_text('recording,t\nx,1\n')
    assert main(['import-bags', str(recordings[0]), '--push-times', str(table), '--out',
                 str(tmp_path / 'c')]) == 2
    assert 'needs the columns bag and t_push_s' in capsys.readouterr().err
    # the recorder's bags carry their pushes: a push-times file is a mistake there
    assert main(['import-bags', str(simulated / truth[0].bag), '--push-times', str(table), '--out',
                 str(tmp_path / 'd')]) == 2


def _glitched(source, target, t_s, robot='asimo_like', delta_rad=0.3):
    """``source`` with one joint state message at or after ``t_s`` [s] whose hip pitches read
    ``delta_rad`` more (within the URDF's limits: a loose encoder connector)."""
    import numpy as np
    from fall_predictor.contract.topics import JOINT_STATES
    done = False
    with BagWriter(target) as bag:
        for message in iter_messages(source):
            msg = message.msg
            names = list(getattr(msg, 'name', []))
            hips = [names.index(n) for n in names if 'hip_pitch' in n]
            if (not done and message.topic == JOINT_STATES.name and hips
                    and msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 >= t_s):
                position = np.array(msg.position, dtype=float)
                position[hips] += delta_rad
                msg.position = position
                done = True
            bag.write(message.topic, message.msg_type, message.t_ns, msg)
    assert done
    return target


def test_a_jump_in_a_robots_recording_is_a_hole_in_every_tool(simulated, recordings_with_push, tmp_path,
                                                               capsys):
    """A joint-state glitch makes the estimated CoM jump faster than physics allows: the feature
    extractor refuses it, as onboard, and evaluate, train and the per-run table go on, counting
    it; the estimator's own refusals (no estimate yet at the start) are counted too, as many as
    the estimator pipeline gives faults."""
    from fall_predictor.data.estimation import run_pipeline
    truth = read_index(simulated)
    glitch_t = truth[0].t_push + 0.2
    bag = _glitched(recordings_with_push[0], tmp_path / 'glitched', glitch_t)
    data = tmp_path / 'data'
    assert main(['import-bags', str(bag), str(recordings_with_push[1]), '--out', str(data)]) == 0
    capsys.readouterr()
    model = _always_falling_model(tmp_path / 'always.json')
    per_run = tmp_path / 'runs.json'
    assert main(['evaluate', '--data', str(data), '--model', str(model), '--per-run', str(per_run),
                 '--json']) == 0
    evaluation = json.loads(capsys.readouterr().out)
    refused = evaluation['refused_by_trajectory']['traj_00000']
    assert refused['features'] >= 1
    faults = sum(e.measurement is None for e in run_pipeline(bag))
    assert refused['estimator'] == faults
    assert evaluation['refused_samples'] == sum(
        r['total'] for r in evaluation['refused_by_trajectory'].values())
    assert json.loads(per_run.read_text())['runs'][0]['refused_samples'] == refused['total']
    assert main(['train', '--data', str(data), '--tau-plus=-0.25', '--tau-his', '0.02',
                 '--out', str(tmp_path / 'm.json'), '--json']) == 0
    assert json.loads(capsys.readouterr().out)['refused_samples'] == evaluation['refused_samples']
