"""Sensor topics in generated bags, and `fall-predictor estimation-error` over them."""
import json

import numpy as np
import pytest

from fall_predictor.cli import main
from fall_predictor.data.dataset import read_index, read_manifest
from fall_predictor.data.estimation import estimate_bag, summarise
from fall_predictor.data.sensorbag import read_robot_description, read_sensor_messages, read_sensor_params
from fall_predictor.profiles import asimo_like_urdf as rm


@pytest.fixture(scope='module')
def sensor_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp('sensors') / 'data'
    assert main(['generate', '--trajectories', '1', '--seed', '3', '--out', str(out), '--horizon', '0.6',
                 '--sensor-noise', '1', '--json']) == 0
    return out


def test_bags_carry_the_sensor_topics_parameters_and_description(sensor_dataset):
    row = read_index(sensor_dataset)[0]
    bag = sensor_dataset / row.bag
    streams: dict[str, list] = {'joints': [], 'imu': [], 'l': [], 'r': []}
    for stream, reading in read_sensor_messages(bag):
        streams[stream].append(reading)
    # The simulator's timing: every stream once per recorded step, at 1 kHz.
    assert {k: len(v) for k, v in streams.items()} == dict.fromkeys(streams, row.samples)
    assert np.diff([r.stamp_ns for r in streams['joints']]) == pytest.approx(1_000_000)
    assert streams['joints'][0].names == rm.JOINT_NAMES
    assert streams['imu'][0].frame_id == rm.PROFILE.imu_frame
    assert (streams['l'][0].frame_id, streams['r'][0].frame_id) == rm.SOLE_FRAMES
    # The robot's weight is on its soles (42.1 kg x 9.81), on average over the walk.
    fz = np.mean([a.wrench[2] + b.wrench[2] for a, b in zip(streams['l'], streams['r'])])
    assert fz == pytest.approx(413.0, rel=0.1)
    params = read_sensor_params(bag)
    assert params['noise_scale'] == 1.0 and params['timing']['joint_rate_hz'] == 1000.0
    assert {k: v for k, v in params.items() if k != 'timing'} == read_manifest(sensor_dataset)['sensors']
    assert read_robot_description(bag) == rm.URDF_PATH.read_text()


def test_estimation_error_json_has_exactly_the_specified_fields(sensor_dataset, capsys):
    assert main(['estimation-error', '--data', str(sensor_dataset), '--json']) == 0
    result = json.loads(capsys.readouterr().out)
    quantities = ['com_m', 'linear_momentum_kg_m_s', 'angular_momentum_kg_m2_s', 'cop_m']
    assert sorted(result) == sorted(quantities + ['contact_mode_agreement'])
    for q in quantities:
        assert sorted(result[q]) == ['median', 'p99', 'post_push_median', 'post_push_p99']
    # An independent recomputation over the bag agrees with what the command reported.
    row = read_index(sensor_dataset)[0]
    b = estimate_bag(sensor_dataset / row.bag)
    ok = [i for i, m in enumerate(b.estimated) if m is not None]
    com = np.array([np.linalg.norm(b.estimated[i].com - b.truth[i].com) for i in ok])
    assert result['com_m']['median'] == pytest.approx(np.median(com))
    assert result['com_m']['p99'] <= 0.010
    assert result['linear_momentum_kg_m_s']['median'] <= 0.3
    assert result['contact_mode_agreement'] >= 0.97


def test_a_dataset_without_sensor_topics_is_a_clear_error(tmp_path, capsys):
    out = tmp_path / 'plain'
    assert main(['generate', '--trajectories', '1', '--seed', '3', '--out', str(out), '--horizon', '0.2',
                 '--json']) == 0
    assert main(['estimation-error', '--data', str(out), '--json']) != 0
    assert 'robot_description' in capsys.readouterr().err


def test_summary_of_known_errors():
    per_bag = [{'com_m': np.array([0.0, 0.01, 0.02, np.nan]), 'linear_momentum_kg_m_s': np.ones(4),
                'angular_momentum_kg_m2_s': np.zeros(4), 'cop_m': np.full(4, np.nan),
                'post_push': np.array([False, True, True, False]),
                'mode_agree': np.array([True, True, False, True])}]
    s = summarise(per_bag)
    assert s['com_m']['median'] == pytest.approx(0.01)
    assert s['com_m']['post_push_median'] == pytest.approx(0.015)
    assert s['cop_m']['median'] is None
    assert s['contact_mode_agreement'] == 0.75


def test_the_sensor_topic_table_is_consistent():
    from fall_predictor.contract.topics import (LATCHED_QOS, SENSOR_TOPICS, SENSOR_TOPICS_BY_NAME, SIM_RATE_HZ,
                                            STREAM_QOS, TOPICS_BY_NAME)
    assert len(SENSOR_TOPICS_BY_NAME) == len(SENSOR_TOPICS) == 6
    for spec in SENSOR_TOPICS:
        assert spec.qos == (STREAM_QOS if spec.rate_hz == SIM_RATE_HZ else LATCHED_QOS), spec.name
        # /joint_states is the same topic and type as the base table's, at 1 kHz.
        if spec.name in TOPICS_BY_NAME:
            assert TOPICS_BY_NAME[spec.name].msg_type == spec.msg_type
    # The frames are the robot's (its profile names them): the table shows placeholders.
    assert SENSOR_TOPICS_BY_NAME['/left_foot/wrench'].frame_id == '(F/T frame)'
    assert SENSOR_TOPICS_BY_NAME['/robot_description'].qos.durability == 'transient_local'
