#!/usr/bin/env python3
"""The CPU of the monitor's own callbacks, without rclpy's executor or DDS in the way.

``fall_monitor --estimator``'s three nodes (state estimator, feature, predictor) are created in
this process as that executable creates them (in-process hand-off, ``config/monitor.yaml``), with
a subscriber of ``fall_predictor/state`` so that its publisher has a reader, as on a robot. The
sensor messages of a simulated walk (``bench_monitor_latency``'s run and sensor feed, restamped to
now) are serialized, then handed to the estimator's subscription callbacks one by one, as rclpy
hands them over; the thread's CPU time over the walking part (the second and third quarters of
the run, before the push) divided by its samples is what the nodes' Python costs per sample. Over
DDS the same process also pays rclpy's executor and middleware (``bench_monitor_latency.py
--deployment floor``), and the benchmark's load on the other core shakes its CPU figures by
several percent of a core from run to run; this one repeats to about 1 %.

The garbage collector's work over the same part is reported too (collections per generation,
their total and longest pause): the feed's message objects are dropped and collected before the
walk, so the heap it scans is the monitor's, as in its own process.

``--profile SORT`` prints a cProfile of the same part instead (sorted by ``tottime`` or
``cumulative``).

    .venv/bin/python benchmarks/bench_monitor_callbacks.py --seconds 12 --repeats 3 \\
        --out docs/monitor/rclpy_floor/callbacks.json
"""
from __future__ import annotations

import argparse
import cProfile
import gc
import json
import os
import platform
import pstats
import time
from pathlib import Path

import numpy as np
import rclpy
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from fall_predictor.contract.topics import STATE
from fall_predictor.msg import FallState
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.ros.endpoints import create_subscription
from fall_predictor.ros.fall_monitor import MONITOR_NODES, in_process_chain

from bench_monitor_latency import REPO, sensor_feed, simulate
from bench_robot_streams import TIMINGS


class CollectorLog:
    """The garbage collector's collections while :attr:`on`: count per generation, pauses."""

    def __init__(self) -> None:
        self.on = False
        self.counts = [0, 0, 0]
        self.pauses_s: list[float] = []
        self._start = 0.0

    def __call__(self, phase: str, info: dict) -> None:
        if not self.on:
            return
        if phase == 'start':
            self._start = time.perf_counter()
        else:
            self.pauses_s.append(time.perf_counter() - self._start)
            self.counts[info['generation']] += 1


def one_run(seconds: float, profile_sort: str | None) -> tuple[float, dict] | None:
    """Our callbacks' CPU per sample [µs] over the walk of one fresh set of nodes, and the
    garbage collector's work meanwhile (None when profiled)."""
    from fall_predictor.ros.state_estimator_node import StateEstimatorNode

    context = rclpy.Context()
    # The feed is handed over faster than real time: samples may be seconds "early".
    rclpy.init(context=context, args=['--ros-args', '--params-file',
                                      str(REPO / 'config' / 'monitor.yaml'),
                                      '-p', 'max_sample_age_s:=10.0'])
    nodes = [make() for make in in_process_chain((StateEstimatorNode, *MONITOR_NODES),
                                                  context=context)]
    listener = rclpy.create_node('bench_listener', context=context)
    try:
        estimator = nodes[0]
        estimator._on_description(String(data=rm.URDF_PATH.read_text()))
        create_subscription(listener, FallState, STATE, lambda msg: None, lossless=True)
        run = simulate(seconds)
        feed = sensor_feed(run, TIMINGS['simulator'])
        stamp0 = time.time_ns()
        for k, msg in enumerate(feed.msgs):
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(
                stamp0 + int(feed.stamps_ns[k]), 1_000_000_000)
        handlers = {'joints': estimator._on_joint_state, 'imu': estimator._on_imu,
                    'l': lambda data: estimator._on_wrench('l', data),
                    'r': lambda data: estimator._on_wrench('r', data)}
        calls = [(handlers[topic], serialize_message(msg))
                 for topic, msg in zip(feed.topics, feed.msgs)]
        quarter = len(calls) // 4
        for handler, data in calls[:quarter]:          # warm up: caches, the first samples
            handler(data)
        # Two flat lists (bytes are not tracked by the collector), the feed collected: the
        # collector then scans the monitor's heap, not the benchmark's.
        walk_handlers = [handler for handler, _ in calls[quarter:3 * quarter]]
        walk_data = [data for _, data in calls[quarter:3 * quarter]]
        samples = len({s for s in feed.sample_of[quarter:3 * quarter].tolist() if s >= 0})
        del calls, feed, run
        gc.collect()
        if profile_sort:
            profiler = cProfile.Profile()
            profiler.enable()
        collector = CollectorLog()
        enabled, count_before = gc.isenabled(), gc.get_count()
        gc.callbacks.append(collector)
        collector.on = True
        cpu0 = time.thread_time()
        for handler, data in zip(walk_handlers, walk_data):
            handler(data)
        cpu = time.thread_time() - cpu0
        collector.on = False
        gc.callbacks.remove(collector)
        if profile_sort:
            profiler.disable()
            pstats.Stats(profiler).sort_stats(profile_sort).print_stats(40)
            return None
        states = nodes[-1].counts
        if states['states'] == 0 or states['degraded_states'] > samples // 100:
            raise SystemExit(f'the nodes did not predict on the walk: {states}')
        return cpu / samples * 1e6, {
            'samples': samples, 'collector_enabled': enabled,
            'allocation_counts_before_after': [count_before, gc.get_count()],
            'collections_per_generation': collector.counts,
            'pause_us_per_sample': round(sum(collector.pauses_s) / samples * 1e6, 2),
            'longest_pause_ms': round(max(collector.pauses_s, default=0.0) * 1e3, 3),
            'tracked_objects': len(gc.get_objects())}
    finally:
        for node in (*nodes, listener):
            node.destroy_node()
        rclpy.try_shutdown(context=context)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=12.0, help='simulated seconds (the '
                        'push comes 1.5 s before the end)')
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--profile', choices=('tottime', 'cumulative'), default=None)
    parser.add_argument('--out', type=Path, default=None, help='also write the JSON here')
    args = parser.parse_args()
    if args.profile:
        one_run(args.seconds, args.profile)
        return
    runs = [one_run(args.seconds, None) for _ in range(args.repeats)]
    per_sample = [cpu for cpu, _ in runs]
    result = {
        'command': 'benchmarks/bench_monitor_callbacks.py --seconds '
                   f'{args.seconds:g} --repeats {args.repeats}',
        'deployment': 'fall_monitor --estimator (state estimator, feature, predictor nodes), '
                      'callbacks called directly with serialized sensor messages',
        'model': 'models/default_model.json', 'params': 'config/monitor.yaml',
        'cpu_us_per_sample': [round(v, 1) for v in per_sample],
        'cpu_us_per_sample_median': round(float(np.median(per_sample)), 1),
        'garbage_collector': [collector for _, collector in runs],
        'load_average_1min': os.getloadavg()[0], 'cpus': os.cpu_count(),
        'python': platform.python_version(),
    }
    text = json.dumps(result, indent=1)
    print(text)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + '\n')


if __name__ == '__main__':
    main()
