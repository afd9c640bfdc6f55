"""The ROS node that watches the fall monitor from outside: one for the bring-up and the tests.

:class:`Observer` resets and pauses the simulator, requests pushes, changes node parameters,
and records what the nodes publish (measurements, predictor states, controller modes,
``/diagnostics``). The bring-up (:mod:`fall_predictor.ros.bringup`, which starts the monitor's
nodes as processes) drives its push runs with :meth:`Observer.run_push`; the node tests and the
latency benchmark use the same node. This module holds the rclpy side of the bring-up so that
importing the bring-up, e.g. to build the command line, stays light.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, NamedTuple, Optional

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.client import Client
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger

from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.errors import BringupError
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import UNMATCHED_INPUTS
from fall_predictor.ros.runner import spin_until
from fall_predictor.contract import messages
from fall_predictor.contract.topics import (CONTROLLER_MODE, DIAGNOSTICS, MEASUREMENT,
                                            MONITOR_RESET_SERVICE, PAUSE_SERVICE, PUSH_REQUEST,
                                            RESET_SERVICE, STATE, WireFormatError)
from fall_predictor.monitor.records import PushSpec
from fall_predictor.msg import FallState
from fall_predictor.msg import Measurement as MeasurementMsg
# What a run is made of (ROS-free); ObservedState is also importable from here, with Observer.
from fall_predictor.ros.run_observation import (DEFAULT_SAMPLE_PERIOD_S, ObservedState,
                                                RunBoundary, RunObservation)

#: Node name of the observer unless its user names it.
DEFAULT_NODE_NAME = 'fall_predictor_observer'
#: Wall time [s] to wait for a service's or a node's answer.
ANSWER_TIMEOUT_S = 10.0
#: Wall time [s] without simulation progress after which a run is declared stuck.
_PROGRESS_TIMEOUT_S = 20.0
#: Wall time [s] to collect states still in flight at the end of a run.
_STATE_DRAIN_S = 1.0


class ObserverError(BringupError):
    """The running system did not answer the observer, or refused a request (a
    :class:`BringupError`, so that the bring-up reports it like its other failures)."""


class ReceivedSample(NamedTuple):
    """One measurement as the observer recorded it."""

    t: float                                #: sample time [s]
    fallen: bool


class ModeChange(NamedTuple):
    """One ``/fall_predictor/controller_mode`` message."""

    t: float                                #: latest sample time received then [s] (-1: none)
    mode: str


@dataclass
class NodeStatus:
    """One node's latest ``/diagnostics`` status."""

    level: int
    message: str
    values: dict[str, str]


def _status_name(node_name: str) -> str:
    """The name a node's ``/diagnostics`` status carries: its fully qualified name."""
    return node_name if node_name.startswith('/') else f'/{node_name}'


