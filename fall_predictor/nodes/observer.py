"""The bring-up's own ROS node: it resets the simulator, requests pushes and watches what the
fall monitor says about each run (used by :mod:`fall_predictor.bringup`, which starts the
monitor's nodes as processes; this module holds its rclpy side so that importing the bring-up,
e.g. to build the command line, stays light)."""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Optional

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rclpy.client import Client
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool, Trigger

from fall_predictor import ros_qos
from fall_predictor.bringup import (PAUSE_SERVICE, PIPELINE_NODES, RECORDER_NODE, RESET_SERVICE,
                                    BringupError)
from fall_predictor.nodes.common import (PUSH_REQUEST, PUSH_REQUEST_FRAME, UNMATCHED_INPUTS,
                                         create_publisher, create_subscription, spin_until)
from fall_predictor.records import PushSpec
from fall_predictor.wire import CONTROLLER_MODE, DIAGNOSTICS, MEASUREMENT, STATE, WireFormatError

#: After a reset, samples from this time on still belong to the previous run [s].
_NEW_RUN_T_S = 0.5
#: Wall time [s] without simulation progress after which a run is declared stuck.
_PROGRESS_TIMEOUT_S = 20.0
#: Wall time [s] to collect states still in flight at the end of a run.
_STATE_DRAIN_S = 1.0


def _round_time(t: Optional[float]) -> Optional[float]:
    """A sample time [s] without float noise (samples are 1 ms apart)."""
    return None if t is None else round(t, 6)


@dataclass
class RunObservation:
    """What the bring-up saw of one run (times in simulation seconds)."""

    push: PushSpec
    t_last: float = -1.0                    #: latest measurement time of this run
    t_last_state: float = -1.0              #: latest state time of this run
    t_fallen: Optional[float] = None
    t_predict: Optional[float] = None       #: first falling state at or after the push
    false_alarm_before_push: bool = False
    degraded_states: int = 0
    push_applied_n: Optional[list[float]] = None
    measurements_started: bool = False
    states_started: bool = False

    def result(self, index: int, horizon_end_s: float,
               controller_mode: Optional[str]) -> dict[str, object]:
        """The run's JSON-ready report (fields: see :mod:`fall_predictor.bringup`)."""
        push = self.push
        fell = self.t_fallen is not None
        predicted_in_time = (self.t_predict is not None
                             and (not fell or self.t_predict <= self.t_fallen))
        if fell:
            outcome = 'fall_predicted' if predicted_in_time else 'fall_missed'
        else:
            outcome = 'predicted_no_fall' if self.t_predict is not None else 'no_fall'
        lead = (self.t_fallen - self.t_predict) if fell and predicted_in_time else None
        return {
            'index': index,
            'push': {'force_n': push.force_n, 'angle_deg': push.angle_deg,
                     'height_m': push.height_m, 't_push': push.t_push,
                     'duration_s': push.duration_s, 'impulse_ns': push.impulse_ns},
            'push_applied_world_n': self.push_applied_n,
            'fell': fell,
            't_predict': _round_time(self.t_predict),
            't_fallen': _round_time(self.t_fallen),
            'lead_time_s': None if lead is None else round(lead, 6),
            'oracle_lead_s': None if not fell else round(self.t_fallen - push.t_push, 6),
            'outcome': outcome,
            'stopped_by': 'fallen' if fell else 'horizon',
            't_end': _round_time(self.t_last),
            'horizon_end_s': horizon_end_s,
            'controller_mode': controller_mode,
            'false_alarm_before_push': self.false_alarm_before_push,
            'degraded_states': self.degraded_states,
        }


def push_request_msg(push: PushSpec) -> WrenchStamped:
    """A push request for the simulator node: onset stamp, heading-frame force [N] and its
    torque about the CoM, ``(0, 0, h) x F`` [N m] (see ``nodes.common.PUSH_REQUEST``)."""
    angle = math.radians(push.angle_deg)
    fx, fy = push.force_n * math.cos(angle), push.force_n * math.sin(angle)
    msg = WrenchStamped()
    msg.header.stamp = ros_qos.stamp(push.t_push)
    msg.header.frame_id = PUSH_REQUEST_FRAME
    msg.wrench.force.x, msg.wrench.force.y = fx, fy
    msg.wrench.torque.x, msg.wrench.torque.y = -push.height_m * fy, push.height_m * fx
    return msg


