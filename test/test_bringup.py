"""Bring-up: the nodes as processes, two pushes in a row, JSON lines, clean shutdown."""
from __future__ import annotations

import dataclasses
import io
import json
from pathlib import Path

import pytest

from test_nodes_support import MOMENTUM_THRESHOLD, test_domain_id, write_momentum_model

from fall_predictor.data.bagio import read_trajectory
from fall_predictor.cli import build_parser
from fall_predictor.ros.bringup import node_overrides, run_bringup
from fall_predictor.monitor.records import PushSpec
from fall_predictor.sim.pushes import PushDistribution, trajectory_seed

SEED = 4            # two strong pushes (472 N and 490 N) at about 2.2 s: short runs
PUSHES = 2
HORIZON_S = 0.5


def _node_processes_on(domain_id: int) -> list[int]:
    """Pids of fall_predictor node processes running on ``domain_id``."""
    pids = []
    for proc in Path('/proc').iterdir():
        if not proc.name.isdigit():
            continue
        try:
            cmdline = (proc / 'cmdline').read_bytes()
            environ = (proc / 'environ').read_bytes().split(b'\0')
        except OSError:
            continue                                # gone, or not ours to read
        if b'fall_predictor.ros.' in cmdline and f'ROS_DOMAIN_ID={domain_id}'.encode() in environ:
            pids.append(int(proc.name))
    return pids


def test_bringup_pushes_reports_json_and_leaves_no_process(tmp_path: Path) -> None:
    domain = test_domain_id(140)
    out = io.StringIO()
    results = run_bringup(PUSHES, SEED, out, domain_id=domain,
                          model_path=write_momentum_model(tmp_path / 'model.json'),
                          record_dir=tmp_path / 'bags', horizon_s=HORIZON_S,
                          log_dir=tmp_path / 'logs')
    assert _node_processes_on(domain) == []
    assert [json.loads(line) for line in out.getvalue().splitlines()] == results
    for index, result in enumerate(results):
        push = PushDistribution().sample(trajectory_seed(SEED, index))
        assert result['index'] == index and result['seed'] == SEED
        assert result['push']['force_n'] == push.force_n and result['push']['t_push'] == push.t_push
        assert result['push_applied_world_n'] is not None
        # Both pushes exceed the model's momentum threshold: predicted, C_fall took over.
        # Not before the recorded momentum crossed the threshold; how much later depends on the
        # samples the best-effort monitor lost keeping up with the unpaced simulation.
        recorded = read_trajectory(tmp_path / 'bags' / f'run_{index:03d}')
        t_cross = next(m.t for m in recorded.measurements if m.t >= push.t_push
                       and max(abs(m.lin_mom[0]), abs(m.lin_mom[1])) > MOMENTUM_THRESHOLD)
        assert t_cross < push.t_force_end
        assert t_cross <= result['t_predict'] <= (result['t_fallen'] or result['t_end'])
        assert result['controller_mode'] == 'fall'
        assert result['outcome'] in ('fall_predicted', 'predicted_no_fall')
        assert result['fell'] == (result['t_fallen'] is not None)
        if result['fell']:
            assert result['lead_time_s'] == round(result['t_fallen'] - result['t_predict'], 6)
            assert result['stopped_by'] == 'fallen'
        else:
            assert result['lead_time_s'] is None and result['stopped_by'] == 'horizon'
            assert result['t_end'] >= push.t_force_end + HORIZON_S - 1e-9
        assert not result['false_alarm_before_push']
        assert sum(result['degraded_reasons'].values()) == result['degraded_states']
    bags = sorted((tmp_path / 'bags').glob('run_*'))
    assert [b.name for b in bags] == ['run_000', 'run_001']
    for index, bag in enumerate(bags):
        recorded = read_trajectory(bag)
        assert recorded.measurements[0].t == 0.0
        assert [p.t for p in recorded.pushes] == [results[index]['push']['t_push']]


