"""A model for a robot and its controller, made as the README's "A model for your robot and your
controller" says, one command per step, on a few runs of the G1 under Unitree's policy in MuJoCo:
calibrate the push range, generate, train (the window chosen on the data), evaluate per run,
render. Each step's output is checked against what the step before made."""
from __future__ import annotations

import csv
import json

import pytest

from fall_predictor import cli
from fall_predictor.data.dataset import read_index, read_manifest
from fall_predictor.monitor.model_file import load_model

ROBOT = 'g1_12dof'


def run(capsys, *argv: str) -> dict:
    code = cli.main([*argv, '--json'])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return json.loads(captured.out.strip().splitlines()[-1])


def test_a_model_for_the_g1_under_its_policy_one_command_per_step(tmp_path, capsys) -> None:
    # 1. Calibrate: the dataset protocol with forces up to a probe, a range suggested.
    calibration = run(capsys, 'calibrate', '--robot', ROBOT, '--trajectories', '3', '--seed', '1',
                      '--probe-force', '1500')
    assert calibration['runs'] == 3 and 0.0 < calibration['suggested_push_force_n'][1]
    assert calibration['setup']['controller'] == 'unitree_rl_gym'
    # 2. Generate (a short horizon: the test's runs, not a dataset's): the policy's own protocol.
    data = tmp_path / 'dev'
    made = run(capsys, 'generate', '--robot', ROBOT, '--trajectories', '6', '--seed', '2',
               '--horizon', '1.5', '--settle-extension', '0', '--out', str(data))
    rows = read_index(data)
    assert made['trajectories'] == 6 and 0 < made['fallen'] < 6
    assert all(r.command_vx_m_s is not None and r.gait_speed_m_s is None for r in rows)
    manifest = read_manifest(data)
    assert manifest['controller']['name'] == 'unitree_rl_gym' and manifest['simulator'] == 'mujoco'
    # 3. Train: the window chosen by cross-validation on the data and stored.
    model = tmp_path / 'model.json'
    trained = run(capsys, 'train', '--data', str(data), '--tau-plus=-0.25', '--folds', '3',
                  '--out', str(model))
    _, metadata = load_model(model)
    assert metadata.recommended_tau_his_s == trained['tau_his_chosen']['tau_his_s']
    # 4. Evaluate per run: one row per run, its label the index's, each fall caught or missed.
    per_run = tmp_path / 'runs.csv'
    result = run(capsys, 'evaluate', '--data', str(data), '--model', str(model),
                 '--per-run', str(per_run))
    table = list(csv.DictReader(per_run.open()))
    assert [r['trajectory_id'] for r in table] == [r.trajectory_id for r in rows]
    assert [r['fallen'] == '1' for r in table] == [r.fallen for r in rows]
    assert sum(r['missed'] == '1' for r in table) == result['n_missed']
    assert result['tau_his_s'] == metadata.recommended_tau_his_s
    # 5. Render a push of the robot under its policy.
    image = tmp_path / 'push.png'
    rendered = run(capsys, 'render', '--robot', ROBOT, '--command', '0.3', '0', '0', '--force',
                   '200', '--onset', '2.0', '--after', '0.3', '--frames', '2', '--out', str(image))
    assert rendered['frames'] == 2 and image.stat().st_size > 10_000
    assert rendered['controller'] == 'unitree_rl_gym' and not rendered['fallen']


@pytest.mark.parametrize('argv, words', [
    (('simulate', '--robot', 'g1_12dof', '--controller', 'nobody'), "has no controller 'nobody'"),
    (('generate', '--robot', 'asimo_like', '--controller', 'unitree_rl_gym', '--trajectories', '1',
      '--out', 'x'), "has no controller 'unitree_rl_gym'"),
])
def test_a_controller_the_robot_does_not_have_is_refused_in_words(capsys, argv, words) -> None:
    code = cli.main(list(argv))
    assert code != 0 and words in capsys.readouterr().err
