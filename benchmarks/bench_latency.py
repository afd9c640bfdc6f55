"""End-to-end latency of the onboard fall monitor, sample to state, over real DDS.

Starts the simulator, controller, feature and predictor nodes as separate processes (as the
bring-up does: lock-step, ``--real-time-factor``, a private ROS domain) and runs one walk of
``--duration`` simulated seconds. For every simulation sample k it measures the wall-clock
time from the simulator publishing measurement k to this process receiving the predictor's
state stamped with sample k's time (``CLOCK_MONOTONIC``, shared by all processes of the
machine): the simulator runs as a small subclass that notes the time just before each
publish. Printed as one JSON object:

* ``latency_ms``: median, p90, p99 and max over all samples;
* ``dropped_samples``: measurements published without a state received for them;
* ``real_time_factor``: simulated seconds per wall second reached (target in
  ``real_time_factor_target``); below the target, ``cpu_percent`` (per process, over the run)
  and ``load_average`` show what holds it back.

With ``--sensors`` the simulator publishes the robot's sensor topics (1 kHz, one stamp per step)
and the monitor estimates its state from them (``state_estimator_node``, or ``fall_monitor
--estimator`` with ``--single-process-monitor``), as on a robot; the publish time is then noted
after the sample's sensor messages. The nodes' executor is their default or
``FALL_PREDICTOR_EXECUTOR`` (``ros/runner.py``), recorded in the JSON.

Usage: ``python benchmarks/bench_latency.py [--duration 60] [--real-time-factor 1.0]
[--model M]`` (default model: a hand-built momentum model in a temporary directory).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Optional

import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.subscription import Subscription

from fall_predictor.ros.bringup import (NodeProcess, default_domain_id, default_params_file,
                                    node_command, ros_environment, start_process,
                                    stop_nodes)
from fall_predictor.monitor.decision_list import Condition, DecisionList, PerModeDecisionLists, Rule
from fall_predictor.monitor.model_file import ModelMetadata, save_model
from fall_predictor.contract import messages
from fall_predictor.msg import FallState
from fall_predictor.ros.runner import executor_kind
from fall_predictor.ros.endpoints import create_subscription
from fall_predictor.ros.runner import run_node, run_nodes
from fall_predictor.ros.simulated_robot import robot_nodes
from fall_predictor.ros.observer import Observer
from fall_predictor.ros.simulator_node import NODE_NAME, SimulatorNode
from fall_predictor.monitor.records import FALLING, FEATURE_NAMES, N_CONTACT_MODES, Measurement
from fall_predictor.contract.topics import STATE

from portable_paths import portable             # noqa: E402  (benchmarks/ is on the path)

_SIMULATOR_CHILD = '--simulator-child'


def _run_timed_simulator(out: Path, ros_args: list[str], composed: bool = False) -> int:
    """The simulator node, noting (sample time [ms], wall time [s]) before each publish (with
    ``publish_sensors``: after, when the sensor messages are out); ``composed``: with the
    controller node in this process (``simulated_robot``)."""
    published: list[tuple[int, float]] = []

    class TimedSimulatorNode(SimulatorNode):
        def _publish_sample(self, m: Measurement) -> None:
            before = time.monotonic()
            super()._publish_sample(m)
            published.append((round(m.t * 1000),
                              time.monotonic() if self._sensors is not None else before))

    if composed:
        code = run_nodes(robot_nodes(TimedSimulatorNode), 'simulated_robot', ros_args)
    else:
        code = run_node(TimedSimulatorNode, NODE_NAME, ros_args)
    np.save(out, np.array(published, dtype=np.float64).reshape(-1, 2))
    return code


def _momentum_model(path: Path) -> Path:
    """A hand-built model (falling above 25 kg m/s of horizontal momentum), as in the tests."""
    rules = tuple(Rule((Condition(FEATURE_NAMES.index(name), op, threshold),), FALLING)
                  for name in ('lin_mom_x', 'lin_mom_y')
                  for op, threshold in (('>', 25.0), ('<=', -25.0)))
    lists = PerModeDecisionLists(tuple(DecisionList(rules) for _ in range(N_CONTACT_MODES)))
    save_model(path, lists, ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={}, dataset_fingerprint='none', recommended_tau_his_s=0.01))
    return path


def _cpu_seconds(pid: int) -> float:
    """User + system CPU time [s] of a process so far."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def _subscribe_timed_states(node: Node, arrivals: list[tuple[int, float]]) -> Subscription:
    """Note (sample time [ms], wall time [s]) of each non-STALE state as it arrives.

    The benchmark's own subscription (its observer follows no stream): the time is taken
    first thing and only the stamp is read, so that little of this process's work is counted.
    """
    def on_state(msg: FallState) -> None:
        now = time.monotonic()
        if msg.status != FallState.STATUS_STALE:
            arrivals.append((round(messages.stamp_ns(msg) / 1e6), now))

    return create_subscription(node, FallState, STATE, on_state, lossless=True)