class Observer:
    """The bring-up's own ROS node: resets, push requests, and what the monitor says."""

    def __init__(self, context: rclpy.Context) -> None:
        self.node = Node('fall_predictor_bringup', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        node = self.node
        self.reset_client = node.create_client(Trigger, RESET_SERVICE)
        self.pause_client = node.create_client(SetBool, PAUSE_SERVICE)
        self.push_pub = create_publisher(node, WrenchStamped, PUSH_REQUEST)
        self.subscriptions = [
            create_subscription(node, Float64MultiArray, MEASUREMENT, self._on_measurement),
            create_subscription(node, DiagnosticArray, STATE, self._on_state),
            create_subscription(node, String, CONTROLLER_MODE, self._on_mode),
        ]
        self._diagnostics_sub = create_subscription(node, DiagnosticArray, DIAGNOSTICS,
                                                    self._on_diagnostics)
        self.run: Optional[RunObservation] = None
        self.controller_mode: Optional[str] = None
        #: Per node (fully qualified name): its input topics without a matched publisher.
        self.unmatched_inputs: dict[str, str] = {}

    def destroy(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()

    def spin_until(self, done: Callable[[], bool], timeout_s: float,
                   check: Callable[[], None] = lambda: None) -> bool:
        """Spin until ``done()`` or ``timeout_s`` wall seconds; ``check()`` may raise."""
        return spin_until(self.executor, done, timeout_s, check)

    def connected(self, with_recorder: bool) -> bool:
        """Every node reports all its inputs matched, and so is this node."""
        expected = PIPELINE_NODES + ((RECORDER_NODE,) if with_recorder else ())
        return (all(self.unmatched_inputs.get(f'/{name}') == '' for name in expected)
                and self.reset_client.service_is_ready() and self.pause_client.service_is_ready()
                and self.push_pub.get_subscription_count() >= 1
                and all(s.get_publisher_count() >= 1 for s in self.subscriptions))

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            for value in status.values:
                if value.key == UNMATCHED_INPUTS:
                    self.unmatched_inputs[status.name] = value.value

    # -- one run ---------------------------------------------------------------------------
    def call(self, client: Client, request: Any, timeout_s: float = 10.0) -> None:
        """Call a simulator service and wait for its success."""
        future = client.call_async(request)
        if not self.spin_until(future.done, timeout_s):
            raise BringupError(f'{client.srv_name} did not answer within {timeout_s} s')
        if not future.result().success:
            raise BringupError(f'{client.srv_name} failed: {future.result().message}')

    def request_push(self, push: PushSpec) -> None:
        self.push_pub.publish(push_request_msg(push))

    def _on_measurement(self, msg: Float64MultiArray) -> None:
        run = self.run
        if run is None:
            return
        try:
            m = ros_qos.measurement_from_msg(msg)
        except WireFormatError:
            return
        if not run.measurements_started:
            if m.t >= _NEW_RUN_T_S:
                return                       # still the previous run, in flight
            run.measurements_started = True
        run.t_last = m.t
        if run.push_applied_n is None and m.push_force.any():
            run.push_applied_n = [round(float(v), 6) for v in m.push_force]
        if run.t_fallen is None and m.fallen:
            run.t_fallen = m.t

    def _on_state(self, msg: DiagnosticArray) -> None:
        run = self.run
        if run is None:
            return
        try:
            state = ros_qos.state_from_msg(msg)
        except WireFormatError:
            return
        if not run.states_started:
            if state.t >= _NEW_RUN_T_S:
                return
            run.states_started = True
        run.t_last_state = max(run.t_last_state, state.t)
        if state.stale_reason is not None:
            # Degraded states before the run's first sample only say it had not started.
            run.degraded_states += run.measurements_started
        elif state.falling:
            if state.t < run.push.t_push:
                run.false_alarm_before_push = True
            elif run.t_predict is None:
                run.t_predict = state.t

    def _on_mode(self, msg: String) -> None:
        self.controller_mode = msg.data

    def run_push(self, index: int, push: PushSpec, horizon_s: float,
                 check: Callable[[], None]) -> dict[str, object]:
        """Reset, push, and watch one run; returns its result."""
        self.run = run = RunObservation(push)
        self.call(self.reset_client, Trigger.Request())
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
        self.call(self.pause_client, SetBool.Request(data=True))    # the run's bag ends here
        t_stop = run.t_last
        self.spin_until(lambda: run.t_last_state >= t_stop, _STATE_DRAIN_S, check)
        return run.result(index, round(t_end, 6), self.controller_mode)
