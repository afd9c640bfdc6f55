#!/usr/bin/env python3
"""Soak: the fall monitor and the recorder fed for minutes at 1 kHz with 1 % malformed input.

A standing robot (the measurement of ``test/test_recorder_crash.py`` with a 1 mm, 0.5 Hz CoM
sway) is published at 1 kHz of wall time, stamped in ROS time (wall time), into two node
processes: ``fall_monitor`` (``config/monitor.yaml``, the shipped model) and ``recorder_node``.
After 1 % of the valid samples (chosen at random, seeded) one malformed message is published
as well, in turn: a value out of the plausibility bounds (CoM height 5 m), a NaN (linear
momentum), a base orientation that is no rotation (the zero quaternion) and an out-of-order stamp
(a valid measurement 0.5 s older than the last). Every valid sample time is published exactly
once, as a ``fall_predictor/msg/Measurement``.

Reported: the node processes' pids and exit codes (never restarted: same pids throughout, each
alive until stopped, exit code 0); per valid sample whether its state arrived, and the nodes'
own counts of missing, stale, out-of-order and invalid samples; the recorder's received /
written / rejected counts and the valid sample times found in its bag; the RSS of each process
every 10 s (first, last, max, and the slope of a line fitted to the samples after the first
minute, or the first 10 s of a run shorter than 3 minutes).

    .venv/bin/python benchmarks/bench_soak.py --minutes 10 --out docs/monitor/soak.json
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import sys
import tempfile
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import serialize_message

from fall_predictor.data.bagio import read_trajectory
from fall_predictor.contract import messages
from fall_predictor.contract.topics import MEASUREMENT, ODOM_FRAME, STATE
from fall_predictor.monitor.records import Measurement
from fall_predictor.ros.bringup import ros_environment, start_process, stop_nodes
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.msg import FallState, Measurement as MeasurementMsg
from fall_predictor.ros import conversions as ros_qos

from pacing import wait_until                   # noqa: E402  (benchmarks/ is on the path)
from portable_paths import portable             # noqa: E402  (benchmarks/ is on the path)

REPO = Path(__file__).resolve().parents[1]
KINDS = ('out_of_bounds', 'nan', 'not_a_rotation', 'out_of_order')
RSS_PERIOD_S = 10.0


def standing(t: float) -> Measurement:
    """The standing robot at sample time ``t`` [s] (CoM swaying 1 mm at 0.5 Hz)."""
    feet = np.array([[0.1, 0.1, 200.0], [-0.1, 0.1, 200.0], [-0.1, -0.1, 200.0], [0.1, -0.1, 200.0]])
    sway = 0.001 * np.sin(np.pi * t)
    return Measurement(t=t, com=np.array([sway, 0.0, 0.59]),
                       lin_mom=np.array([42.1 * 0.001 * np.pi * np.cos(np.pi * t), 0.0, 0.0]),
                       ang_mom=np.zeros(3), heading=0.0, cop=np.array([sway, 0.0, 0.0]),
                       left_contacts=feet[:2], right_contacts=feet[2:],
                       left_foot=np.array([0.0, 0.1, 0.0]), right_foot=np.array([0.0, -0.1, 0.0]),
                       non_foot_contact=False)


def measurement_msg(t: float, stamp_ns: int) -> MeasurementMsg:
    """The ``fall_predictor/msg/Measurement`` of :func:`standing` at sample time ``t``, stamped
    ``stamp_ns`` (ROS time: the monitor refuses samples older than ``max_sample_age_s``)."""
    return messages.measurement_msg(ros_qos.TYPES, stamp_ns, ODOM_FRAME, standing(t))


class StandingMessages:
    """Messages of :func:`standing`, built by patching the five values that change into one
    message (building one costs ~0.1 ms a sample on a loaded machine)."""

    def __init__(self) -> None:
        self.msg = measurement_msg(0.0, 0)
        for t, ns in ((0.25, 7), (1.0, 1_795_000_000_123_000_000), (7.3, 12_000_000)):
            assert serialize_message(self.message(t, ns)) == serialize_message(measurement_msg(t, ns))

    def message(self, t: float, stamp_ns: int) -> MeasurementMsg:
        msg = self.msg
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        sway = 0.001 * np.sin(np.pi * t)
        msg.com.x = msg.cop.x = float(sway)
        msg.linear_momentum.x = float(42.1 * 0.001 * np.pi * np.cos(np.pi * t))
        return msg


def malformed(kind: str, t: float, stamp_ns: int) -> MeasurementMsg:
    """A malformed measurement of ``kind`` published after the sample at ``t`` / ``stamp_ns``."""
    if kind == 'out_of_order':
        return measurement_msg(t - 0.5, stamp_ns - 500_000_000)
    msg = measurement_msg(t, stamp_ns)
    if kind == 'out_of_bounds':
        msg.com.z = 5.0
    elif kind == 'nan':
        msg.linear_momentum.x = math.nan
    elif kind == 'not_a_rotation':
        msg.base_orientation.x = msg.base_orientation.y = msg.base_orientation.z = 0.0
        msg.base_orientation.w = 0.0
    return msg


def rss_mb(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024.0
    return float('nan')


def rss_summary(samples: list[tuple[float, float]]) -> dict[str, float]:
    t = np.array([s[0] for s in samples])
    mb = np.array([s[1] for s in samples])
    warm_up_s = 60.0 if t[-1] >= 180.0 else 10.0    # start-up allocations left out
    later = t >= warm_up_s
    slope = (float(np.polyfit(t[later], mb[later], 1)[0]) * 60.0 if later.sum() >= 3
             else float('nan'))
    return {'first_mb': round(float(mb[0]), 1), 'last_mb': round(float(mb[-1]), 1),
            'max_mb': round(float(mb.max()), 1), 'slope_from_s': warm_up_s,
            'slope_mb_per_min': round(slope, 3)}


def soak(minutes: float, seed: int, domain_id: int, work: Path) -> dict[str, object]:
    env = ros_environment(domain_id)
    bags = work / 'bags'
    params = ['--ros-args', '--params-file', str(REPO / 'config' / 'monitor.yaml')]
    nodes = {
        'fall_monitor': start_process('fall_monitor', [
            sys.executable, '-m', 'fall_predictor.ros.fall_monitor', *params], env, work),
        'recorder_node': start_process('recorder_node', [
            sys.executable, '-m', 'fall_predictor.ros.recorder_node', '--ros-args',
            '-p', f'bag_path:={bags}', '-p', 'start_type_description_service:=false'], env, work),
    }
    pids = {name: n.process.pid for name, n in nodes.items()}
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id)
    sender = Node('soak_robot', context=context)
    receiver = Node('soak_receiver', context=context)
    publisher = create_publisher(sender, MeasurementMsg, MEASUREMENT)
    states: dict[int, int] = {}                 # sample time [ms] -> state status
    counters: dict[str, dict[str, str]] = {}

    def on_state(msg: FallState) -> None:
        states.setdefault(round(messages.stamp_ns(msg) / 1e6), int(msg.status))

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            counters[status.name] = {kv.key: kv.value for kv in status.values}
            counters[status.name]['level'] = str(status.level[0])
            counters[status.name]['message'] = status.message

    state_sub = create_subscription(receiver, FallState, STATE, on_state, lossless=True)
    receiver.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 50)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(receiver)
    stop = threading.Event()
    rss: dict[str, list[tuple[float, float]]] = {name: [] for name in [*nodes, 'this_process']}
    alive_throughout = {name: True for name in nodes}

    def receive() -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.01)

    def sample_rss(start: float) -> None:
        while True:
            now = time.monotonic() - start
            for name, n in nodes.items():
                alive_throughout[name] &= n.process.poll() is None
                if alive_throughout[name]:
                    rss[name].append((now, rss_mb(n.process.pid)))
            rss['this_process'].append((now, rss_mb(os.getpid())))
            if stop.wait(RSS_PERIOD_S):
                return

    receiver_thread = threading.Thread(target=receive, daemon=True)
    receiver_thread.start()
    rng = np.random.default_rng(seed)
    n_valid = int(round(minutes * 60_000))
    # Malformed samples from the second second on: an out-of-order stamp 0.5 s old then
    # still lies inside the recording (an older one would start a new run: method §12).
    bad_after = np.sort(rng.choice(np.arange(1000, n_valid), size=n_valid // 100, replace=False))
    bad_kinds = [KINDS[i % len(KINDS)] for i in range(len(bad_after))]
    try:
        deadline = time.monotonic() + 90.0
        while not (publisher.get_subscription_count() >= 2 and state_sub.get_publisher_count() >= 1
                   and len(counters) >= 3):
            if time.monotonic() > deadline or any(n.process.poll() is not None
                                                  for n in nodes.values()):
                raise RuntimeError('nodes did not start:\n' + '\n'.join(
                    n.log_tail() for n in nodes.values()))
            time.sleep(0.05)
        time.sleep(1.0)
        start = time.monotonic() + 0.01
        rss_thread = threading.Thread(target=sample_rss, args=(start,), daemon=True)
        rss_thread.start()
        t0 = 1.0                                # the robot's clock when the soak starts [s]
        stamp0_ns = (time.time_ns() // 1_000_000 + 10) * 1_000_000   # its stamp: ROS time, whole ms
        standing_messages = StandingMessages()
        next_bad = 0
        lag = np.empty(n_valid)
        for k in range(n_valid):
            due = start + 0.001 * k
            wait_until(due)                     # releases the CPU and the GIL meanwhile
            lag[k] = time.monotonic() - due
            t = t0 + 0.001 * k
            stamp_ns = stamp0_ns + 1_000_000 * k
            publisher.publish(standing_messages.message(t, stamp_ns))
            while next_bad < len(bad_after) and bad_after[next_bad] == k:
                publisher.publish(malformed(bad_kinds[next_bad], t, stamp_ns))
                next_bad += 1
        wall_s = time.monotonic() - start
        time.sleep(3.0)                         # states in flight, one more diagnostics report
        for name, n in nodes.items():
            alive_throughout[name] &= n.process.poll() is None
    finally:
        stop.set()
        receiver_thread.join(timeout=2.0)
        sender.destroy_node()
        receiver.destroy_node()
        rclpy.try_shutdown(context=context)
        codes = stop_nodes(nodes)
    keys = [stamp0_ns // 1_000_000 + k for k in range(n_valid)]
    got = sum(1 for key in keys if key in states)
    statuses: dict[str, int] = {}
    for key in keys:
        if key in states:
            statuses[str(states[key])] = statuses.get(str(states[key]), 0) + 1
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        runs = sorted(bags.glob('run_*'))
        recorded = [m.t for run in runs for m in (read_trajectory(run).measurements or [])]
    recorded_ms = [round(t * 1000) for t in recorded]
    recorded_set = set(recorded_ms)
    in_bag = sum(1 for key in keys if key in recorded_set)
    feature = counters.get('/feature_node', {})
    recorder = counters.get('/recorder_node', {})
    predictor = counters.get('/predictor_node', {})
    received, written, rejected = (int(x) for x in recorder.get(
        f'{MEASUREMENT.name} received/written/rejected', '-1/-1/-1').split('/'))
    run_records = {run.name: json.loads((run / 'fall_predictor.json').read_text())
                   for run in runs if (run / 'fall_predictor.json').exists()}
    return {
        'valid_samples': n_valid,
        'malformed_samples': {kind: bad_kinds.count(kind) for kind in KINDS},
        'wall_s': round(wall_s, 3),
        'publish_lag_ms_p99': round(float(np.percentile(lag, 99)) * 1e3, 3),
        'publish_lag_ms_max': round(float(lag.max()) * 1e3, 3),
        'pids': pids, 'alive_throughout': alive_throughout, 'exit_codes': codes,
        'states_for_valid_samples': got,
        'valid_samples_without_state': n_valid - got,
        'state_status_counts': statuses,
        'feature_node_missing_samples': int(feature.get('missing_samples', -1)),
        'valid_samples_unaccounted': n_valid - got - int(feature.get('missing_samples', 0)),
        # With the feature node's count: a valid sample that got features but whose state
        # never reached this process was lost on the way to the consumer (only it sees that).
        # The predictor's count also holds its staleness reports (timer, no new sample).
        'features_published_by_feature_node': int(feature.get('features', -1)),
        'states_published_by_predictor': int(predictor.get('states', -1)),
        'states_received_in_all': len(states),
        'recorder_measurements_received_written_rejected': [received, written, rejected],
        'node_diagnostics': counters,
        'bag_runs': [run.name for run in runs],
        'bag_measurements': len(recorded_ms),
        'bag_valid_samples': in_bag,
        'bag_valid_samples_missing': n_valid - in_bag,
        'bag_extra_messages': len(recorded_ms) - in_bag,
        'bag_holds_every_accepted_message': len(recorded_ms) == written == received - rejected,
        'bag_reader_warnings': [str(w.message) for w in caught],
        'run_records': run_records,
        'rss': {name: rss_summary(samples) for name, samples in rss.items() if samples},
        'rss_samples_mb': {name: [round(mb, 1) for _, mb in samples]
                           for name, samples in rss.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--minutes', type=float, default=10.0, help='soak duration [min]')
    parser.add_argument('--seed', type=int, default=14)
    parser.add_argument('--domain-id', type=int, default=1 + os.getpid() % 100)
    parser.add_argument('--work', type=Path, default=None,
                        help='directory for the node logs and the bag (default: a temporary one, '
                             'removed afterwards)')
    parser.add_argument('--out', type=Path, default=None, help='also write the JSON here')
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix='bench_soak_'))
    work.mkdir(parents=True, exist_ok=True)
    try:
        result = {'command': 'benchmarks/bench_soak.py ' + ' '.join(sys.argv[1:]),
                  'model': 'models/default_model.json', 'params': 'config/monitor.yaml',
                  **soak(args.minutes, args.seed, args.domain_id, work),
                  'cpus': os.cpu_count(), 'python': platform.python_version(),
                  'load_average_after': [round(x, 2) for x in os.getloadavg()]}
    finally:
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)
    text = json.dumps(portable(result), indent=1)   # no machine path in a committed file
    print(text)
    if args.out is not None:
        args.out.write_text(text + '\n')


if __name__ == '__main__':
    main()