def _percentiles_ms(latencies_s: np.ndarray) -> dict[str, float]:
    ms = latencies_s * 1000.0
    return {'median': round(float(np.median(ms)), 3),
            'p90': round(float(np.percentile(ms, 90)), 3),
            'p99': round(float(np.percentile(ms, 99)), 3), 'max': round(float(ms.max()), 3)}


#: The nodes of the simulated system (diagnostics names), whatever process runs them.
NODE_NAMES = ('predictor_node', 'feature_node', 'controller_node', 'simulator_node')


def run_benchmark(duration_s: float, real_time_factor: float, model: Optional[Path],
                  domain_id: int, single_process_monitor: bool = False,
                  composed_robot: bool = False, sensors: bool = False) -> dict[str, object]:
    tmp = Path(tempfile.mkdtemp(prefix='bench_latency_'))
    model = model or _momentum_model(tmp / 'model.json')
    env = ros_environment(domain_id)
    params = default_params_file()
    publish_times = tmp / 'published.npy'
    nodes: dict[str, NodeProcess] = {}
    context = rclpy.Context()
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    rclpy.init(context=context, domain_id=domain_id)
    observer: Optional[Observer] = None
    state_arrivals: list[tuple[int, float]] = []     # (sample time [ms], wall [s])
    try:
        monitor = ((('fall_monitor', {'model_path': str(model)}),) if single_process_monitor
                   else (('predictor_node', {'model_path': str(model)}), ('feature_node', {}),
                         *((('state_estimator_node', {}),) if sensors else ())))
        controller = () if composed_robot else (('controller_node', {'ground_truth': 'true'}
                                                 if sensors else {}),)
        for name, overrides in (*monitor, *controller):
            command = node_command(name, params, overrides)
            if name == 'fall_monitor' and sensors:
                command.insert(3, '--estimator')    # after "python -m <module>"
            nodes[name] = start_process(name, command, env, tmp)
        simulator = {'real_time_factor': repr(float(real_time_factor)), 'autostart': 'false',
                     'lockstep': 'true'}
        if sensors:
            simulator['publish_sensors'] = 'true'
        ros_args = node_command('simulator_node', params, simulator)[3:]  # no "python -m <module>"
        robot = 'simulated_robot' if composed_robot else 'simulator_node'
        nodes[robot] = start_process(
            robot, [sys.executable, __file__, _SIMULATOR_CHILD + ('-composed' if composed_robot
                                                                   else ''),
                    str(publish_times), *ros_args], env, tmp)
        # No stream subscriptions but the timed one: this process must not load the system.
        observer = Observer(context, 'bench_latency', follow_streams=False)
        state_sub = _subscribe_timed_states(observer.node, state_arrivals)

        def check_alive() -> None:
            for node in nodes.values():
                if node.process.poll() is not None:
                    raise RuntimeError(f'{node.name} exited:\n{node.log_tail()}')

        names = NODE_NAMES + (('state_estimator_node',) if sensors else ())
        if not observer.spin_until(lambda: observer.connected(names)
                                   and state_sub.get_publisher_count() >= 1, 60.0, check_alive):
            raise RuntimeError(f'the nodes did not come up (logs in {tmp})')
        load_before = os.getloadavg()
        cpu_before = {name: _cpu_seconds(node.process.pid) for name, node in nodes.items()}
        own_cpu_before = time.process_time()
        wall_start = time.monotonic()
        observer.reset_world()
        last_ms = round(duration_s * 1000)

        def finished() -> bool:
            return bool(state_arrivals) and state_arrivals[-1][0] >= last_ms

        if not observer.spin_until(finished, duration_s / max(real_time_factor, 0.05) * 20 + 60):
            raise RuntimeError('the run did not finish')
        wall_s = time.monotonic() - wall_start
        cpu = {name: round(100.0 * (_cpu_seconds(node.process.pid) - cpu_before[name]) / wall_s, 1)
               for name, node in nodes.items()}
        cpu['bench_latency'] = round(100.0 * (time.process_time() - own_cpu_before) / wall_s, 1)
        load_after = os.getloadavg()
        observer.pause_world()
        observer.spin_for(1.0)
    finally:
        if observer is not None:
            observer.destroy()
        rclpy.try_shutdown(context=context)
        stop_nodes(nodes)

    published = {int(k): t for k, t in np.load(publish_times)}
    received = {}
    for k, t in state_arrivals:
        received.setdefault(k, t)
    samples = [k for k in sorted(published) if k <= last_ms]
    latencies = np.array([received[k] - published[k] for k in samples if k in received])
    simulated_s = samples[-1] / 1000.0
    return {
        'duration_s': simulated_s,
        'wall_s': round(wall_s, 3),
        'real_time_factor_target': real_time_factor,
        'monitor': ('fall_monitor (one process)' if single_process_monitor else 'two processes'
                    if not sensors else 'three processes') + (', from the sensor topics' if sensors
                                                              else ', fed measurements'),
        'executor': executor_kind(),
        'robot': ('simulated_robot (simulator + controller, one process)' if composed_robot
                  else 'simulator_node and controller_node, two processes'),
        'real_time_factor': round(simulated_s / wall_s, 4),
        'samples_published': len(samples),
        'states_received': int(latencies.size),
        'dropped_samples': len(samples) - int(latencies.size),
        'latency_ms': _percentiles_ms(latencies),
        'cpu_percent': cpu,
        'load_average': {'before': [round(x, 2) for x in load_before],
                         'after': [round(x, 2) for x in load_after]},
        'cpus': os.cpu_count(),
        'python': platform.python_version(),
        'logs': str(tmp),
    }


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1].startswith(_SIMULATOR_CHILD):
        sys.exit(_run_timed_simulator(Path(sys.argv[2]), sys.argv[3:],
                                      composed=sys.argv[1].endswith('-composed')))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=60.0,
                        help='simulated seconds (default 60)')
    parser.add_argument('--real-time-factor', type=float, default=1.0,
                        help='simulator pacing: 1.0 = real time (default), 0 = as fast as possible')
    parser.add_argument('--model', type=Path, default=None, help='model file')
    parser.add_argument('--domain-id', type=int, default=None)
    parser.add_argument('--single-process-monitor', action='store_true',
                        help='run the feature and predictor nodes as fall_monitor (one process)')
    parser.add_argument('--composed-robot', action='store_true',
                        help='run the simulator and controller nodes as simulated_robot '
                             '(one process, lock-step closed in process)')
    parser.add_argument('--sensors', action='store_true',
                        help='the simulator publishes the sensor topics; the monitor estimates '
                             'the state (with the state estimator)')
    parser.add_argument('--out', type=Path, default=None, help='also write the JSON here')
    args = parser.parse_args()
    result = run_benchmark(args.duration, args.real_time_factor, args.model,
                           default_domain_id() if args.domain_id is None else args.domain_id,
                           args.single_process_monitor, args.composed_robot, args.sensors)
    text = json.dumps(portable(result), indent=1)   # no machine path in a committed file
    print(text)
    if args.out is not None:
        args.out.write_text(text + '\n')


if __name__ == '__main__':
    main()