def test_bringup_arguments() -> None:
    args = build_parser().parse_args(['bringup', '--pushes', '3', '--seed', '7', '--json',
                                      '--real-time-factor', '1'])
    assert (args.pushes, args.seed, args.json, args.real_time_factor) == (3, 7, True, 1.0)
    assert args.domain_id is None and args.record is None
    assert args.sensors                 # the estimator in the loop, as on a robot, by default
    assert not build_parser().parse_args(['bringup', '--true-state']).sensors


def test_an_unpaced_run_checks_no_sample_age_a_paced_run_does() -> None:
    """Unpaced, simulated time is not wall time: a predictor lagging /clock on a busy machine
    would answer STALE by the machine's load (a DDS test run's predictor logged samples
    0.07-0.13 s late at a push), so the bring-up switches the age check off; paced, it stays
    on."""
    for sensors, record in ((False, None), (True, Path('bags'))):
        names, unpaced = node_overrides(0.0, None, True, sensors, 'robot', 'asimo_like', record)
        assert set(names) == set(unpaced) and 'predictor_node' in names
        assert unpaced['predictor_node']['max_sample_age_s'] == '0.0'
        assert unpaced['simulator_node']['real_time_factor'] == '0.0'
        _, paced = node_overrides(1.0, None, True, sensors, 'robot', 'asimo_like', record)
        assert 'max_sample_age_s' not in paced['predictor_node']
        assert paced['simulator_node']['real_time_factor'] == '1.0'


def test_record_live_with_c_bal_throughout_then_import_and_train(tmp_path: Path) -> None:
    """Offline from live: bring-up records (C_bal in charge), import the bags, train on them."""
    from fall_predictor.cli import main as cli_main
    from fall_predictor.data.recording_import import import_recordings
    from fall_predictor.monitor.model_file import load_model

    results = run_bringup(PUSHES, SEED, None, domain_id=test_domain_id(150),
                          model_path=write_momentum_model(tmp_path / 'model.json'),
                          record_dir=tmp_path / 'bags', horizon_s=2.0, log_dir=tmp_path / 'logs',
                          fall_trigger=False)
    # The predictor still says falling, but the controller never hands over.
    assert all(r['controller_mode'] == 'balance' and r['t_predict'] is not None for r in results)
    report = import_recordings(sorted((tmp_path / 'bags').glob('run_*')), tmp_path / 'data')
    assert not report.rejected and len(report.rows) == PUSHES
    for row, result in zip(report.rows, results):
        assert row.t_push == result['push']['t_push']
        assert row.force_n == pytest.approx(result['push']['force_n'], rel=1e-6)
        assert row.fallen == result['fell']
        if row.fallen:
            # The bring-up's own observer sees the fall when the bag does, unless it lost
            # samples (its queue overflows on a saturated machine): then late by at most what it
            # lost, never early.
            late_s = result['t_fallen'] - row.t_fallen
            assert -1e-9 <= late_s <= 0.001 * result['observer_lost_samples'] + 1e-9, result
    assert cli_main(['train', '--data', str(tmp_path / 'data'), '--tau-plus=0', '--out',
                     str(tmp_path / 'trained.json')]) == 0
    lists, metadata = load_model(tmp_path / 'trained.json')
    assert metadata.tau_plus_s == 0.0 and sum(lists.rule_sizes) > 0


def test_recordings_where_c_fall_took_over_are_rejected(tmp_path: Path) -> None:
    from fall_predictor.data.recording_import import import_recordings

    run_bringup(1, SEED, None, domain_id=test_domain_id(160),
                model_path=write_momentum_model(tmp_path / 'model.json'),
                record_dir=tmp_path / 'bags', horizon_s=HORIZON_S, log_dir=tmp_path / 'logs')
    report = import_recordings(sorted((tmp_path / 'bags').glob('run_*')), tmp_path / 'data')
    assert report.rows == [] and 'C_fall took over' in next(iter(report.rejected.values()))


class _Pushes:
    """The given pushes, one per run, in order (run_bringup asks its push distribution for one
    push per run)."""

    def __init__(self, *pushes: PushSpec):
        self._pushes = iter(pushes)

    def sample(self, rng, gait=None) -> PushSpec:
        return next(self._pushes)


