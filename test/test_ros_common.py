"""``run_nodes``: the main() body of every node process, on its shutdown paths."""
from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time

import pytest

from test_nodes_support import test_domain_id

from fall_predictor.ros.bringup import ros_environment

# A node whose timer callback publishes after the context has been shut down under it, as
# Ctrl-C / SIGTERM do while a callback runs (rclpy invalidates the context at once, in C).
_NODE = textwrap.dedent('''
    import sys
    import time
    import rclpy
    from rclpy.node import Node
    from std_msgs.msg import Bool
    from fall_predictor.ros.runner import run_nodes

    class Node_(Node):
        def __init__(self):
            super().__init__('shutdown_race')
            self.pub = self.create_publisher(Bool, 'flag', 1)
            self.create_timer(0.05, self.tick)
            if sys.argv[1] == 'guard':
                self.guard = self.create_guard_condition(
                    lambda: print('guard ran', file=sys.stderr, flush=True))

        def tick(self):
            if sys.argv[1] == 'guard':
                self.guard.trigger()
            elif sys.argv[1] == 'shutdown':
                rclpy.get_default_context().shutdown()
            elif sys.argv[1] == 'busy':         # a long callback that a signal interrupts
                print('in callback', file=sys.stderr, flush=True)
                time.sleep(0.3)
            else:
                raise RuntimeError('a real fault in a callback')
            self.pub.publish(Bool(data=True))

    raise SystemExit(run_nodes((Node_,), 'shutdown_race', []))
''')


def _run(mode: str, executor: str = '') -> subprocess.CompletedProcess:
    env = ros_environment(test_domain_id(166))
    if executor:
        env['FALL_PREDICTOR_EXECUTOR'] = executor
    return subprocess.run([sys.executable, '-c', _NODE, mode], env=env,
                          capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize('executor', ['single_threaded', 'events'])
def test_a_publish_racing_the_shutdown_is_a_clean_exit(executor: str) -> None:
    """rclpy.shutdown() from a callback (no node of the package does; the signals are handled
    between callbacks, test below) invalidates the context under the callback's publish."""
    done = _run('shutdown', executor)
    assert done.returncode == 0, done.stderr
    if executor == 'events':
        # The EventsExecutor logs every exception out of a callback at FATAL itself, before it
        # reaches the runner: the exit is clean, the log is not.
        assert 'Exception in \'timers\' callback' in done.stderr
    else:
        assert 'context is invalid' not in done.stderr


@pytest.mark.parametrize('executor', ['single_threaded', 'events'])
def test_a_fault_in_a_callback_with_the_context_valid_still_fails_the_process(executor: str) -> None:
    done = _run('fault', executor)
    assert done.returncode != 0
    assert 'RuntimeError: a real fault in a callback' in done.stderr


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize('executor', ['single_threaded', 'events'])
def test_a_signal_during_a_callback_ends_the_process_cleanly_after_it(executor: str,
                                                                       signum: int) -> None:
    """Ctrl-C or SIGTERM while a callback runs: the callback finishes (its publish succeeds),
    the process exits 0 and logs no error, with either executor."""
    env = ros_environment(test_domain_id(166))
    env['FALL_PREDICTOR_EXECUTOR'] = executor
    process = subprocess.Popen([sys.executable, '-c', _NODE, 'busy'], env=env,
                               stderr=subprocess.PIPE, text=True)
    try:
        assert process.stderr.readline().strip() == 'in callback'
        process.send_signal(signum)
        assert process.wait(timeout=10) == 0
        log = process.stderr.read()
    finally:
        process.kill()
        process.stderr.close()
    assert 'FATAL' not in log and 'Traceback' not in log and 'Exception' not in log, log


@pytest.mark.parametrize('executor', ['single_threaded', 'events'])
def test_a_process_with_guard_conditions_runs_them_with_either_setting(executor: str) -> None:
    """The EventsExecutor refuses guard conditions (simulated_robot's lock-step loop uses one):
    such a process spins on the SingleThreadedExecutor, and says so."""
    env = ros_environment(test_domain_id(166))
    env['FALL_PREDICTOR_EXECUTOR'] = executor
    process = subprocess.Popen([sys.executable, '-c', _NODE, 'guard'], env=env,
                               stderr=subprocess.PIPE, text=True)
    try:
        lines = []
        while not lines or lines[-1] != 'guard ran':
            line = process.stderr.readline()
            assert line, '\n'.join(lines)
            lines.append(line.strip())
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=10) == 0
    finally:
        process.kill()
        process.stderr.close()
    fallback = any('spinning on the SingleThreadedExecutor' in line for line in lines)
    assert fallback == (executor == 'events'), lines


