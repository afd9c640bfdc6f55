"""Helpers of the node and bring-up tests (no tests here).

* a per-process ROS domain (from the pid) with localhost-only discovery, so concurrent test
  runs and other ROS systems on the machine never meet;
* a real model file, hand-built: falling when the horizontal linear momentum exceeds 25 kg m/s
  in any direction of the heading frame (walking stays below 10 kg m/s; a 45 N s push exceeds
  25 kg m/s within the push, about 1 s before the robot is fallen);
* :class:`Probe`, the tests' own ROS node: push requests, resets, parameter changes, and
  everything the nodes publish, recorded.
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool, Trigger

from fall_predictor import ros_qos
from fall_predictor.nodes.observer import push_request_msg
from fall_predictor.decision_list import Condition, DecisionList, PerModeDecisionLists, Rule
from fall_predictor.model_file import ModelMetadata, save_model
from fall_predictor.nodes.common import (PUSH_REQUEST, UNMATCHED_INPUTS, create_publisher,
                                         create_subscription, spin_until)
from fall_predictor.records import FALLING, FEATURE_NAMES, N_CONTACT_MODES, PushSpec
from fall_predictor.wire import (CONTROLLER_MODE, DIAGNOSTICS, MEASUREMENT, STATE,
                                 PredictorState, WireFormatError)

#: Momentum threshold of the test model [kg m/s].
MOMENTUM_THRESHOLD = 25.0
#: History window recommended by the test model [s].
MODEL_TAU_HIS_S = 0.01
#: After a reset, samples from this time on still belong to the old run [s].
NEW_RUN_T_S = 0.5


def test_domain_id(offset: int) -> int:
    """A ROS domain id for this test process: 1..70 from the pid, plus ``offset`` (0, 70 or
    140, one per test module), always within Fast DDS's 0..232."""
    return 1 + os.getpid() % 70 + offset


test_domain_id.__test__ = False        # a helper, not a test


def write_momentum_model(path: Path) -> Path:
    """Save the hand-built momentum model (every contact mode) with ``save_model``."""
    x, y = FEATURE_NAMES.index('lin_mom_x'), FEATURE_NAMES.index('lin_mom_y')
    rules = tuple(Rule((Condition(feature, op, threshold),), FALLING)
                  for feature in (x, y)
                  for op, threshold in (('>', MOMENTUM_THRESHOLD), ('<=', -MOMENTUM_THRESHOLD)))
    lists = PerModeDecisionLists(tuple(DecisionList(rules) for _ in range(N_CONTACT_MODES)))
    save_model(path, lists, ModelMetadata(
        tau_plus_s=0.0, balanced_weight=4.0, falling_weight=1.0, learner_name='hand-built',
        learner_params={'momentum_threshold_kg_m_s': MOMENTUM_THRESHOLD},
        dataset_fingerprint='none', recommended_tau_his_s=MODEL_TAU_HIS_S))
    return path


@contextmanager
def ros_context(domain_id: int) -> Iterator[rclpy.Context]:
    """An initialised rclpy context on ``domain_id`` with localhost-only discovery."""
    saved = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    context = rclpy.Context()
    try:
        rclpy.init(context=context, domain_id=domain_id)
    finally:
        if saved is None:
            os.environ.pop('ROS_AUTOMATIC_DISCOVERY_RANGE')
        else:
            os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = saved
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


@dataclass
class Status:
    """One /diagnostics status as received."""

    level: int
    message: str
    values: dict[str, str]