#: SEED's first push (472 N at 4 deg, 0.24 m, 2.213 s into the default walk) and the same push
#: at 100 N. Offline (sim.trajectory.run_trajectory, C_bal throughout, 3 s after the push) the
#: robot survives this push at 0 to 250 N and falls from 300 N; at 472 N it falls 0.66 s after
#: the push ends. The 100 N push raises the horizontal momentum to 14.4 kg m/s (9.6 while
#: walking), under the hand-built model's 25; the 472 N push passes 25 at 2.256 s.
LARGE_PUSH = PushDistribution().sample(trajectory_seed(SEED, 0))
SMALL_PUSH = dataclasses.replace(LARGE_PUSH, force_n=100.0)
SENSORS_HORIZON_S = 0.8     # past the fall with C_bal (0.66 s) and with C_fall (0.43 s)


def test_bringup_with_sensors_runs_the_estimator_in_the_loop(tmp_path: Path) -> None:
    # The simulator publishes only sensor topics (and the truth on its own topic); the
    # measurement every other node reads comes from state_estimator_node. What the estimated
    # state makes of the two pushes is what the physics gives: the small one is neither
    # predicted nor a fall, the large one is predicted during the push and the robot falls.
    domain = test_domain_id(155)
    small, large = run_bringup(2, SEED, None, domain_id=domain,
                               model_path=write_momentum_model(tmp_path / 'model.json'),
                               horizon_s=SENSORS_HORIZON_S, log_dir=tmp_path / 'logs',
                               sensors=True, push_distribution=_Pushes(SMALL_PUSH, LARGE_PUSH))
    assert _node_processes_on(domain) == []
    assert small['push']['force_n'] == SMALL_PUSH.force_n
    assert small['outcome'] == 'no_fall'
    assert small['t_predict'] is None and small['controller_mode'] == 'balance'
    assert small['stopped_by'] == 'horizon'
    assert small['t_end'] >= SMALL_PUSH.t_force_end + SENSORS_HORIZON_S - 1e-9
    assert large['push']['force_n'] == LARGE_PUSH.force_n
    assert large['outcome'] == 'fall_predicted'
    assert LARGE_PUSH.t_push <= large['t_predict'] <= LARGE_PUSH.t_force_end
    assert large['controller_mode'] == 'fall' and large['stopped_by'] == 'fallen'
    assert large['t_predict'] < large['t_fallen'] < LARGE_PUSH.t_force_end + SENSORS_HORIZON_S
    log = (tmp_path / 'logs' / 'state_estimator_node.log').read_text()
    assert 'robot description: 42.10 kg, 26 joints' in log


def test_a_node_that_ignores_sigint_and_sigterm_is_aborted_with_its_stacks_in_its_log(tmp_path: Path) -> None:
    # A hung node must neither hold the bring-up forever nor vanish without a trace: after
    # SIGINT and SIGTERM it gets SIGABRT, and faulthandler writes where it was stuck.
    import sys
    import time

    from fall_predictor.ros.bringup import start_process, stop_nodes
    stuck = ('import signal, time\n'
             'signal.signal(signal.SIGINT, signal.SIG_IGN)\n'
             'signal.signal(signal.SIGTERM, signal.SIG_IGN)\n'
             'def wait_forever():\n'
             '    print("ready", flush=True)\n'
             '    while True:\n'
             '        time.sleep(0.05)\n'
             'wait_forever()\n')
    node = start_process('predictor_node', [sys.executable, '-c', stuck], {'PATH': '/usr/bin:/bin'}, tmp_path)
    deadline = time.monotonic() + 20.0
    while 'ready' not in node.log_tail() and time.monotonic() < deadline:
        time.sleep(0.05)
    started = time.monotonic()
    codes = stop_nodes({'predictor_node': node}, sigint_timeout_s=0.5, term_timeout_s=0.5)
    assert codes == {'predictor_node': -6}
    assert time.monotonic() - started < 5.0
    log = node.log_path.read_text()
    assert 'most recent call first' in log and 'wait_forever' in log
