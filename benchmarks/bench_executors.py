#!/usr/bin/env python3
"""rclpy's EventsExecutor against the SingleThreadedExecutor on one 1 kHz message loop.

One node publishes a 30-float message from a 1 kHz timer to its own best-effort subscription and
runs a 100 Hz timer, for ``--seconds``, once per executor and way of spinning, each in a fresh
process (one rclpy context each):

* ``spin_once``: ``executor.spin_once(timeout_sec=0.1)`` in a loop until the time is up (what the
  package's ``spin_until`` does);
* ``spin``: ``executor.spin()`` ended by ``rclpy.shutdown()`` from a timer thread (what
  ``run_nodes`` does on Ctrl-C). A run that does not end within ``--seconds`` + 10 s is killed
  and reported as ``hung``.

Per run: messages received, timer ticks (of 100 per second), process CPU seconds. Prints and
writes JSON (``--out``).

    python benchmarks/bench_executors.py --seconds 5 --out docs/monitor/executors.json
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

CHILD = r'''
import json, sys, threading, time
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray

kind, how, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
rclpy.init()
node = Node('executor_bench')
qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
count = {'received': 0, 'ticks': 0}
node.create_subscription(Float64MultiArray, 'bench', lambda m: count.__setitem__('received', count['received'] + 1), qos)
node.create_timer(0.01, lambda: count.__setitem__('ticks', count['ticks'] + 1))
pub = node.create_publisher(Float64MultiArray, 'bench', qos)
msg = Float64MultiArray(data=[1.0] * 30)
node.create_timer(0.001, lambda: pub.publish(msg))
executor = EventsExecutor() if kind == 'events' else SingleThreadedExecutor()
executor.add_node(node)
c0 = time.process_time()
if how == 'spin_once':
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        executor.spin_once(timeout_sec=0.1)
else:
    threading.Timer(seconds, rclpy.shutdown).start()
    try:
        executor.spin()
    except ExternalShutdownException:
        pass
print(json.dumps({**count, 'cpu_s': round(time.process_time() - c0, 3)}), flush=True)
'''


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=5.0)
    parser.add_argument('--out', type=Path, default=None)
    args = parser.parse_args(argv)
    runs = []
    for kind in ('single_threaded', 'events'):
        for how in ('spin_once', 'spin'):
            try:
                done = subprocess.run([sys.executable, '-c', CHILD, kind, how, str(args.seconds)],
                                      capture_output=True, text=True, timeout=args.seconds + 10.0)
                row = json.loads(done.stdout.strip().splitlines()[-1]) if done.returncode == 0 else \
                    {'error': done.stderr.strip().splitlines()[-1:]}
            except subprocess.TimeoutExpired:
                row = {'hung': True}
            runs.append({'executor': kind, 'spinning': how, 'seconds': args.seconds,
                         'messages_published_at_1khz': round(1000 * args.seconds), **row})
            print(json.dumps(runs[-1]), flush=True)
    result = {'runs': runs, 'load_average': os.getloadavg(), 'cores': os.cpu_count()}
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(result, indent=1) + '\n')
    return result


if __name__ == '__main__':
    main()
