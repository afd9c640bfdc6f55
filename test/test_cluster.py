"""``--scheduler``: generate, sweep and robustness on a Dask cluster give what a local run gives
and an interrupted or damaged cluster run still ends in the same dataset.

The cluster is a ``distributed.LocalCluster`` of 2 worker processes (1 thread each) started by
this module: the same scheduler protocol as workers on other machines.
"""
import hashlib
import json
import os
import shutil
import signal
import threading
import time
from pathlib import Path

import distributed        # a declared dependency (requirements.txt: .[cluster]): missing is a failure
import pytest

from fall_predictor.cli import main
from fall_predictor.data import parallel
from fall_predictor.data.generation import GenerationConfig, generate_dataset

TRAJECTORIES = 4
SEED = 11


def _config() -> GenerationConfig:
    return GenerationConfig(seed=SEED, horizon_after_push_s=0.5, pre_push_s=0.2,
                            settle_extension_s=0.0)


def _contents(dataset: Path) -> dict[str, str]:
    """sha256 of every file of the bags and the index: what must not depend on where it ran."""
    return {str(f.relative_to(dataset)): hashlib.sha256(f.read_bytes()).hexdigest()
            for sub in ('bags', 'index') for f in sorted((dataset / sub).rglob('*')) if f.is_file()}


@pytest.fixture(scope='module')
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as local_cluster:
        yield local_cluster


@pytest.fixture(scope='module')
def local_reference(tmp_path_factory) -> Path:
    """The dataset made by one local process."""
    out = tmp_path_factory.mktemp('reference') / 'local'
    generate_dataset(out, TRAJECTORIES, SEED, jobs=1, config=_config(), progress=False)
    return out


def test_generate_on_a_cluster_is_bit_identical_to_a_local_run(cluster, local_reference, tmp_path):
    out = tmp_path / 'cluster'
    rows = generate_dataset(out, TRAJECTORIES, SEED, config=_config(), progress=False,
                            scheduler=cluster.scheduler_address)
    assert len(rows) == TRAJECTORIES
    reference = _contents(local_reference)
    assert len(reference) == 3 * TRAJECTORIES          # MCAP file, metadata.yaml, index row
    assert _contents(out) == reference
    # dataset.json records the CPU time and the machine, per worker: both workers took part.
    cost = json.loads((out / 'dataset.json').read_text())['generation']
    workers = set(cluster.scheduler_info['workers'])
    assert cost['trajectories'] == TRAJECTORIES and cost['cpu_s'] > 0
    (host, record), = cost['machines'].items()
    assert record['cores'] == os.cpu_count() and record['trajectories'] == TRAJECTORIES
    assert set(record['workers']) == workers
    assert cost['runs'][-1]['scheduler'] == cluster.scheduler_address


def test_the_cli_generates_on_a_cluster_and_reports_cpu_and_machines(cluster, local_reference,
                                                                     tmp_path, capsys):
    out = tmp_path / 'cli'
    assert main(['generate', '--trajectories', '2', '--seed', str(SEED),
                 '--horizon', '0.5', '--settle-extension', '0', '--out', str(out),
                 '--scheduler', cluster.scheduler_address,
                 '--json']) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload['scheduler'] == cluster.scheduler_address and payload['cpu_s'] > 0
    assert sum(m['trajectories'] for m in payload['machines'].values()) == 2
    # Same trajectories as the library call with the CLI's settings, made locally.
    local = tmp_path / 'local'
    generate_dataset(local, 2, SEED, progress=False,
                     config=GenerationConfig(seed=SEED, horizon_after_push_s=0.5,
                                             settle_extension_s=0.0))
    assert _contents(out) == _contents(local)


def test_an_interrupted_run_resumes_on_a_cluster_to_the_same_dataset(cluster, local_reference,
                                                                     tmp_path):
    out = tmp_path / 'resumed'
    # Interrupted: two trajectories finished locally, a third half written (no index row).
    generate_dataset(out, 2, SEED, config=_config(), progress=False)
    finished = {p: p.stat().st_mtime_ns for p in (out / 'index').glob('*.json')}
    shutil.copytree(out / 'bags' / 'traj_00000', out / 'bags' / 'traj_00002.partial')
    generate_dataset(out, TRAJECTORIES, SEED, config=_config(), progress=False,
                     scheduler=cluster.scheduler_address)
    assert {p: p.stat().st_mtime_ns for p in finished} == finished      # not redone
    assert not (out / 'bags' / 'traj_00002.partial').exists()
    assert _contents(out) == _contents(local_reference)
    cost = json.loads((out / 'dataset.json').read_text())['generation']
    assert cost['trajectories'] == TRAJECTORIES
    assert [run['simulated_trajectories'] for run in cost['runs']] == [2, 2]


