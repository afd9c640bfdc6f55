"""The ``main()`` of every node: create the nodes of a process and spin them until shutdown."""
from __future__ import annotations

import faulthandler
import gc
import os
import signal
import sys
import time
from collections.abc import Sequence
from typing import Callable, Optional

import rclpy
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from fall_predictor.errors import TeamFileError, one_line
from fall_predictor.ros.parameters import NodeStartupError

#: Environment variable that chooses the executor of every node process (:func:`make_executor`).
EXECUTOR_ENV = 'FALL_PREDICTOR_EXECUTOR'
EXECUTORS = ('single_threaded', 'events')


#: The executor of a node process unless ``$FALL_PREDICTOR_EXECUTOR`` says otherwise.
DEFAULT_EXECUTOR = 'events'


def executor_kind(kind: Optional[str] = None) -> str:
    """``kind``, else ``$FALL_PREDICTOR_EXECUTOR``, else :data:`DEFAULT_EXECUTOR`; checked
    (NodeStartupError naming the choices)."""
    kind = kind or os.environ.get(EXECUTOR_ENV) or DEFAULT_EXECUTOR
    if kind not in EXECUTORS:
        raise NodeStartupError(f'{EXECUTOR_ENV}={kind!r} is not an executor: use one of {EXECUTORS}')
    return kind


def make_executor(kind: Optional[str] = None) -> Executor:
    """The executor ``kind`` (:func:`executor_kind`): rclpy's experimental EventsExecutor
    ('events', the default: a third less CPU and half the tail latency for the monitor in
    ``benchmarks/bench_monitor_latency.py``, docs/results.md) or its SingleThreadedExecutor
    ('single_threaded', the fallback). NodeStartupError for another name."""
    kind = executor_kind(kind)
    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        return EventsExecutor()
    return SingleThreadedExecutor()


#: Longest wait [s] of one spin: a stop request is seen within this.
_SPIN_PERIOD_S = 0.1

#: Wall time [s] the DDS teardown of a node process may take once its nodes are destroyed
#: (:func:`_bound_teardown`); milliseconds normally.
TEARDOWN_TIMEOUT_S = 5.0
#: Where a hung teardown's stacks go when the process is already stopping because a node could
#: not start (its FATAL line says why; kept open for faulthandler's thread).
_QUIET_DUMP = None


def _bound_teardown(quiet: bool) -> None:
    """End the process (exit code 1) if what remains of its exit takes longer than
    :data:`TEARDOWN_TIMEOUT_S`, interpreter shutdown included.

    Deleting a Fast DDS 2.14 participant can livelock with its discovery threads when other
    processes of the domain leave at the same moment (seen: six node processes refusing to start
    together; the main thread spins in ``DomainParticipant::set_listener`` under
    ``rmw_destroy_node`` while a receive thread waits in a discovery callback). That wait holds
    the GIL, so the watchdog is faulthandler's C thread; it writes every thread's Python stack
    to stderr (``quiet``: nowhere) and calls ``_exit(1)``. Armed only after the nodes are
    destroyed: a recorder drains its queue in ``destroy_node``, and that must not be cut short.
    """
    global _QUIET_DUMP
    if quiet and _QUIET_DUMP is None:
        _QUIET_DUMP = open(os.devnull, 'w')        # noqa: SIM115 (open until the process ends)
    faulthandler.dump_traceback_later(TEARDOWN_TIMEOUT_S, exit=True,
                                      file=_QUIET_DUMP if quiet else sys.stderr)


class StopRequest:
    """SIGINT / SIGTERM as a request to stop between callbacks (installed by :func:`run_nodes`).

    rclpy's own handlers shut the context down at once, in C, under a callback that may be
    running: its next publish then fails, and the EventsExecutor logs that at FATAL. Handled
    here, the signal only sets a flag; the spin loop ends after the callback in progress and the
    nodes are destroyed in order.
    """

    def __init__(self) -> None:
        self.signal: Optional[int] = None

    def __call__(self, signum: int, frame: object) -> None:
        self.signal = signum

    def install(self) -> None:
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, self)

    @property
    def requested(self) -> bool:
        return self.signal is not None