class Observer:
    """A ROS node outside the fall monitor: resets, pauses, pushes, parameter changes, and a
    record of what the nodes publish.

    Recorded since the last :meth:`reset_world` (messages of the previous run still in flight
    are dropped): :attr:`samples`, :attr:`states`, :attr:`modes`; over the node's lifetime:
    :attr:`controller_mode` (the latest) and :attr:`diagnostics` (each node's latest status,
    keyed by its fully qualified name, e.g. ``'/predictor_node'``). Methods that take a node
    name accept it with or without the leading slash. Requests the system does not answer
    (or refuses) raise :class:`ObserverError`.

    Args:
        context: An initialised rclpy context (its domain is the system's).
        node_name: This node's name.
        follow_streams: Subscribe to the measurement, state and controller mode topics. Off,
            the node only calls services, publishes push requests and reads ``/diagnostics``:
            for a user that subscribes on its own (the latency benchmark), so that the system
            it measures has no second 1 kHz reader to serve.
    """

    def __init__(self, context: rclpy.Context, node_name: str = DEFAULT_NODE_NAME, *,
                 follow_streams: bool = True) -> None:
        self.node = Node(node_name, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        node = self.node
        self.reset_client = node.create_client(Trigger, RESET_SERVICE)
        self.pause_client = node.create_client(SetBool, PAUSE_SERVICE)
        #: The monitor's one reset (its other nodes and the controller follow its RESET event).
        self.monitor_reset_client = node.create_client(Trigger, MONITOR_RESET_SERVICE)
        self.push_pub = create_publisher(node, WrenchStamped, PUSH_REQUEST)
        #: The stream subscriptions (each must be matched before a run can be followed).
        self.subscriptions = [
            create_subscription(node, MeasurementMsg, MEASUREMENT, self._on_measurement,
                                lossless=True),
            create_subscription(node, FallState, STATE, self._on_state, lossless=True),
            create_subscription(node, String, CONTROLLER_MODE, self._on_mode),
        ] if follow_streams else []
        self._diagnostics_sub = create_subscription(node, DiagnosticArray, DIAGNOSTICS,
                                                    self._on_diagnostics)
        self._parameter_clients: dict[str, AsyncParameterClient] = {}
        self.samples: list[ReceivedSample] = []
        self.states: list[ObservedState] = []
        self.modes: list[ModeChange] = []
        self.controller_mode: Optional[str] = None
        self.diagnostics: dict[str, NodeStatus] = {}
        #: The push run :meth:`run_push` follows (it stays after the run ends).
        self.run: Optional[RunObservation] = None
        # After a reset: drop samples and states of the previous run still in flight.
        self._run_boundary = RunBoundary()

    def destroy(self) -> None:
        """Stop the executor and destroy the node."""
        self.executor.shutdown()
        self.node.destroy_node()

    # -- recording -------------------------------------------------------------------------
    def _on_measurement(self, msg: MeasurementMsg) -> None:
        try:
            m = messages.measurement_from_msg(msg).measurement
        except WireFormatError:
            return                          # not a sample (e.g. the node tests' garbage)
        if m is None:
            return                          # a fault: no state to record
        if not self._run_boundary.take_sample(m.t):
            return                          # still the previous run, in flight
        self.samples.append(ReceivedSample(m.t, m.fallen))
        if self.run is not None:
            self.run.add_measurement(m)

    def _on_state(self, msg: FallState) -> None:
        try:
            stamp_ns, monitor_state = messages.fall_state_from_msg(msg)
        except WireFormatError:
            return
        state = ObservedState(stamp_ns / 1e9, monitor_state)
        if not self._run_boundary.take_state(state.t):
            return
        self.states.append(state)
        if self.run is not None:
            self.run.add_state(state)

    def _on_mode(self, msg: String) -> None:
        self.controller_mode = msg.data
        self.modes.append(ModeChange(self.t_last, msg.data))

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            self.diagnostics[status.name] = NodeStatus(
                status.level[0], status.message, {kv.key: kv.value for kv in status.values})

    @property
    def t_last(self) -> float:
        """Latest sample time [s] received since the last reset (-1 before any)."""
        return self.samples[-1].t if self.samples else -1.0

    def first_state(self, predicate: Callable[[ObservedState], bool],
                    t_from: float = -math.inf) -> Optional[ObservedState]:
        """The first recorded state at or after ``t_from`` [s] for which ``predicate`` holds."""
        return next((s for s in self.states if s.t >= t_from and predicate(s)), None)

    def all_inputs_matched(self, node_names: Iterable[str]) -> bool:
        """Every named node has reported on ``/diagnostics`` that all its inputs are matched."""
        statuses = (self.diagnostics.get(_status_name(name)) for name in node_names)
        return all(status is not None and status.values.get(UNMATCHED_INPUTS) == ''
                   for status in statuses)

    def connected(self, node_names: Iterable[str]) -> bool:
        """Every named node reports all its inputs matched, and so is this node (including
        the monitor's reset service when the predictor node is named)."""
        node_names = list(node_names)
        monitor = any(n.lstrip('/').endswith('predictor_node') for n in node_names)
        return (self.all_inputs_matched(node_names)
                and (not monitor or self.monitor_reset_client.service_is_ready())
                and self.reset_client.service_is_ready() and self.pause_client.service_is_ready()
                and self.push_pub.get_subscription_count() >= 1
                and all(s.get_publisher_count() >= 1 for s in self.subscriptions))

    # -- driving ---------------------------------------------------------------------------
    def spin_until(self, done: Callable[[], bool], timeout_s: float,
                   check: Callable[[], None] = lambda: None) -> bool:
        """Spin until ``done()`` or ``timeout_s`` wall seconds; ``check()`` may raise.

        Returns:
            Whether ``done()`` became true.
        """
        return spin_until(self.executor, done, timeout_s, check)

    def spin_for(self, seconds: float, check: Callable[[], None] = lambda: None) -> None:
        """Spin (record what arrives) for ``seconds`` wall seconds; ``check()`` may raise."""
        self.spin_until(lambda: False, seconds, check)

    def call(self, client: Client, request: Any, timeout_s: float = ANSWER_TIMEOUT_S) -> None:
        """Call a simulator service and wait for its success.

        Raises:
            ObserverError: No answer within ``timeout_s`` wall seconds, or a failure answer.
        """
        future = client.call_async(request)
        if not self.spin_until(future.done, timeout_s):
            raise ObserverError(f'{client.srv_name} did not answer within {timeout_s} s')
        if not future.result().success:
            raise ObserverError(f'{client.srv_name} failed: {future.result().message}')

    def reset_world(self) -> None:
        """Start a new run: pause the simulator, reset the monitor if it is up (its one reset,
        the only way to undo a fall; the controller follows it), then reset the simulator (a
        fresh world at t = 0), and start a new record."""
        self.samples.clear()
        self.states.clear()
        self.modes.clear()
        self._run_boundary.reset()
        if self.pause_client.service_is_ready():
            self.call(self.pause_client, SetBool.Request(data=True))
            self.spin_for(0.05)             # let the last samples of the old run arrive
        if self.monitor_reset_client.service_is_ready():
            self.call(self.monitor_reset_client, Trigger.Request())
        self.call(self.reset_client, Trigger.Request())

    def pause_world(self) -> None:
        """Pause the simulator (a recorded run ends here)."""
        self.call(self.pause_client, SetBool.Request(data=True))

    def request_push(self, push: PushSpec) -> None:
        """Ask the simulator for ``push`` (onset ``push.t_push`` in simulation time)."""
        self.push_pub.publish(ros_qos.push_request_to_msg(push))

    def set_parameters(self, node_name: str, **values: object) -> list[SetParametersResult]:
        """Set parameters of ``node_name`` through its parameter services.

        Returns:
            One result per value, in order; a refused value is ``successful`` false with the
            node's ``reason``.

        Raises:
            ObserverError: The node's parameter services are not found or do not answer.
        """
        client = self._parameter_clients.get(node_name)
        if client is None:
            # One client per node: each one adds six service clients to the DDS graph.
            client = self._parameter_clients[node_name] = AsyncParameterClient(
                self.node, node_name)
        if not client.wait_for_services(ANSWER_TIMEOUT_S):
            raise ObserverError(f'{node_name}: parameter services not found within '
                                f'{ANSWER_TIMEOUT_S} s')
        future = client.set_parameters([Parameter(k, value=v) for k, v in values.items()])
        if not self.spin_until(future.done, ANSWER_TIMEOUT_S):
            raise ObserverError(f'{node_name}: set_parameters did not answer within '
                                f'{ANSWER_TIMEOUT_S} s')
        return list(future.result().results)

    def fresh_diagnostics(self, node_name: str, timeout_s: float = 5.0) -> NodeStatus:
        """The next ``/diagnostics`` status of ``node_name`` (its latest is forgotten first).

        Raises:
            ObserverError: None within ``timeout_s`` wall seconds.
        """
        name = _status_name(node_name)
        self.diagnostics.pop(name, None)
        if not self.spin_until(lambda: name in self.diagnostics, timeout_s):
            raise ObserverError(f'no /diagnostics from {name} within {timeout_s} s')
        return self.diagnostics[name]

    # -- one push run of the bring-up --------------------------------------------------------
    def simulator_sample_period_s(self, node_name: str = 'simulator_node') -> float:
        """The period [s] of the measurements the simulator drives, as its ``/diagnostics``
        reports it (:data:`DEFAULT_SAMPLE_PERIOD_S` before it has)."""
        status = self.diagnostics.get(_status_name(node_name))
        try:
            return float(status.values['sample_period_s'])
        except (AttributeError, KeyError, ValueError):
            return DEFAULT_SAMPLE_PERIOD_S

    def run_push(self, index: int, push: PushSpec, horizon_s: float,
                 check: Callable[[], None],
                 fallen_com_height_m: Optional[float] = None) -> dict[str, object]:
        """Reset, push, and watch one run until fallen or ``horizon_s`` after the push ended,
        then pause the simulator.

        Args:
            index: The run's index (reported).
            push: The push to request.
            horizon_s: Simulation time [s] watched after the push ends.
            check: Called while spinning; may raise to abort (e.g. a node died).
            fallen_com_height_m: The robot's fallen CoM height [m] (its profile's); None: the
                default robot's.

        Returns:
            The run's JSON-ready result (:meth:`RunObservation.result`).

        Raises:
            BringupError: The simulation did not advance for a while, or a service failed.
        """
        self.run = run = RunObservation(push, self.simulator_sample_period_s(),
                                        fallen_com_height_m)
        self.reset_world()
        self.request_push(push)
        t_end = push.t_force_end + horizon_s
        last = (time.monotonic(), run.t_last)

        def progressing() -> None:
            nonlocal last
            check()
            now = time.monotonic()
            if run.t_last != last[1]:
                last = (now, run.t_last)
            elif now - last[0] > _PROGRESS_TIMEOUT_S:
                raise BringupError(f'push {index}: the simulation did not advance for '
                                   f'{_PROGRESS_TIMEOUT_S} s (stuck at t = {run.t_last} s)')

        self.spin_until(lambda: run.t_fallen is not None or run.t_last >= t_end - 1e-9,
                        math.inf, progressing)
        self.pause_world()                  # the run's bag ends here
        t_stop = run.t_last
        self.spin_until(lambda: run.t_last_state >= t_stop, _STATE_DRAIN_S, check)
        return run.result(index, round(t_end, 6), self.controller_mode)