def test_a_worker_killed_mid_run_costs_only_its_trajectory(local_reference, tmp_path):
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as own_cluster, \
            distributed.Client(own_cluster.scheduler_address) as observer:
        killed = {}

        def kill_a_busy_worker():
            deadline = time.monotonic() + 60.0
            while time.monotonic() < deadline:
                busy = [address for address, tasks in observer.processing().items() if tasks]
                if busy:
                    time.sleep(0.5)                    # well inside a trajectory (~2 s of CPU)
                    pids = observer.run(os.getpid, workers=busy[:1])
                    killed['worker'], killed['pid'] = next(iter(pids.items()))
                    killed['finished'] = len(list((tmp_path / 'killed' / 'index').glob('*.json')))
                    os.kill(killed['pid'], signal.SIGKILL)
                    return
                time.sleep(0.05)

        killer = threading.Thread(target=kill_a_busy_worker)
        killer.start()
        generate_dataset(tmp_path / 'killed', TRAJECTORIES, SEED, config=_config(), progress=False,
                         scheduler=own_cluster.scheduler_address)
        killer.join()
        assert 'pid' in killed, 'no worker was busy'
        assert killed['finished'] < TRAJECTORIES          # killed while work was left
        assert killed['worker'] not in observer.scheduler_info()['workers']
    assert _contents(tmp_path / 'killed') == _contents(local_reference)


def _sweep_results(out: Path) -> dict:
    """sweep.json without what depends on the machine (wall times, the command line)."""
    document = json.loads((out / 'sweep.json').read_text())

    def strip(value):
        if isinstance(value, dict):
            return {k: strip(v) for k, v in value.items()
                    if k not in ('timing', 'command', 'fit_s', 'data_dir', 'files') and not k.endswith('wall_s')}
        if isinstance(value, list):
            return [strip(v) for v in value]
        return value
    return strip(document)


def test_sweep_on_a_cluster_equals_the_local_sweep(cluster, small_dataset, tmp_path):
    data = tmp_path / 'data'
    shutil.copytree(small_dataset, data)
    arguments = ['sweep', '--data', str(data), '--quick', '--folds', '2', '--tau-plus=-0.25,0.25',
                 '--tau-his', '0,0.06', '--no-learning-curve', '--no-capture-point', '--json']
    assert main(arguments + ['--out', str(tmp_path / 'local')]) == 0
    transitions = cluster.scheduler.transition_counter
    assert main(arguments + ['--out', str(tmp_path / 'cluster'),
                             '--scheduler', cluster.scheduler_address]) == 0
    # The trainings went through the cluster's scheduler (not a silent local run).
    assert cluster.scheduler.transition_counter > transitions
    local, remote = _sweep_results(tmp_path / 'local'), _sweep_results(tmp_path / 'cluster')
    assert local['points'] and local == remote


def test_robustness_on_a_cluster_equals_the_local_table(cluster, capsys):
    arguments = ['robustness', '--impulses', '25', '--phases', '1', '--horizon', '0.5', '--json']
    assert main(arguments) == 0
    local = json.loads(capsys.readouterr().out)
    assert main(arguments + ['--scheduler', cluster.scheduler_address]) == 0
    remote = json.loads(capsys.readouterr().out)
    assert len(local['survived'][0]) == 8
    assert {k: v for k, v in local.items() if k != 'wall_s'} == \
           {k: v for k, v in remote.items() if k != 'wall_s'}


def test_an_address_without_a_scheduler_is_one_clear_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(parallel, 'CONNECT_TIMEOUT_S', 2.0)
    assert main(['generate', '--trajectories', '1', '--out', str(tmp_path / 'd'),
                 '--scheduler', 'tcp://127.0.0.1:9', '--json']) == 2
    assert 'tcp://127.0.0.1:9' in capsys.readouterr().err
