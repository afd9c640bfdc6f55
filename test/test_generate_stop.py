"""``fall-predictor generate`` as a process: SIGTERM ends it between two runs with one line and no
traceback, the index counting only the runs committed; a second writer into the same folder is
refused while the first runs; running the command again finishes the dataset."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from fall_predictor.data.dataset_writer import LOCK_FILE

#: A tiny dataset: the ASIMO-like robot's default gait (simulated once), 0.5 s after each push.
TRAJECTORIES = 6
WAIT_S = 300.0


def generate(out: Path) -> subprocess.Popen:
    command = [sys.executable, '-m', 'fall_predictor.cli.main', 'generate', '--trajectories',
               str(TRAJECTORIES), '--seed', '1', '--horizon', '0.5', '--settle-extension', '0',
               '--fixed-gait', '--jobs', '1', '--out', str(out)]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, 'PYTHONPATH': str(Path(__file__).resolve().parents[1])})


def wait_for(condition, what: str) -> None:
    deadline = time.monotonic() + WAIT_S
    while not condition():
        assert time.monotonic() < deadline, f'no {what} within {WAIT_S} s'
        time.sleep(0.05)


def lines(text: str) -> list[str]:
    """The lines of a stderr, the progress bar's carriage-return updates apart."""
    return [line for chunk in text.split('\n') for line in chunk.split('\r') if line.strip()]


def test_sigterm_ends_generate_cleanly_and_a_second_writer_is_refused(tmp_path):
    out = tmp_path / 'data'
    first = generate(out)
    try:
        wait_for(lambda: (out / LOCK_FILE).exists(), 'lock file')
        assert json.loads((out / LOCK_FILE).read_text())['pid'] == first.pid
        # A second writer with the same settings into the same folder: refused, naming the first.
        second = generate(out)
        _, err = second.communicate(timeout=WAIT_S)
        assert second.returncode == 2
        [said] = [line for line in lines(err) if line.startswith('fall-predictor generate:')]
        assert f'another writer (generate, pid {first.pid}) is writing into this dataset' in said
        wait_for(lambda: len(list((out / 'index').glob('traj_*.json'))) >= 1, 'committed run')
        first.send_signal(signal.SIGTERM)
        _, err = first.communicate(timeout=WAIT_S)
    finally:
        first.kill()
    assert first.returncode == 128 + signal.SIGTERM
    assert 'Traceback' not in err and 'KeyboardInterrupt' not in err, err
    [said] = [line for line in lines(err) if line.startswith('fall-predictor generate:')]
    committed = sorted(p.stem for p in (out / 'index').glob('traj_*.json'))
    assert 1 <= len(committed) < TRAJECTORIES
    runs = 'run' if len(committed) == 1 else 'runs'
    assert said == (f'fall-predictor generate: stopped by SIGTERM: {len(committed)} {runs} committed '
                    f'by this run, {len(committed)} of {TRAJECTORIES} in {out}; running the same '
                    'command again continues from there')
    # The index counts only committed runs: each with its whole bag, cost record and manifest entry.
    assert all((out / 'bags' / tid / 'metadata.yaml').exists() for tid in committed)
    assert sorted(p.stem for p in (out / 'costs').glob('traj_*.json')) == committed
    generation = json.loads((out / 'dataset.json').read_text())['generation']
    assert generation['trajectories'] == len(committed)
    assert generation['runs'][-1]['simulated_trajectories'] == len(committed)
    assert not (out / LOCK_FILE).exists()
    # Running it again finishes the rest.
    again = generate(out)
    _, err = again.communicate(timeout=WAIT_S)
    assert again.returncode == 0, err
    generation = json.loads((out / 'dataset.json').read_text())['generation']
    assert generation['trajectories'] == TRAJECTORIES
    assert generation['runs'][-1]['simulated_trajectories'] == TRAJECTORIES - len(committed)
