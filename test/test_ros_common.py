"""``run_nodes``: the main() body of every node process, on its shutdown paths."""
from __future__ import annotations

import subprocess
import sys
import textwrap

from test_nodes_support import test_domain_id

from fall_predictor.ros.bringup import ros_environment

# A node whose timer callback publishes after the context has been shut down under it, as
# Ctrl-C / SIGTERM do while a callback runs (rclpy invalidates the context at once, in C).
_NODE = textwrap.dedent('''
    import sys
    import rclpy
    from rclpy.node import Node
    from std_msgs.msg import Bool
    from fall_predictor.ros.runner import run_nodes

    class Node_(Node):
        def __init__(self):
            super().__init__('shutdown_race')
            self.pub = self.create_publisher(Bool, 'flag', 1)
            self.create_timer(0.05, self.tick)

        def tick(self):
            if sys.argv[1] == 'shutdown':
                rclpy.get_default_context().shutdown()
            else:
                raise RuntimeError('a real fault in a callback')
            self.pub.publish(Bool(data=True))

    raise SystemExit(run_nodes((Node_,), 'shutdown_race', []))
''')


def _run(mode: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-c', _NODE, mode], env=ros_environment(test_domain_id(170)),
                          capture_output=True, text=True, timeout=60)


def test_a_publish_racing_the_shutdown_is_a_clean_exit() -> None:
    done = _run('shutdown')
    assert done.returncode == 0, done.stderr
    assert 'context is invalid' not in done.stderr


def test_a_fault_in_a_callback_with_the_context_valid_still_fails_the_process() -> None:
    done = _run('fault')
    assert done.returncode != 0
    assert 'RuntimeError: a real fault in a callback' in done.stderr
