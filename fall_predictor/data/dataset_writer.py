"""What keeps a dataset whole while it is written: one writer at a time, and a stop asked for
(Ctrl-C, SIGTERM from a scheduler or ``kill``) that ends between two runs, never inside one's
commit.

* :func:`writer_lock`: a lock file (:data:`LOCK_FILE`) in the dataset folder holds the writer's
  host, pid and start time. A second writer into the same folder is refused
  (:class:`DatasetLocked`, saying who holds it); a lock left by a writer that died without
  removing it (SIGKILL, a power cut) is taken over when its process (pid and start time) no
  longer runs on this host. A lock of another host (a shared disk) cannot be checked from here:
  it is refused, the message saying which file to remove if that writer is gone.
* :func:`stop_on_signals`: SIGINT and SIGTERM raise :class:`StopRequested` in the writing process
  (its main thread), and inside :func:`commit_section` they wait for the section to end: a run's
  bag, cost record and index row are written together or not at all, and the index counts only
  runs that were committed.
"""
from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import threading
import time
from pathlib import Path
from typing import Iterator, Optional

#: The lock file of a dataset folder being written.
LOCK_FILE = 'writer.lock'
#: The signals that stop a writer cleanly.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class DatasetLocked(RuntimeError):
    """Another process writes into the dataset folder (the message says which, and what to do)."""


class StopRequested(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived while writing (``signum``: which). A KeyboardInterrupt, as Ctrl-C
    is: no ``except Exception`` swallows it, and joblib stops its workers for it."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        self.name = signal.Signals(signum).name
        super().__init__(f'stopped by {self.name}')


class WriterStopped(StopRequested):
    """A writer stopped by SIGINT or SIGTERM between two runs: ``committed`` runs were written by
    this process, ``finished`` of ``trajectories`` are in dataset ``out``; the same command again
    continues from there."""

    def __init__(self, signum: int, out: Path, committed: int, finished: int,
                 trajectories: int) -> None:
        super().__init__(signum)
        self.out, self.committed, self.finished, self.trajectories = (out, committed, finished,
                                                                      trajectories)

    def __str__(self) -> str:
        runs = 'run' if self.committed == 1 else 'runs'
        return (f'stopped by {self.name}: {self.committed} {runs} committed by this run, '
                f'{self.finished} of {self.trajectories} in {self.out}; running the same command '
                'again continues from there')


def _start_ticks(pid: int) -> Optional[int]:
    """When process ``pid`` started (clock ticks after boot, Linux's /proc), None where unknown:
    with the pid it names one process, whatever pids were reused since."""
    try:
        stat = Path(f'/proc/{pid}/stat').read_text()
        return int(stat[stat.rindex(')') + 2:].split()[19])
    except (OSError, ValueError, IndexError):
        return None


def _holder_running(holder: dict) -> bool:
    """Whether the process a lock names still runs (its pid, started when the lock says)."""
    pid = holder.get('pid')
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass                        # it runs, as another user
    started = holder.get('started')
    return started is None or _start_ticks(pid) in (None, started)


def _read_lock(path: Path) -> dict:
    try:
        holder = json.loads(path.read_text())
        return holder if isinstance(holder, dict) else {}
    except (OSError, ValueError):
        return {}                   # being written, or garbage: judged by what it says (nothing)


@contextlib.contextmanager
def writer_lock(folder: str | os.PathLike, what: str = 'generate') -> Iterator[Path]:
    """Hold ``folder``'s writer lock for the ``with`` block (the folder must exist)."""
    path = Path(folder) / LOCK_FILE
    me = {'pid': os.getpid(), 'host': socket.gethostname(), 'writer': what,
          'started': _start_ticks(os.getpid())}
    text = json.dumps(me)
    for _ in range(3):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _read_lock(path)
            pid, host = holder.get('pid'), holder.get('host')
            if host not in (None, me['host']):
                raise DatasetLocked(
                    f'{folder}: another writer ({holder.get("writer", "?")}, pid {pid} on host {host}) '
                    f'holds {path}; if it is no longer running, remove that file') from None
            if _holder_running(holder):
                raise DatasetLocked(
                    f'{folder}: another writer ({holder.get("writer", "?")}, pid {pid}) is writing into '
                    'this dataset; wait for it to finish (running the same command again then '
                    'continues) or write into another folder') from None
            if not holder and _recent(path):
                raise DatasetLocked(f'{folder}: another writer is taking {path} right now; try again')
            # Stale: its writer is gone. Removed, then taken by O_EXCL as any writer would.
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            continue
        with os.fdopen(fd, 'w') as f:
            f.write(text)
        break
    else:
        raise DatasetLocked(f'{folder}: could not take {path} (other writers keep taking it)')
    try:
        yield path
    finally:
        if _read_lock(path).get('pid') == me['pid']:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()


def _recent(path: Path, within_s: float = 2.0) -> bool:
    """Whether ``path`` changed less than ``within_s`` ago (a lock being written by its taker)."""
    try:
        return time.time() - path.stat().st_mtime < within_s
    except OSError:
        return False


class _Stop:
    """Per process: the signal held back while a commit runs, and whether one runs."""

    def __init__(self) -> None:
        self.committing = False
        self.pending: int | None = None


_STOP = _Stop()


def _on_signal(signum: int, frame) -> None:
    if _STOP.committing:
        _STOP.pending = signum      # raised when the commit ends
        return
    raise StopRequested(signum)


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """SIGINT and SIGTERM raise :class:`StopRequested` during the ``with`` block (the previous
    handlers are back after it). Off the main thread, where Python cannot take signals, nothing
    changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, _on_signal) for s in STOP_SIGNALS}
    _STOP.committing, _STOP.pending = False, None
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


@contextlib.contextmanager
def commit_section() -> Iterator[None]:
    """A stop asked for inside the block waits for its end (then :class:`StopRequested`)."""
    _STOP.committing = True
    try:
        yield
    finally:
        _STOP.committing = False
    if _STOP.pending is not None:
        signum, _STOP.pending = _STOP.pending, None
        raise StopRequested(signum)

