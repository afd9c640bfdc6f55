"""The fall-predictor command line: simulate, generate and stats."""
import json
import shutil
import subprocess
import sys

import pytest

from fall_predictor.cli import main


def test_simulate_json_reports_the_outcome(capsys):
    assert main(['simulate', '--duration', '3.2', '--push-force', '450', '--push-angle', '0',
                 '--push-height', '0.2', '--push-time', '1.5', '--json']) == 0
    out = json.loads(capsys.readouterr().out)
    assert out['fallen'] is True and 1.6 < out['t_fallen'] <= 3.2
    assert out['push']['impulse_ns'] == pytest.approx(45.0)


def test_simulate_without_push_stays_balanced(capsys):
    assert main(['simulate', '--duration', '1.5', '--json']) == 0
    out = json.loads(capsys.readouterr().out)
    assert out['fallen'] is False and out['t_fallen'] is None and out['push'] is None


def test_invalid_arguments_are_rejected_with_a_message(capsys):
    with pytest.raises(SystemExit) as exc:
        main(['simulate', '--duration', 'nan'])
    assert exc.value.code == 2
    assert 'not a finite number' in capsys.readouterr().err
    assert main(['simulate', '--duration', '1.0', '--push-force', '100', '--push-time', '2.0']) == 2


def test_module_entry_point_has_help_for_every_subcommand():
    for command in ('simulate', 'generate', 'stats'):
        done = subprocess.run([sys.executable, '-m', 'fall_predictor', command, '--help'],
                              capture_output=True, text=True, timeout=60)
        assert done.returncode == 0 and 'usage' in done.stdout


def test_stats_json_and_exit_code_on_a_damaged_dataset(small_dataset, tmp_path, capsys):
    assert main(['stats', str(small_dataset), '--plots', str(tmp_path / 'p'), '--json']) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats['trajectories'] == 8 and not stats['unreadable_bags']
    damaged = tmp_path / 'damaged'
    shutil.copytree(small_dataset, damaged)
    shutil.rmtree(damaged / 'cache', ignore_errors=True)
    mcap = next((damaged / 'bags' / 'traj_00001').glob('*.mcap'))
    mcap.write_bytes(b'garbage')
    assert main(['stats', str(damaged), '--plots', str(tmp_path / 'q'), '--json']) == 1
    stats = json.loads(capsys.readouterr().out)
    assert list(stats['unreadable_bags']) == ['traj_00001']
