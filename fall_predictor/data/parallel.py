"""Where parallel work runs: local processes or a Dask cluster, through one joblib code path.

Every parallel loop of the package is a ``joblib.Parallel`` call. Compute-bound loops
(simulating trajectories for ``generate``, the sweep's trainings, the robustness table) use
:func:`compute_parallel`, which follows the backend that :func:`compute_backend` selected for
the command:

* local (no scheduler): ``jobs`` processes of joblib's loky backend on this machine;
* a Dask cluster (``scheduler='tcp://host:8786'``, a running ``dask scheduler`` with its
  ``dask worker`` processes): joblib's ``dask`` backend through a ``distributed.Client``. Tasks
  go to the cluster's workers and ``jobs`` is not used by these loops (the cluster's worker
  threads decide how many tasks run at once).

Loops that read a dataset's files (features, capture-point cache) use :func:`local_parallel`
and stay on the machine that holds the dataset, whatever the backend: the cluster gets the
arrays it needs as task arguments (joblib's Dask backend scatters a large argument once per
call), and generated bags come back to this machine as bytes (see
:mod:`fall_predictor.data.generation`). So no directory has to be shared with the workers.

A task's result does not depend on where it ran: every task is a pure function of its
arguments (a trajectory's gait and push are drawn from ``(seed, index)`` alone, and each worker
thread simulates in its own PyBullet world), which makes a cluster run bit-identical to a local
one (test/test_cluster.py). A Dask worker that dies takes only its running tasks with it; the
scheduler gives them to another worker.
"""
from __future__ import annotations

import os
import socket
import threading
from contextlib import contextmanager
from typing import Any, Iterator, Optional

#: Seconds to wait for the scheduler to answer, and for a cluster's first worker.
CONNECT_TIMEOUT_S = 30.0
WAIT_FOR_WORKERS_S = 60.0


@contextmanager
def compute_backend(scheduler: Optional[str] = None) -> Iterator[Optional[Any]]:
    """Run the :func:`compute_parallel` loops of the block on the Dask cluster at
    ``scheduler`` (``'tcp://host:8786'``), or locally if None.

    Yields the ``distributed.Client`` (None locally). Raises ``RuntimeError`` naming the address
    if no scheduler answers there, or if the ``distributed`` package is missing.
    """
    if scheduler is None:
        yield None
        return
    try:
        from distributed import Client
    except ImportError as error:               # pragma: no cover - a declared dependency
        raise RuntimeError('--scheduler needs the dask "distributed" package '
                           '(pip install distributed)') from error
    from joblib import parallel_config

    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError) as error:
        raise RuntimeError(f'no Dask scheduler answers at {scheduler}: {error}') from error
    try:
        with parallel_config(backend='dask', client=client,
                             wait_for_workers_timeout=WAIT_FOR_WORKERS_S):
            yield client
    finally:
        client.close()


def compute_parallel(jobs: int, **kwargs: Any):
    """``joblib.Parallel`` for compute-bound tasks: ``jobs`` local processes, or the cluster
    of the enclosing :func:`compute_backend`."""
    from joblib import Parallel
    return Parallel(n_jobs=jobs, **kwargs)


def local_parallel(jobs: int, **kwargs: Any):
    """``joblib.Parallel`` that always runs on this machine (``jobs`` loky processes), for
    tasks that read this machine's files."""
    from joblib import Parallel
    return Parallel(n_jobs=jobs, backend='loky', **kwargs)


def machine() -> dict[str, Any]:
    """This machine: host name and logical CPU count."""
    return {'host': socket.gethostname(), 'cores': os.cpu_count()}


def worker_name() -> str:
    """Who runs the current task: the Dask worker's address, else ``host:pid``."""
    try:
        from distributed import get_worker
        return str(get_worker().address)
    except (ImportError, ValueError):
        return f'{socket.gethostname()}:{os.getpid()}'


class PerThread(threading.local):
    """Objects kept for the life of a worker thread (a simulator, a simulated walk): a Dask
    worker may run several tasks at once in threads, and a PyBullet world serves one of them."""

    def __init__(self) -> None:
        self.objects: dict[Any, Any] = {}

    def get(self, key: Any, make) -> Any:
        if key not in self.objects:
            self.objects[key] = make()
        return self.objects[key]


def progress_bar(total: int, initial: int = 0, desc: str = 'trajectories', unit: str = 'traj',
                 disable: bool = False):
    """A tqdm bar that shows items per second (never inverted to seconds per item) and the ETA."""
    from tqdm import tqdm
    return tqdm(total=total, initial=initial, desc=desc, unit=unit, disable=disable,
                bar_format='{l_bar}{bar}| {n_fmt}/{total_fmt} '
                           '[{elapsed}<{remaining}, {rate_noinv_fmt}{postfix}]')
