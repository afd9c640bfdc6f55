"""The fall-predictor command line: every subcommand, with and without ROS installed."""
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


def test_module_entry_point_runs_the_tool():
    done = subprocess.run([sys.executable, '-m', 'fall_predictor', 'simulate', '--help'],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.startswith('usage: fall-predictor simulate')


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


SUBCOMMANDS = ('simulate', 'generate', 'stats', 'train', 'rules', 'evaluate', 'fit-direction',
               'fit-time-to-fall', 'sweep', 'import-bags', 'bringup', 'robustness', 'repair-bag', 'estimation-error',
               'calibrate', 'render', 'check')

#: Makes every ROS 2 Python package unimportable (rclpy, message packages, ament, launch), as
#: on a machine without ROS; then runs the command line given as JSON on argv[1], one
#: invocation per list element, and prints the exit codes and whether ROS got imported.
_WITHOUT_ROS = r'''
import importlib.abc, json, sys

class NoRos(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        top = name.split('.')[0]
        if (top.startswith(('rclpy', 'rosidl', 'rcl_', 'ament', 'launch', 'builtin_interfaces'))
                or top.endswith(('_msgs', '_srvs', '_interfaces'))):
            raise ModuleNotFoundError(f'No module named {name!r} (ROS blocked by the test)')
        return None

sys.meta_path.insert(0, NoRos())
from fall_predictor.cli import main
codes = []
for argv in json.loads(sys.argv[1]):
    try:
        codes.append(main(argv))
    except SystemExit as done:
        codes.append(done.code)
ros = sorted(m for m in sys.modules if m.split('.')[0] == 'rclpy' or m.endswith('_msgs'))
print(json.dumps({'codes': codes, 'ros_modules': ros}))
'''


def _run_without_ros(invocations: list[list[str]], timeout_s: float = 600) -> dict:
    done = subprocess.run([sys.executable, '-c', _WITHOUT_ROS, json.dumps(invocations)],
                          capture_output=True, text=True, timeout=timeout_s)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1]) | {'stderr': done.stderr}


def test_help_for_the_tool_and_every_subcommand_needs_no_ros():
    from fall_predictor.cli import build_parser
    subparsers = next(a for a in build_parser()._actions if a.dest == 'command')
    assert set(subparsers.choices) == set(SUBCOMMANDS)     # a new subcommand joins this test
    result = _run_without_ros([['--help']] + [[command, '--help'] for command in SUBCOMMANDS])
    assert result['codes'] == [0] * (1 + len(SUBCOMMANDS))
    assert result['ros_modules'] == []


def test_every_offline_subcommand_runs_without_ros(small_dataset, tmp_path):
    data = tmp_path / 'data'
    shutil.copytree(small_dataset, data)
    model = tmp_path / 'model.json'
    result = _run_without_ros([
        ['simulate', '--duration', '0.3', '--json'],
        ['generate', '--trajectories', '1', '--seed', '3', '--horizon', '0.2', '--settle-extension', '0',
         '--out', str(tmp_path / 'generated'), '--json'],
        ['stats', str(data), '--plots', str(tmp_path / 'plots'), '--json'],
        ['train', '--data', str(data), '--tau-plus', '0', '--out', str(model)],
        ['rules', str(model)],
        # the model's window, chosen by train on the same data
        ['evaluate', '--data', str(data), '--model', str(model), '--json'],
        # its triggers: too few falls to learn a direction from (refused in words), enough for
        # a time to fall
        ['fit-direction', '--data', str(data), '--model', str(model), '--out', str(tmp_path / 'm.json')],
        ['fit-time-to-fall', '--data', str(data), '--model', str(model), '--out',
         str(tmp_path / 't.json'), '--json'],
        ['sweep', '--data', str(data), '--out', str(tmp_path / 'sweep'), '--folds', '2',
         '--tau-plus', '0', '--tau-his', '0,0.01', '--no-learning-curve', '--no-capture-point'],
        ['import-bags', str(data / 'bags' / 'traj_00000'), '--out', str(tmp_path / 'imported')],
        ['bringup', '--pushes', '1'],
        ['robustness', '--impulses', '5', '--phases', '1', '--horizon', '0.2', '--json'],
        ['repair-bag', str(data / 'bags'), '--json'],           # intact bags: nothing to do
    ])
    assert result['codes'] == [0, 0, 0, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0], result['stderr'][-3000:]
    assert result['ros_modules'] == []
    assert 'bringup needs ROS 2' in result['stderr']
    assert 'too few to learn a fall direction' in result['stderr'] and not (tmp_path / 'm.json').exists()
    assert (tmp_path / 't.json').exists()
    assert (tmp_path / 'generated' / 'index' / 'traj_00000.json').exists()
    assert (tmp_path / 'sweep' / 'sweep.json').exists() and model.exists()