def spin_until_shutdown(executor: Executor, stop: Optional[StopRequest] = None) -> None:
    """Spin until ``stop`` is requested or the context shuts down (``rclpy.shutdown()``), one
    wake-up at a time for either executor (the EventsExecutor's ``spin()`` does not return on
    shutdown in this rclpy: ``bench_executors.py`` reports it hung)."""
    while rclpy.ok() and not (stop is not None and stop.requested):
        executor.spin_once(timeout_sec=_SPIN_PERIOD_S)


# --------------------------------------------------------------------------------------------
# main()
# --------------------------------------------------------------------------------------------

def run_node(factory: Callable[[], Node], name: str, args: Optional[list[str]] = None) -> int:
    """Create the node with ``factory`` and spin it until Ctrl-C / SIGTERM / shutdown.

    Returns the process exit code: 0 after a normal shutdown, 1 if the node could not start
    (the reason is logged as one FATAL line, no traceback).
    """
    return run_nodes((factory,), name, args)


def _is_team_file_error(error: BaseException) -> bool:
    """Whether ``error`` (or what it was raised from) is a mistake in a team's file: exit 2, as
    the command line's. (A startup error raised through a node's constructor reaches here
    without its cause: it says so itself, ``team_file``.)"""
    while error is not None:
        if isinstance(error, TeamFileError) or getattr(error, 'team_file', False):
            return True
        error = error.__cause__
    return False


def run_nodes(factories: Sequence[Callable[[], Node]], name: str,
              args: Optional[list[str]] = None) -> int:
    """Create one node per factory in this process and spin them all with one executor
    (:func:`make_executor`: the callbacks of all nodes run in turn, no threads), until
    Ctrl-C / SIGTERM / shutdown. Exit code as :func:`run_node`; if one node cannot start,
    none runs.

    The body of a node process: once its nodes are destroyed, the rest of the process's exit
    is bounded by :data:`TEARDOWN_TIMEOUT_S` (:func:`_bound_teardown`; exit code 1 if it
    hangs), through the interpreter's own shutdown.
    """
    stop = StopRequest()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop.install()
    nodes: list[Node] = []
    could_not_start = False
    try:
        try:
            for factory in factories:
                nodes.append(factory())
            kind = executor_kind()
        except (NodeStartupError, TeamFileError) as error:
            # Stopping from here: bounded already (the FATAL line goes to the console before
            # its /rosout publish, which is DDS). A mistake in a team's file not already said
            # as a startup error (a deploy config, a network read by the node): one line, exit 2.
            could_not_start = True
            _bound_teardown(quiet=True)
            rclpy.logging.get_logger(name).fatal(f'cannot start: {one_line(error)}')
            return 2 if _is_team_file_error(error) else 1
        if kind == 'events' and any(list(node.guards) for node in nodes):
            # This rclpy's EventsExecutor refuses guard conditions ("Guard conditions not
            # supported"), which the in-process lock-step loop of simulated_robot uses.
            rclpy.logging.get_logger(name).info(
                'guard conditions in use: spinning on the SingleThreadedExecutor')
            kind = 'single_threaded'
        executor = make_executor(kind)
        for node in nodes:
            executor.add_node(node)
        try:
            spin_until_shutdown(executor, stop)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        except Exception:
            # A shutdown by another path than the signals (rclpy.shutdown() from a callback or
            # another thread) invalidates the context at once; a callback already running then
            # fails on its next publish ("publisher's context is invalid"). That is the
            # shutdown, not a fault; with the context still valid it is one.
            if rclpy.ok():
                raise
        return 0
    finally:
        for node in nodes:
            node.destroy_node()
        if not could_not_start:             # else bounded since it knew
            _bound_teardown(quiet=False)
        # A node that failed in its constructor is torn down here, under the bound, rather
        # than by the collector at interpreter exit.
        gc.collect()
        rclpy.try_shutdown()


def spin_until(executor: Executor, done: Callable[[], bool], timeout_s: float,
               check: Callable[[], None] = lambda: None) -> bool:
    """Spin ``executor`` until ``done()`` or ``timeout_s`` wall seconds; ``check()`` may raise.

    Returns whether ``done()`` became true.
    """
    deadline = time.monotonic() + timeout_s
    while not done():
        check()
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return False
        executor.spin_once(timeout_sec=min(0.05, remaining))
    return True
