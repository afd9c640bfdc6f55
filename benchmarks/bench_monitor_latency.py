#!/usr/bin/env python3
"""The fall monitor fed at 1 kHz, as on a robot: drops, sample -> state latency, CPU per node.

A simulated trajectory (a walk, then a push that fells the robot) is replayed at 1 kHz of wall
time, stamps following ROS time as a robot's do, into the monitor deployed in one of three ways:

* ``single``: the ``fall_monitor`` executable (feature + predictor nodes, one process, one
  executor) fed ``fall_predictor/measurement``;
* ``separate``: ``feature_node`` and ``predictor_node`` as two processes, fed the same;
* ``estimator``: ``fall_monitor --estimator`` (state estimator + feature + predictor nodes, one
  process) fed the robot's sensor topics (joint states, IMU, foot wrenches) and its
  ``robot_description``, timed by ``--timing``: ``simulator`` (every stream at 1 kHz, one stamp
  per step), ``robot_1khz`` / ``robot_500hz`` (a robot's drivers: joint states split into legs and
  upper body at 1 kHz / 500 Hz, IMU 0.3 ms and foot sensors 0.4 ms after them;
  :class:`~fall_predictor.sim.drivers.DriverTiming`);
* ``floor``: ``benchmarks/rclpy_floor_node.py``, fed as ``estimator``: the same subscriptions and
  state publisher on the same executor, computing nothing. Its CPU is rclpy's share of the
  estimator deployment's, a floor under any monitor made of rclpy nodes.

The monitor runs with ``config/monitor.yaml`` (REP 2003 QoS: it reads best effort, depth 10) and
the shipped model. This process publishes each message at its due time (sleeping until 0.3 ms
before it, then waiting on ``CLOCK_MONOTONIC``) and receives the states on a second thread.
A sample is one measurement, or the sensor messages of one driving (legs') joint state stamp
and those stamped less than 1 ms after it; latency = state arrival minus the publish time of
the sample's last message, so it includes this process's own receive path. A sample without a
state is a drop (the nodes count those they lost as missing or stale samples; those counters are
in the JSON too). CPU is each node process's user + system time over the replay. The executor is
the nodes' default, or ``FALL_PREDICTOR_EXECUTOR`` (``ros/runner.py``). ``--monitor-cpus 1`` pins
the node processes (all their threads, DDS's included) to CPU 1 with ``taskset`` and this process
to the others, as a robot pins its real-time processes: whether moving between cores costs the
monitor anything.

    .venv/bin/python benchmarks/bench_monitor_latency.py --seconds 10 --deployment all \\
        --out docs/monitor/latency.json
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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import String

from fall_predictor.contract import messages
from fall_predictor.contract.topics import (IMU, LEFT_FOOT_WRENCH, MEASUREMENT, ODOM_FRAME,
                                            RIGHT_FOOT_WRENCH, ROBOT_DESCRIPTION,
                                            SENSOR_JOINT_STATES, STATE)
from fall_predictor.msg import FallState, Measurement
from fall_predictor.monitor.records import PushSpec
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.bringup import ros_environment, start_process, stop_nodes
from fall_predictor.ros.runner import executor_kind
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.sim.drivers import DriverTiming, driver_messages
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.trajectory import TrajectoryResult, run_trajectory

from bench_robot_streams import LEGS, TIMINGS   # the robot-streams benchmark's three timings
from pacing import wait_until

REPO = Path(__file__).resolve().parents[1]
COUNTERS = ('missing_samples', 'stale_samples', 'out_of_order', 'invalid_measurements',
            'invalid_features', 'states', 'estimates', 'degraded_estimates')
DEPLOYMENTS = {
    'single': ('fall_monitor: feature + predictor nodes, one process, fed measurements',
               {'fall_monitor': []}),
    'separate': ('feature_node and predictor_node, two processes, fed measurements',
                 {'feature_node': [], 'predictor_node': []}),
    'estimator': ('fall_monitor --estimator: estimator + feature + predictor nodes, one '
                  'process, fed the sensor topics', {'fall_monitor': ['--estimator']}),
    'floor': ('rclpy floor: the estimator deployment\'s subscriptions and state publisher, '
              'computing nothing (benchmarks/rclpy_floor_node.py)', {'rclpy_floor': []}),
}
#: The deployments fed the robot's sensor topics (the others: measurements).
SENSOR_DEPLOYMENTS = ('estimator', 'floor')
#: The node processes that are not the package's own nodes: their scripts.
SCRIPTS = {'rclpy_floor': Path(__file__).resolve().parent / 'rclpy_floor_node.py'}
#: How many nodes of each deployment report on /diagnostics (the run waits for all of them).
REPORTING_NODES = {'single': 2, 'separate': 2, 'estimator': 3, 'floor': 1}
_SAMPLE_WINDOW_NS = 1_000_000       # sensor messages this soon after a driving stamp: its sample


@dataclass
class Feed:
    """What the benchmark publishes: message k on ``topics[k]``, stamped ``stamps_ns[k]`` after
    the replay's start (the header is set at publish time, as a driver does);
    ``sample_of[k]``: the stamp of the sample (answered by a state with that stamp) the message
    belongs to, or -1."""

    topics: list[str]
    msgs: list[object]
    stamps_ns: np.ndarray
    sample_of: np.ndarray


def _cpu_seconds(pid: int) -> float:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _percentiles_ms(latencies_s: np.ndarray) -> dict[str, float]:
    ms = latencies_s * 1000.0
    return {name: round(float(np.percentile(ms, q)), 3)
            for name, q in (('median', 50), ('p90', 90), ('p99', 99), ('p99_9', 99.9),
                            ('max', 100))}


def simulate(seconds: float) -> TrajectoryResult:
    """A walk pushed hard at ``seconds - 1.5`` s (it falls), its sensor truth recorded."""
    push = PushSpec(force_n=450.0, angle_deg=0.0, height_m=0.1, t_push=max(0.5, seconds - 1.5))
    return run_trajectory(push, seconds, stop_when_fallen=False, record_sensors=True)


def measurement_feed(run: TrajectoryResult) -> Feed:
    t0 = run.measurements[0].t
    stamps = [round((m.t - t0) * 1e9) for m in run.measurements]
    return Feed(['measurement'] * len(stamps),
                [messages.measurement_msg(ros_qos.TYPES, ns, ODOM_FRAME, m)
                 for ns, m in zip(stamps, run.measurements)],
                np.array(stamps), np.array(stamps))


def sensor_feed(run: TrajectoryResult, timing: DriverTiming) -> Feed:
    """The drivers' messages of the run's noisy sensor samples."""
    samples = apply_sensors(run.sensor_truths, SensorParams(), seed=0)
    timing = DriverTiming(**{**timing.to_dict(), 'joint_groups': timing.joint_groups,
                             'clock_offset_ns': -round(samples[0].t * 1e9)})
    build = {'joints': messages.joint_state_msg, 'imu': messages.imu_msg,
             'l': messages.wrench_msg, 'r': messages.wrench_msg}
    topics, msgs, stamps, sample_of = [], [], [], []
    driving = -1
    for stream, reading in driver_messages(samples, timing):
        if stream == 'joints' and set(reading.names) & set(LEGS):
            driving = reading.stamp_ns
        topics.append(stream)
        msgs.append(build[stream](ros_qos.TYPES, reading))
        stamps.append(reading.stamp_ns)
        within = driving >= 0 and reading.stamp_ns - driving < _SAMPLE_WINDOW_NS
        sample_of.append(driving if within else -1)
    return Feed(topics, msgs, np.array(stamps), np.array(sample_of))


def replay(deployment: str, feed: Feed, domain_id: int, node_params: list[str],
           monitor_cpus: tuple[int, ...] = ()) -> dict[str, object]:
    label, modules = DEPLOYMENTS[deployment]
    tmp = Path(tempfile.mkdtemp(prefix=f'bench_monitor_{deployment}_'))
    env = ros_environment(domain_id)
    ros_args = ['--ros-args', '--params-file', str(REPO / 'config' / 'monitor.yaml'), *node_params]
    executable = 'fall_monitor' if 'fall_monitor' in modules else None
    pin = ['taskset', '-c', ','.join(map(str, monitor_cpus))] if monitor_cpus else []
    nodes = {name: start_process(name, [*pin, sys.executable, *(
        [str(SCRIPTS[name])] if name in SCRIPTS else ['-m', f'fall_predictor.ros.{name}']),
        *options, *ros_args], env, tmp) for name, options in modules.items()}
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id)
    sender = Node('bench_robot', context=context)
    receiver = Node('bench_receiver', context=context)
    sensors = deployment in SENSOR_DEPLOYMENTS
    publishers = ({'joints': create_publisher(sender, JointState, SENSOR_JOINT_STATES),
                   'imu': create_publisher(sender, Imu, IMU),
                   'l': create_publisher(sender, WrenchStamped, LEFT_FOOT_WRENCH),
                   'r': create_publisher(sender, WrenchStamped, RIGHT_FOOT_WRENCH)} if sensors
                  else {'measurement': create_publisher(sender, Measurement, MEASUREMENT)})
    arrivals: dict[int, float] = {}
    counters: dict[str, dict[str, str]] = {}

    def on_state(msg) -> None:
        # Every state answers its sample (OK, DEGRADED, or FALLEN once the robot is down).
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
        if sensors:
            create_publisher(sender, String, ROBOT_DESCRIPTION).publish(
                String(data=rm.URDF_PATH.read_text()))
        deadline = time.monotonic() + 60.0
        while not (all(p.get_subscription_count() >= 1 for p in publishers.values())
                   and state_sub.get_publisher_count() >= 1
                   and len(counters) >= REPORTING_NODES[deployment]):
            if time.monotonic() > deadline or any(n.process.poll() is not None
                                                  for n in nodes.values()):
                raise RuntimeError(f'monitor did not start ({executable}):\n' + '\n'.join(
                    n.log_tail() for n in nodes.values()))
            time.sleep(0.05)
        time.sleep(1.0)                     # discovery settles; the estimator builds its model
        pubs = [publishers[topic] for topic in feed.topics]
        offsets_s = feed.stamps_ns / 1e9
        stamp0 = time.time_ns() + 10_000_000
        cpu_before = {name: _cpu_seconds(n.process.pid) for name, n in nodes.items()}
        load_before = os.getloadavg()
        sent = np.empty(len(feed.msgs))
        start = time.monotonic() + (stamp0 - time.time_ns()) / 1e9
        for k, (publisher, msg) in enumerate(zip(pubs, feed.msgs)):
            due = start + offsets_s[k]
            wait_until(due)                 # the nodes and the receiving thread run meanwhile
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp0 + int(feed.stamps_ns[k]),
                                                                   1_000_000_000)
            publisher.publish(msg)
            sent[k] = time.monotonic()
        wall_s = time.monotonic() - start
        time.sleep(2.0)                     # states in flight, and one more diagnostics report
        cpu = {name: round(100.0 * (_cpu_seconds(n.process.pid) - cpu_before[name]) / wall_s, 1)
               for name, n in nodes.items()}
        load_after = os.getloadavg()
        lag = sent - (start + offsets_s)
    finally:
        stop.set()
        thread.join(timeout=2.0)
        sender.destroy_node()
        receiver.destroy_node()
        rclpy.try_shutdown(context=context)
        codes = stop_nodes(nodes)
    # A sample's reference time: its last message's publish.
    ready: dict[int, float] = {}
    for stamp, t in zip(feed.sample_of.tolist(), sent.tolist()):
        if stamp >= 0:
            ready[stamp0 + stamp] = max(ready.get(stamp0 + stamp, t), t)
    latencies = np.array([arrivals[k] - t for k, t in ready.items() if k in arrivals])
    return {
        'deployment': label,
        'executor': executor_kind(),
        'monitor_cpus': list(monitor_cpus) or 'any',
        'messages_published': len(feed.msgs),
        'samples': len(ready),
        'states_received': int(latencies.size),
        'dropped_samples': len(ready) - int(latencies.size),
        'latency_ms': _percentiles_ms(latencies),
        'replay_wall_s': round(wall_s, 3),
        'publish_lag_ms_p99': round(float(np.percentile(lag, 99)) * 1e3, 3),
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
    parser.add_argument('--deployment', choices=(*DEPLOYMENTS, 'both', 'all'), default='both',
                        help='both: single and separate; all: every deployment')
    parser.add_argument('--timing', choices=(*TIMINGS, 'all'), default='simulator',
                        help='sensor stream timing of the estimator and floor deployments')
    parser.add_argument('--domain-id', type=int, default=1 + os.getpid() % 100)
    parser.add_argument('--monitor-cpus', type=lambda text: tuple(int(c) for c in text.split(',')),
                        default=(), help='pin the node processes to these CPUs (e.g. 1) and '
                        'this process to the others')
    parser.add_argument('--out', type=Path, default=None, help='also write the JSON here')
    args = parser.parse_args()
    if args.monitor_cpus:
        others = os.sched_getaffinity(0) - set(args.monitor_cpus)
        if not others or not set(args.monitor_cpus) <= os.sched_getaffinity(0):
            parser.error(f'--monitor-cpus {args.monitor_cpus}: needs CPUs this process may use, '
                         f'and one left for it ({sorted(os.sched_getaffinity(0))})')
        os.sched_setaffinity(0, others)     # before any thread (DDS's) is started
    run = simulate(args.seconds)
    deployments = {'both': ('single', 'separate'), 'all': tuple(DEPLOYMENTS)}.get(
        args.deployment, (args.deployment,))
    timings = tuple(TIMINGS) if args.timing == 'all' else (args.timing,)
    runs = []
    for deployment in deployments:
        if deployment not in SENSOR_DEPLOYMENTS:
            runs.append(replay(deployment, measurement_feed(run), args.domain_id, [],
                               args.monitor_cpus))
            continue
        for name in timings:
            timing = TIMINGS[name]
            driving = ['-p', 'driving_joints:=' + json.dumps(list(LEGS))] if timing.joint_groups else []
            result = replay(deployment, sensor_feed(run, timing), args.domain_id, driving,
                            args.monitor_cpus)
            runs.append({'timing': name, **result})
    result = {
        'command': 'benchmarks/bench_monitor_latency.py ' + ' '.join(sys.argv[1:]),
        'replayed_s': round(run.measurements[-1].t - run.measurements[0].t, 3),
        'model': 'models/default_model.json', 'params': 'config/monitor.yaml',
        'runs': runs, 'cpus': os.cpu_count(), 'python': platform.python_version(),
    }
    text = json.dumps(result, indent=1)
    print(text)
    if args.out is not None:
        args.out.write_text(text + '\n')


if __name__ == '__main__':
    main()
