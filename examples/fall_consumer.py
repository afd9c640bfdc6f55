#!/usr/bin/env python3
"""A minimal consumer of the fall monitor: copy it into your robot's code and adapt.

It subscribes, as an integrator's node would, to

* ``fall_predictor/fall_event`` (fall_predictor/msg/FallEvent, reliable + transient local, depth
  1): FALLING (switch to your fall controller now; with the predicted direction and time to
  fall), FALLEN, STANDING, RESET. Latched: a node that starts late still learns the last event.
* ``fall_predictor/state`` (fall_predictor/msg/FallState, best effort, depth 10): one per
  sample, with named fields and constants (status, reason, falling, latched, contact mode, ...).

Topic names are relative: run it in the monitor's namespace (``-r __ns:=/robot1``).

    python3 examples/fall_consumer.py [--exit-on-fall] --ros-args -r __ns:=/robot1

It needs rclpy and the package's messages (``fall_predictor.msg``); a consumer that wants common
types only reads ``fall_predictor/falling`` (std_msgs/Bool, latched) instead.
"""
import argparse
import math
import sys

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data

from fall_predictor.msg import FallEvent, FallState

EVENT_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
STATUS_NAMES = {FallState.STATUS_OK: 'ok', FallState.STATUS_DEGRADED: 'degraded',
                FallState.STATUS_STALE: 'stale', FallState.STATUS_DISABLED: 'disabled',
                FallState.STATUS_FALLEN: 'fallen'}
EVENT_NAMES = {FallEvent.EVENT_FALLING: 'FALLING', FallEvent.EVENT_FALLEN: 'FALLEN',
               FallEvent.EVENT_STANDING: 'STANDING', FallEvent.EVENT_RESET: 'RESET'}


class FallConsumer(Node):
    """Logs each fall event and, once a second, the latest state."""

    def __init__(self, exit_on_fall: bool) -> None:
        super().__init__('fall_consumer')
        self.exit_on_fall = exit_on_fall
        self.done = False
        self.latest_state = None
        self.create_subscription(FallEvent, 'fall_predictor/fall_event', self.on_event, EVENT_QOS)
        self.create_subscription(FallState, 'fall_predictor/state', self.on_state,
                                 qos_profile_sensor_data)
        self.create_timer(1.0, self.log_state)

    def on_event(self, msg: FallEvent) -> None:
        if msg.event == FallEvent.EVENT_FALLING:
            # This is where a robot switches to its fall controller.
            heading_deg = math.degrees(math.atan2(msg.direction.y, msg.direction.x))
            self.get_logger().info(
                f'FALLING: direction {heading_deg:.0f} deg from the heading (frame '
                f'{msg.header.frame_id}), time to fall {msg.time_to_fall:.2f} s')
            self.done = self.exit_on_fall
        else:
            self.get_logger().info(EVENT_NAMES.get(msg.event, f'event {msg.event}'))
        self.log_state()

    def on_state(self, msg: FallState) -> None:
        self.latest_state = msg

    def log_state(self) -> None:
        s = self.latest_state
        if s is not None:
            stamp = s.header.stamp.sec + s.header.stamp.nanosec * 1e-9
            reason = f' ({s.reason})' if s.reason else ''
            self.get_logger().info(
                f'stamp {stamp:.3f} s, {STATUS_NAMES.get(s.status, "?")}{reason}, '
                f'falling {s.falling}, latched {s.latched}')


def main(args=None) -> int:
    argv = sys.argv[1:] if args is None else args
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--exit-on-fall', action='store_true',
                        help='exit (code 0) at the FALLING event')
    ros_args = rclpy.utilities.remove_ros_args(argv)
    options = parser.parse_args(ros_args)
    rclpy.init(args=argv)
    node = FallConsumer(options.exit_on_fall)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok() and not node.done:
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
