"""Replaying a recording's sensor data into a live monitor the way a robot's drivers publish it.

:class:`SensorReplayer` is a node that publishes ``robot_description`` and, in real time, the
sensor messages of a recording re-timed by :class:`~fall_predictor.sim.drivers.DriverTiming`
(stamps: ROS time now, so the monitor's age check runs as on a robot), and listens to the monitor's
events and states. The robot-streams benchmark and its DDS test drive ``fall_monitor --estimator``
with it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import rclpy
from geometry_msgs.msg import WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger

from fall_predictor.contract import messages
from fall_predictor.contract.topics import (FALL_EVENT, IMU, LEFT_FOOT_WRENCH, MONITOR_RESET_SERVICE,
                                            RIGHT_FOOT_WRENCH, ROBOT_DESCRIPTION,
                                            SENSOR_JOINT_STATES, STATE)
from fall_predictor.monitor.fall_monitor import EVENT_FALLING
from fall_predictor.monitor.sensor_records import SensorSample
from fall_predictor.msg import FallEvent, FallState
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.runner import spin_until
from fall_predictor.sim.drivers import DriverTiming, driver_messages

_BUILD = {'joints': messages.joint_state_msg, 'imu': messages.imu_msg,
          'l': messages.wrench_msg, 'r': messages.wrench_msg}


@dataclass
class ReplayResult:
    """What the monitor said during one replay (times relative to the recording's start [s])."""

    falling_s: list[float] = field(default_factory=list)    #: FALLING events
    states: int = 0                                         #: FallState messages
    status_counts: dict[int, int] = field(default_factory=dict)
    joint_messages: int = 0                                 #: joint state messages published
    #: States that answer a published joint state's stamp (OK, DEGRADED, FALLEN, or STALE for a
    #: sample that came too late), each stamp once; the watchdog's STALE states answer none.
    sample_states: int = 0
    publish_lag_s: float = 0.0                              #: worst lag of the publishing loop

    @property
    def first_alarm_s(self) -> float | None:
        return self.falling_s[0] if self.falling_s else None


class SensorReplayer:
    """The robot's side: its sensor topics out, the monitor's events and states in."""

    def __init__(self, context: rclpy.Context, namespace: str = '') -> None:
        self.node = Node('sensor_replayer', namespace=namespace, context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.pubs = {'joints': create_publisher(self.node, JointState, SENSOR_JOINT_STATES),
                     'imu': create_publisher(self.node, Imu, IMU),
                     'l': create_publisher(self.node, WrenchStamped, LEFT_FOOT_WRENCH),
                     'r': create_publisher(self.node, WrenchStamped, RIGHT_FOOT_WRENCH)}
        self.description = create_publisher(self.node, String, ROBOT_DESCRIPTION)
        self._events: list[tuple[int, int]] = []
        self._states: list[tuple[int, int]] = []
        create_subscription(self.node, FallEvent, FALL_EVENT,
                            lambda m: self._events.append((messages.stamp_ns(m), m.event)))
        create_subscription(self.node, FallState, STATE,
                            lambda m: self._states.append((messages.stamp_ns(m), m.status)),
                            lossless=True)

    def destroy(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()

    def spin_until(self, done: Callable[[], bool], timeout_s: float) -> bool:
        return spin_until(self.executor, done, timeout_s)

    def connected(self, streams: Sequence[str] = ('joints', 'imu', 'l', 'r')) -> bool:
        """The description and each of ``streams`` have a subscriber (a robot without foot F/T
        sensors: ``('joints', 'imu')``, its monitor subscribes to no wrench)."""
        return (all(self.pubs[stream].get_subscription_count() for stream in streams)
                and self.description.get_subscription_count() > 0)

    def publish_description(self, urdf: str) -> None:
        self.description.publish(String(data=urdf))

    def reset_monitor(self, timeout_s: float = 10.0) -> None:
        """The monitor's one reset (a new run: no latch, no history)."""
        client = self.node.create_client(Trigger, MONITOR_RESET_SERVICE)
        try:
            if not client.wait_for_service(timeout_sec=timeout_s):
                raise RuntimeError(f'{MONITOR_RESET_SERVICE} not available')
            future = client.call_async(Trigger.Request())
            if not self.spin_until(future.done, timeout_s) or not future.result().success:
                raise RuntimeError(f'{MONITOR_RESET_SERVICE} did not succeed')
        finally:
            self.node.destroy_client(client)

    def replay(self, samples: Sequence[SensorSample], timing: DriverTiming,
               drain_s: float = 1.0) -> ReplayResult:
        """Publish ``samples`` as ``timing``'s drivers would, in real time from now (the stamps:
        now + the samples' times; ``timing.clock_offset_ns`` is replaced), then listen for
        ``drain_s``; what the monitor said."""
        self._events.clear()
        self._states.clear()
        offset_ns = time.time_ns() + 200_000_000
        timing = DriverTiming(**{**timing.to_dict(), 'clock_offset_ns': offset_ns,
                                 'joint_groups': timing.joint_groups})
        result = ReplayResult()
        joint_stamps = set()
        for stream, reading in driver_messages(samples, timing):
            while time.time_ns() < reading.stamp_ns:
                self.executor.spin_once(timeout_sec=0.0)
            result.publish_lag_s = max(result.publish_lag_s, (time.time_ns() - reading.stamp_ns) / 1e9)
            self.pubs[stream].publish(_BUILD[stream](ros_qos.TYPES, reading))
            if stream == 'joints':
                result.joint_messages += 1
                joint_stamps.add(reading.stamp_ns)
        self.spin_until(lambda: False, drain_s)
        result.falling_s = [(stamp - offset_ns) / 1e9 for stamp, kind in self._events
                            if kind == EVENT_FALLING]
        result.states = len(self._states)
        result.sample_states = len({stamp for stamp, _ in self._states} & joint_stamps)
        for _, status in self._states:
            result.status_counts[status] = result.status_counts.get(status, 0) + 1
        return result