def _session_processes(session_id: int) -> list[int]:
    """Processes of the machine still in the session ``session_id``."""
    import os
    from pathlib import Path
    pids = []
    for stat in Path('/proc').glob('[0-9]*/stat'):
        try:
            fields = stat.read_text().rsplit(')', 1)[1].split()
        except OSError:
            continue                        # ended while we looked
        if int(fields[3]) == session_id and fields[0] != 'Z':
            pids.append(int(stat.parent.name))
    return [p for p in pids if p != os.getpid()]


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='reads /proc')
def test_sigterm_stops_generate_and_its_worker_processes(tmp_path):
    """A terminated generate (SIGTERM, as a job scheduler or a `kill` sends it) takes its joblib
    workers with it: no process of its session is left afterwards; rerunning finishes the set."""
    import time
    from pathlib import Path
    out = tmp_path / 'd'
    command = [sys.executable, '-m', 'fall_predictor.cli', 'generate', '--trajectories', '6',
               '--seed', '3', '--horizon', '1.0', '--settle-extension', '0', '--jobs', '2',
               '--out', str(out), '--json']
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               start_new_session=True)
    deadline = time.monotonic() + 120.0
    while len(_session_processes(process.pid)) < 3:         # the tool and its two workers
        assert process.poll() is None and time.monotonic() < deadline, process.stderr.read()
        time.sleep(0.1)
    process.terminate()
    process.wait(timeout=60)
    assert process.returncode != 0
    deadline = time.monotonic() + 30.0
    while _session_processes(process.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _session_processes(process.pid) == []
    process.stderr.close()
    assert main(command[3:-1] + ['--json']) == 0
    assert len(list(Path(out, 'bags').iterdir())) == 6


@pytest.mark.parametrize('argv, robot, gait_variety, force_n', [
    ([], 'asimo_like', True, (0.0, 500.0)),
    (['--fixed-gait'], 'asimo_like', False, (0.0, 500.0)),
    # The G1's profile: its own push range, its own gait (gait_variety: false).
    (['--robot', 'g1'], 'g1', False, (0.0, 200.0)),
])
def test_generate_takes_the_push_range_and_the_gait_draws_from_the_robot_profile(argv, robot, gait_variety,
                                                                                 force_n):
    from fall_predictor.cli import build_parser
    from fall_predictor.cli.dataset import generation_config
    config = generation_config(build_parser().parse_args(['generate', '--trajectories', '2', '--out', 'x']
                                                         + argv))
    assert config.robot == robot
    assert config.gait_variety is gait_variety
    assert tuple(config.push_distribution.force_n) == force_n


@pytest.mark.parametrize('robot, legs, upper_body', [('asimo_like', 12, 14), ('g1', 12, 17)])
def test_generate_with_the_robot_timing_splits_that_robots_own_joints(robot, legs, upper_body):
    """``--sensor-timing robot`` splits the joint states into the robot's legs and upper body, from
    its profile (the G1's generation refused its own joints while the ASIMO-like robot's names
    were written into the command)."""
    from fall_predictor.cli import build_parser
    from fall_predictor.cli.dataset import generation_config
    from fall_predictor.profiles.profile import load_profile
    config = generation_config(build_parser().parse_args(
        ['generate', '--trajectories', '2', '--out', 'x', '--robot', robot,
         '--sensor-noise', '1', '--sensor-timing', 'robot', '--joint-rate-hz', '500']))
    groups = config.timing().joint_groups
    assert [len(g) for g in groups] == [legs, upper_body]
    assert sorted(groups[0] + groups[1]) == sorted(load_profile(robot).joint_names)
    assert config.timing().joint_rate_hz == 500.0


def test_fit_time_to_fall_replaces_the_regressor_and_keeps_the_decisions(small_dataset, tmp_path,
                                                                          capsys):
    """``fit-time-to-fall`` writes the model with boosted trees fitted at its triggers (method
    §8d); its decision lists, settings and direction are the input model's."""
    from fall_predictor.monitor.boosted_trees import BoostedTimeToFall
    from fall_predictor.monitor.model_file import load_model
    from fall_predictor.monitor.time_to_fall import TimeToFallRegressor
    data = tmp_path / 'data'
    shutil.copytree(small_dataset, data)
    model, fitted = tmp_path / 'model.json', tmp_path / 'fitted.json'
    assert main(['train', '--data', str(data), '--tau-plus', '0', '--tau-his-recommended', '0.01',
                 '--out', str(model)]) == 0
    assert main(['fit-time-to-fall', '--data', str(data), '--model', str(model), '--out',
                 str(fitted), '--json']) == 0
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    lists, before = load_model(model)
    lists_after, after = load_model(fitted)
    assert isinstance(before.time_to_fall, TimeToFallRegressor)
    assert isinstance(after.time_to_fall, BoostedTimeToFall) and report['trees'] == 100
    assert report['triggers'] >= 1 and report['samples'] >= report['triggers']
    assert lists_after == lists and after.recommended_tau_his_s == before.recommended_tau_his_s
    assert after.feature_settings == before.feature_settings