class Probe:
    """The tests' node: sends requests, records what the fall monitor publishes."""

    def __init__(self, context: rclpy.Context) -> None:
        self.node = Node('test_probe', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        node = self.node
        self.push_pub = create_publisher(node, WrenchStamped, PUSH_REQUEST)
        self.reset_client = node.create_client(Trigger, '/simulator_node/reset')
        self.pause_client = node.create_client(SetBool, '/simulator_node/pause')
        #: (t, fallen) of every measurement; every state; (latest t, mode) per mode message.
        self.samples: list[tuple[float, bool]] = []
        self.states: list[PredictorState] = []
        self.modes: list[tuple[float, str]] = []
        self.diagnostics: dict[str, Status] = {}
        # After a reset: drop samples and states of the old run still in flight.
        self._skip_old_samples = self._skip_old_states = False
        self.subscriptions = [
            create_subscription(node, Float64MultiArray, MEASUREMENT, self._on_measurement),
            create_subscription(node, DiagnosticArray, STATE, self._on_state),
            create_subscription(node, String, CONTROLLER_MODE, self._on_mode),
            create_subscription(node, DiagnosticArray, DIAGNOSTICS, self._on_diagnostics),
        ]

    def destroy(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()

    # -- recording -------------------------------------------------------------------------
    def _on_measurement(self, msg: Float64MultiArray) -> None:
        try:
            m = ros_qos.measurement_from_msg(msg)
        except WireFormatError:
            return                          # the tests' own injected garbage
        if self._skip_old_samples and m.t >= NEW_RUN_T_S:
            return
        self._skip_old_samples = False
        self.samples.append((m.t, m.fallen))

    def _on_state(self, msg: DiagnosticArray) -> None:
        state = ros_qos.state_from_msg(msg)
        if self._skip_old_states and state.t >= NEW_RUN_T_S:
            return
        self._skip_old_states = False
        self.states.append(state)

    def _on_mode(self, msg: String) -> None:
        self.modes.append((self.samples[-1][0] if self.samples else -1.0, msg.data))

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            self.diagnostics[status.name] = Status(
                status.level[0], status.message, {kv.key: kv.value for kv in status.values})

    def all_inputs_matched(self, node_names: Iterable[str]) -> bool:
        """Every named node has reported /diagnostics with all its inputs connected."""
        return all(name in self.diagnostics
                   and self.diagnostics[name].values.get(UNMATCHED_INPUTS) == ''
                   for name in node_names)

    @property
    def t(self) -> float:
        """Latest measurement time [s] received (-1 before any)."""
        return self.samples[-1][0] if self.samples else -1.0

    # -- driving ---------------------------------------------------------------------------
    def spin_until(self, done: Callable[[], bool], timeout_s: float) -> bool:
        return spin_until(self.executor, done, timeout_s)

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)

    def reset_world(self) -> None:
        """A fresh world; forget what was received (and what of the old run is in flight)."""
        self.samples.clear()
        self.states.clear()
        self.modes.clear()
        self._skip_old_samples = self._skip_old_states = True
        future = self.reset_client.call_async(Trigger.Request())
        assert self.spin_until(future.done, 10.0), 'no answer from /simulator_node/reset'
        assert future.result().success

    def pause_world(self) -> None:
        future = self.pause_client.call_async(SetBool.Request(data=True))
        assert self.spin_until(future.done, 10.0), 'no answer from /simulator_node/pause'
        assert future.result().success

    def request_push(self, push: PushSpec) -> None:
        self.push_pub.publish(push_request_msg(push))

    def set_parameters(self, node_name: str, **values: object) -> list[SetParametersResult]:
        """Set parameters of ``node_name`` through its set_parameters service."""
        client = AsyncParameterClient(self.node, node_name)
        assert client.wait_for_services(10.0), f'{node_name} parameter services not found'
        future = client.set_parameters([Parameter(k, value=v) for k, v in values.items()])
        assert self.spin_until(future.done, 10.0), f'{node_name}: set_parameters timed out'
        return list(future.result().results)

    def fresh_diagnostics(self, node_name: str, timeout_s: float = 5.0) -> Status:
        """The next /diagnostics status of ``node_name`` (e.g. '/predictor_node')."""
        self.diagnostics.pop(node_name, None)
        assert self.spin_until(lambda: node_name in self.diagnostics, timeout_s), \
            f'no /diagnostics from {node_name} within {timeout_s} s'
        return self.diagnostics[node_name]

    def first_state(self, predicate: Callable[[PredictorState], bool],
                    t_from: float = -math.inf) -> Optional[PredictorState]:
        return next((s for s in self.states if s.t >= t_from and predicate(s)), None)