def test_an_unknown_executor_is_refused_in_words() -> None:
    done = _run('shutdown', 'multi')
    assert done.returncode == 1
    assert "FALL_PREDICTOR_EXECUTOR='multi' is not an executor" in done.stderr


# A node that leaves behind an object whose finalizer never returns, as deleting a Fast DDS
# participant did not when it livelocked with discovery threads while other processes left.
_STUCK_TEARDOWN = textwrap.dedent('''
    import sys
    import threading
    from rclpy.node import Node
    from fall_predictor.ros.parameters import NodeStartupError
    from fall_predictor.ros.runner import run_nodes

    class Stuck:
        def __init__(self, node):
            self.node, node.stuck = node, self      # a cycle: freed by the collector
        def __del__(self):
            threading.Event().wait()

    class StuckNode(Node):
        def __init__(self):
            super().__init__('stuck_teardown')
            Stuck(self)
            if sys.argv[1] == 'refuse':
                raise NodeStartupError('no usable model: the reason')
            print('started', file=sys.stderr, flush=True)

    raise SystemExit(run_nodes((StuckNode,), 'stuck_teardown', []))
''')


def test_a_node_that_cannot_start_exits_even_if_its_teardown_hangs() -> None:
    """The node that failed in its constructor is torn down under the bound: exit code 1 after
    TEARDOWN_TIMEOUT_S, its FATAL line the only output (no stack dump)."""
    from fall_predictor.ros.runner import TEARDOWN_TIMEOUT_S
    started = time.monotonic()
    done = subprocess.run([sys.executable, '-c', _STUCK_TEARDOWN, 'refuse'],
                          env=ros_environment(test_domain_id(166)), capture_output=True,
                          text=True, timeout=60)
    elapsed_s = time.monotonic() - started
    assert done.returncode == 1, done.stderr
    assert TEARDOWN_TIMEOUT_S <= elapsed_s < TEARDOWN_TIMEOUT_S + 20.0
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and '[FATAL]' in lines[0], done.stderr
    assert 'cannot start: no usable model: the reason' in lines[0]


def test_a_teardown_that_hangs_at_interpreter_exit_ends_with_its_stacks() -> None:
    """After a normal stop the bound lasts through the interpreter's shutdown (where the
    collector frees the node's cycle): exit code 1 and every thread's stack on stderr."""
    from fall_predictor.ros.runner import TEARDOWN_TIMEOUT_S
    process = subprocess.Popen([sys.executable, '-c', _STUCK_TEARDOWN, 'run'],
                               env=ros_environment(test_domain_id(166)),
                               stderr=subprocess.PIPE, text=True)
    try:
        assert process.stderr.readline().strip() == 'started'
        process.send_signal(signal.SIGINT)
        started = time.monotonic()
        assert process.wait(timeout=60) == 1
        elapsed_s = time.monotonic() - started
        log = process.stderr.read()
    finally:
        process.kill()
        process.stderr.close()
    assert TEARDOWN_TIMEOUT_S <= elapsed_s < TEARDOWN_TIMEOUT_S + 20.0
    assert 'Timeout (' in log and 'in __del__' in log, log
