#!/usr/bin/env python3
"""The fall monitor fed at 1 kHz, as on a robot: drops, sample -> state latency, CPU per node.

A simulated trajectory (a walk, then a push that fells the robot) is replayed measurement by
measurement at 1 kHz of wall time, sample times following wall time as a robot's do, into the
monitor deployed in one of two ways:

* ``single``: the ``fall_monitor`` executable (feature + predictor nodes, one process, one
  executor);
* ``separate``: ``feature_node`` and ``predictor_node`` as two processes.

The monitor runs with ``config/monitor.yaml`` (REP 2003 QoS: it reads best effort, depth 10) and
the shipped model. This process publishes each measurement at its due time (sleeping until
0.3 ms before it, then waiting on ``CLOCK_MONOTONIC``) and receives the states on a second
thread; latency = state arrival minus
the measurement's publish time, so it includes this process's own receive path. A sample
without a state is a drop (the nodes count those they lost as missing or stale samples; those
counters are in the JSON too). CPU is each node process's user + system time over the replay.

    .venv/bin/python benchmarks/bench_monitor_latency.py --seconds 30 \\
        --out docs/bench_monitor_latency.json
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from fall_predictor.contract import messages
from fall_predictor.contract.topics import MEASUREMENT, ODOM_FRAME, STATE
from fall_predictor.msg import FallState, Measurement
from fall_predictor.monitor.records import PushSpec
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.bringup import ros_environment, start_process, stop_nodes
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.sim.trajectory import run_trajectory

REPO = Path(__file__).resolve().parents[1]
COUNTERS = ('missing_samples', 'stale_samples', 'out_of_order', 'invalid_measurements',
            'invalid_features', 'states')


def _cpu_seconds(pid: int) -> float:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _percentiles_ms(latencies_s: np.ndarray) -> dict[str, float]:
    ms = latencies_s * 1000.0
    return {name: round(float(np.percentile(ms, q)), 3)
            for name, q in (('median', 50), ('p90', 90), ('p99', 99), ('p99_9', 99.9),
                            ('max', 100))}


def simulate(seconds: float) -> list:
    """Measurements of a walk pushed hard at ``seconds - 1.5`` s (it falls): the replay input."""
    push = PushSpec(force_n=450.0, angle_deg=0.0, height_m=0.1, t_push=max(0.5, seconds - 1.5))
    return run_trajectory(push, seconds, stop_when_fallen=False).measurements


def replay(deployment: str, measurements: list, domain_id: int) -> dict[str, object]:
    tmp = Path(tempfile.mkdtemp(prefix=f'bench_monitor_{deployment}_'))
    env = ros_environment(domain_id)
    ros_args = ['--ros-args', '--params-file', str(REPO / 'config' / 'monitor.yaml')]
    modules = ['fall_monitor'] if deployment == 'single' else ['feature_node', 'predictor_node']
    nodes = {name: start_process(name, [sys.executable, '-m', f'fall_predictor.ros.{name}',
                                        *ros_args], env, tmp) for name in modules}
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id)
    sender = Node('bench_robot', context=context)
    receiver = Node('bench_receiver', context=context)
    publisher = create_publisher(sender, Measurement, MEASUREMENT)
    arrivals: dict[int, float] = {}
    counters: dict[str, dict[str, str]] = {}

    def on_state(msg) -> None:
        # Every state answers its sample (OK, or FALLEN once the robot is down).
        arrivals.setdefault(messages.stamp_ns(msg), time.monotonic())

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            counters[status.name] = {kv.key: kv.value for kv in status.values}

    state_sub = create_subscription(receiver, FallState, STATE, on_state, lossless=True)
    receiver.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 50)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(receiver)
    stop = threading.Event()

    def receive() -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.01)

    thread = threading.Thread(target=receive, daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 60.0
        while not (publisher.get_subscription_count() >= 1 and state_sub.get_publisher_count() >= 1
                   and len(counters) >= 2):
            if time.monotonic() > deadline or any(n.process.poll() is not None
                                                  for n in nodes.values()):
                raise RuntimeError('monitor did not start:\n' + '\n'.join(
                    n.log_tail() for n in nodes.values()))
            time.sleep(0.05)
        time.sleep(1.0)
        # Sample stamps follow ROS time from the first publish on, as a robot's do.
        stamp0 = time.time_ns() + 10_000_000
        stamps = [stamp0 + round((m.t - measurements[0].t) * 1e9) for m in measurements]
        msgs = [messages.measurement_msg(ros_qos.TYPES, ns, ODOM_FRAME, m)
                for ns, m in zip(stamps, measurements)]
        cpu_before = {name: _cpu_seconds(n.process.pid) for name, n in nodes.items()}
        load_before = os.getloadavg()
        t0 = measurements[0].t
        sent = np.empty(len(msgs))
        start = time.monotonic() + (stamp0 - time.time_ns()) / 1e9
        for k, (m, msg) in enumerate(zip(measurements, msgs)):
            due = start + (m.t - t0)
            # Sleep (releasing the CPU and the GIL: the nodes and the receiving thread need
            # them) until just before the due time, then wait out the rest.
            ahead = due - time.monotonic() - 0.0003
            if ahead > 0.0:
                time.sleep(ahead)
            while time.monotonic() < due:
                pass
            sent[k] = time.monotonic()
            publisher.publish(msg)
        wall_s = time.monotonic() - start
        time.sleep(2.0)                     # states in flight, and one more diagnostics report
        cpu = {name: round(100.0 * (_cpu_seconds(n.process.pid) - cpu_before[name]) / wall_s, 1)
               for name, n in nodes.items()}
        load_after = os.getloadavg()
    finally:
        stop.set()
        thread.join(timeout=2.0)
        sender.destroy_node()
        receiver.destroy_node()
        rclpy.try_shutdown(context=context)
        codes = stop_nodes(nodes)
    keys = stamps
    latencies = np.array([arrivals[k] - sent[i] for i, k in enumerate(keys) if k in arrivals])
    publish_lag = np.diff(sent) - 0.001
    return {
        'deployment': ('fall_monitor: feature + predictor nodes, one process' if deployment ==
                       'single' else 'feature_node and predictor_node, two processes'),
        'executor': os.environ.get('FALL_PREDICTOR_EXECUTOR') or 'single_threaded',
        'samples': len(keys),
        'states_received': int(latencies.size),
        'dropped_samples': len(keys) - int(latencies.size),
        'latency_ms': _percentiles_ms(latencies),
        'replay_wall_s': round(wall_s, 3),
        'replay_period_jitter_ms_p99': round(float(np.percentile(publish_lag, 99)) * 1e3, 3),
        'cpu_percent_of_one_core': cpu,
        'node_counters': {name: {k: v for k, v in values.items() if k in COUNTERS}
                          for name, values in counters.items()},
        'exit_codes': codes,
        'load_average': {'before': [round(x, 2) for x in load_before],
                         'after': [round(x, 2) for x in load_after]},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=30.0, help='replayed seconds')
    parser.add_argument('--deployment', choices=('single', 'separate', 'both'), default='both')
    parser.add_argument('--domain-id', type=int, default=1 + os.getpid() % 100)
    parser.add_argument('--out', type=Path, default=None, help='also write the JSON here')
    args = parser.parse_args()
    measurements = simulate(args.seconds)
    deployments = ('single', 'separate') if args.deployment == 'both' else (args.deployment,)
    result = {
        'command': 'benchmarks/bench_monitor_latency.py ' + ' '.join(sys.argv[1:]),
        'replayed_s': round(measurements[-1].t - measurements[0].t, 3),
        'model': 'models/default_model.json', 'params': 'config/monitor.yaml',
        'runs': [replay(d, measurements, args.domain_id) for d in deployments],
        'cpus': os.cpu_count(), 'python': platform.python_version(),
    }
    text = json.dumps(result, indent=1)
    print(text)
    if args.out is not None:
        args.out.write_text(text + '\n')


if __name__ == '__main__':
    main()
