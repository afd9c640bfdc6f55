#!/usr/bin/env python3
"""The rclpy floor of ``fall_monitor --estimator``: a node with the monitor's inputs and output
that computes nothing (``bench_monitor_latency.py --deployment floor``).

It subscribes to the robot's sensor topics as the state estimator does (serialized messages,
the topics' QoS from the package's contract, the robot's foot sensors included), and for the
first joint state of each stamp publishes a ``fall_predictor/state`` of that stamp, serialized
as the predictor node serializes it (``contract/cdr.fall_state_cdr``). It spins on the package's default executor (``ros/runner.py``) and
reports itself on ``/diagnostics`` as the monitor's nodes do, so the benchmark drives it exactly
as it drives the monitor. Its CPU is what rclpy costs to take those messages and publish the
states: a floor under any monitor written as rclpy nodes.
"""
from __future__ import annotations

import struct
import sys

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState

from fall_predictor.contract import cdr
from fall_predictor.contract.wire import LEVEL_OK
from fall_predictor.contract.topics import (HEADING_FRAME, IMU, LEFT_FOOT_WRENCH,
                                            RIGHT_FOOT_WRENCH, SENSOR_JOINT_STATES, STATE)
from fall_predictor.monitor.fall_monitor import STATUS_OK, MonitorState
from fall_predictor.msg import FallState
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import Diagnostics
from fall_predictor.ros.runner import run_nodes

#: A header's stamp in a CDR message: after the 4-byte encapsulation, sec (int32), nanosec.
_STAMP = struct.Struct('<iI')
_STATE = MonitorState(STATUS_OK, contact_mode=0)


class FloorNode(Node):
    def __init__(self) -> None:
        super().__init__('rclpy_floor')
        self._state = create_publisher(self, FallState, STATE)
        self._last_ns = -1
        self.counts = {'joint_messages': 0, 'other_messages': 0, 'states': 0}
        self._inputs = [create_subscription(self, JointState, SENSOR_JOINT_STATES,
                                            self._on_joint_state, raw=True)]
        self._inputs += [create_subscription(self, msg_type, spec, self._on_other, raw=True)
                         for msg_type, spec in ((Imu, IMU), (WrenchStamped, LEFT_FOOT_WRENCH),
                                                (WrenchStamped, RIGHT_FOOT_WRENCH))]
        self._diagnostics = Diagnostics(self, self._report, lambda: max(self._last_ns, 0),
                                        self._inputs, None)

    def _on_joint_state(self, data: bytes) -> None:
        self.counts['joint_messages'] += 1
        sec, nanosec = _STAMP.unpack_from(data, 4)
        ns = sec * 1_000_000_000 + nanosec
        if ns != self._last_ns:
            self._last_ns = ns
            self._state.publish(cdr.fall_state_cdr(ns, HEADING_FRAME, _STATE))
            self.counts['states'] += 1

    def _on_other(self, data: bytes) -> None:
        self.counts['other_messages'] += 1

    def _report(self):
        return LEVEL_OK, 'taking messages', dict(self.counts)


if __name__ == '__main__':
    raise SystemExit(run_nodes([FloorNode], 'rclpy_floor', sys.argv))
