"""A dataset's writer: one at a time (a lock file with its pid; a dead writer's lock taken over),
and a stop asked for inside a commit waits for the commit to end."""
import json
import os
import signal
import socket
import subprocess
import sys

import pytest

from fall_predictor.data.dataset_writer import (LOCK_FILE, DatasetLocked, StopRequested,
                                                commit_section, stop_on_signals, writer_lock)


def _dead_pid() -> int:
    """The pid of a process that has exited (and been reaped)."""
    child = subprocess.Popen([sys.executable, '-c', 'pass'])
    child.wait()
    return child.pid


def test_a_second_writer_is_refused_naming_the_first(tmp_path):
    holder = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)'])
    try:
        (tmp_path / LOCK_FILE).write_text(json.dumps(
            {'pid': holder.pid, 'host': socket.gethostname(), 'writer': 'generate'}))
        with pytest.raises(DatasetLocked, match=f'pid {holder.pid}.*wait for it'):
            with writer_lock(tmp_path):
                pass
        assert json.loads((tmp_path / LOCK_FILE).read_text())['pid'] == holder.pid   # untouched
    finally:
        holder.kill()
        holder.wait()


def test_the_lock_is_held_during_the_block_and_removed_after(tmp_path):
    with writer_lock(tmp_path) as path:
        assert json.loads(path.read_text())['pid'] == os.getpid()
        with pytest.raises(DatasetLocked):          # a second writer, even of this process
            with writer_lock(tmp_path):
                pass
        assert path.exists()                        # the refused one left the lock alone
    assert not (tmp_path / LOCK_FILE).exists()


def test_a_reused_pid_does_not_keep_a_dead_writers_lock(tmp_path):
    """A lock naming this process's pid with another start time (a writer killed in a container
    whose next process got its pid) is stale."""
    (tmp_path / LOCK_FILE).write_text(json.dumps({'pid': os.getpid(), 'host': socket.gethostname(),
                                                  'writer': 'generate', 'started': -1}))
    with writer_lock(tmp_path) as path:
        assert json.loads(path.read_text())['started'] != -1


def test_a_dead_writers_lock_is_taken_over(tmp_path):
    dead = _dead_pid()
    (tmp_path / LOCK_FILE).write_text(json.dumps({'pid': dead, 'host': socket.gethostname(),
                                                  'writer': 'generate'}))
    with writer_lock(tmp_path) as path:
        assert json.loads(path.read_text())['pid'] == os.getpid()
    assert not path.exists()


def test_a_lock_of_another_host_is_refused_saying_which_file_to_remove(tmp_path):
    (tmp_path / LOCK_FILE).write_text(json.dumps({'pid': 1, 'host': 'elsewhere', 'writer': 'generate'}))
    with pytest.raises(DatasetLocked, match=f'host elsewhere.*{LOCK_FILE}.*remove that file'):
        with writer_lock(tmp_path):
            pass


def test_a_stop_inside_a_commit_waits_for_its_end():
    done = []
    with pytest.raises(StopRequested) as stop:
        with stop_on_signals():
            with commit_section():
                os.kill(os.getpid(), signal.SIGTERM)
                done.append('bag')          # the commit goes on after the signal
                done.append('index row')
            done.append('next run')         # never reached: the stop comes at the commit's end
    assert done == ['bag', 'index row'] and stop.value.signum == signal.SIGTERM


def test_a_stop_outside_a_commit_is_at_once_and_the_handlers_come_back():
    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(StopRequested) as stop:
        with stop_on_signals():
            os.kill(os.getpid(), signal.SIGINT)
            pytest.fail('the stop did not interrupt')
    assert stop.value.name == 'SIGINT' and signal.getsignal(signal.SIGINT) is before
