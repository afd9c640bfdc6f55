#!/usr/bin/env python3
"""Where the fall monitor's CPU goes per 1 kHz sample: its own work or rclpy's executor.

Runs the ``fall_monitor`` nodes (feature + predictor, in-process hand-off, the shipped model,
``config/monitor.yaml``) in this process on a measured trajectory (a walk, then a push that
fells the robot) and times, per sample, in CPU time of this single thread:

* ``chain``: the feature node's measurement callback called directly, which runs the whole
  chain (checks, features, the in-process hand-off, prediction, packing and publishing the
  features and the state over DDS): the package's own work plus rclpy's ``publish``;
* ``through_executor``: the same measurements published on the measurement topic by a node of
  this process and taken by the feature node through ``SingleThreadedExecutor.spin_once``
  (wait set, take, deserialization, task): the chain plus what the executor adds;
* ``through_executor_without_parameter_services``: the same with the nodes' six parameter
  services each left out of the wait set (``start_parameter_services=False``), to show how
  the executor's cost grows with the entities it waits on.

No other process takes part, so the figures do not depend on scheduling. Each figure is the
median over ``--repeats`` passes of the trajectory.

    .venv/bin/python benchmarks/bench_monitor_cpu.py --out docs/bench_monitor_cpu.json
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path
from statistics import median

import rclpy
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import Float64MultiArray

from fall_predictor.contract.topics import MEASUREMENT
from fall_predictor.monitor.records import PushSpec
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher
from fall_predictor.ros.fall_monitor import MONITOR_NODES, in_process_chain
from fall_predictor.sim.trajectory import run_trajectory

REPO = Path(__file__).resolve().parents[1]


def _pass(messages: list, parameter_services: bool, through_executor: bool) -> float:
    """CPU seconds per sample of one pass over ``messages`` with fresh nodes."""
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=1 + os.getpid() % 100,
               args=['--ros-args', '--params-file', str(REPO / 'config' / 'monitor.yaml')])
    try:
        feature, predictor = [make() for make in in_process_chain(
            MONITOR_NODES, context=context, start_parameter_services=parameter_services)]
        source = rclpy.create_node('bench_source', context=context)
        publisher = create_publisher(source, Float64MultiArray, MEASUREMENT)
        executor = SingleThreadedExecutor(context=context)
        for node in (feature, predictor):
            executor.add_node(node)
        deadline = time.monotonic() + 10.0
        while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        start = time.process_time()
        for msg in messages:
            if through_executor:
                before = feature.counts['measurements']
                publisher.publish(msg)
                while feature.counts['measurements'] == before:
                    executor.spin_once()
            else:
                feature._on_measurement(msg)
        cpu_s = (time.process_time() - start) / len(messages)
        if predictor.counts['states'] != len(messages):
            raise RuntimeError(f'{predictor.counts["states"]} states for {len(messages)} samples')
        executor.shutdown()
        for node in (source, predictor, feature):
            node.destroy_node()
        return cpu_s
    finally:
        rclpy.try_shutdown(context=context)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=3.0, help='trajectory length [s]')
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--out', type=Path, default=None, help='also write the JSON here')
    args = parser.parse_args()
    push = PushSpec(force_n=450.0, angle_deg=0.0, height_m=0.1, t_push=args.seconds - 1.5)
    measurements = run_trajectory(push, args.seconds, stop_when_fallen=False).measurements
    messages = [ros_qos.measurement_to_msg(m) for m in measurements]
    cases = {'chain': (True, False), 'through_executor': (True, True),
             'through_executor_without_parameter_services': (False, True)}
    per_sample_us = {name: round(1e6 * median(_pass(messages, *flags)
                                              for _ in range(args.repeats)), 1)
                     for name, flags in cases.items()}
    result = {
        'command': 'benchmarks/bench_monitor_cpu.py ' + ' '.join(sys.argv[1:]),
        'samples_per_pass': len(messages), 'repeats': args.repeats,
        'cpu_us_per_sample': per_sample_us,
        'executor_us_per_sample': round(per_sample_us['through_executor']
                                        - per_sample_us['chain'], 1),
        'load_average': [round(x, 2) for x in os.getloadavg()],
        'cpus': os.cpu_count(), 'python': platform.python_version(),
    }
    text = json.dumps(result, indent=1)
    print(text)
    if args.out is not None:
        args.out.write_text(text + '\n')


if __name__ == '__main__':
    main()
