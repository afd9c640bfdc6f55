#!/usr/bin/env python3
"""A minimal consumer of the fall monitor: copy it into your robot's code and adapt.

It subscribes, as an integrator's node would, to

* ``fall_predictor/falling`` (std_msgs/Bool, reliable + transient local, depth 1): the trigger.
  Because it is latched, a node that starts late still learns that a fall was called.
* ``fall_predictor/state`` (std_msgs/Float64MultiArray, best effort, depth 10), read by slot
  index (layout ``fall_predictor/state/v2``; no string parsing);
* ``fall_predictor/fall_direction`` (geometry_msgs/Vector3Stamped, heading frame, latched).

Topic names are relative: run it in the monitor's namespace (``-r __ns:=/robot1``).

    python3 examples/fall_consumer.py [--exit-on-fall] --ros-args -r __ns:=/robot1

Only rclpy and standard messages are imported, so it runs without this package installed.
"""
import argparse
import math
import sys

import rclpy
from geometry_msgs.msg import Vector3Stamped
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from std_msgs.msg import Bool, Float64MultiArray

# Slots of the state layout fall_predictor/state/v2 (see the package README).
T, STATUS, FALLING, LATCHED, ATOMIC, GUARD, CONTACT_MODE, TAU_HIS, TIME_TO_FALL = range(9)
DIRECTION_X, DIRECTION_Y = 9, 10
STATUS_NAMES = {0: 'ok', 1: 'disabled', 2: 'stale'}
STATE_LABEL = 'fall_predictor/state/v2'

TRIGGER_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)


class FallConsumer(Node):
    """Logs the trigger, the fall direction and, once a second, the latest state."""

    def __init__(self, exit_on_fall: bool) -> None:
        super().__init__('fall_consumer')
        self.exit_on_fall = exit_on_fall
        self.done = False
        self.falling = None
        self.latest_state = None
        self.create_subscription(Bool, 'fall_predictor/falling', self.on_falling, TRIGGER_QOS)
        self.create_subscription(Float64MultiArray, 'fall_predictor/state', self.on_state,
                                 qos_profile_sensor_data)
        self.create_subscription(Vector3Stamped, 'fall_predictor/fall_direction',
                                 self.on_direction, TRIGGER_QOS)
        self.create_timer(1.0, self.log_state)

    def on_falling(self, msg: Bool) -> None:
        self.falling = msg.data
        # This is where a robot switches to its fall controller.
        self.get_logger().info(f'falling: {msg.data}')
        self.log_state()
        if msg.data and self.exit_on_fall:
            self.done = True

    def on_state(self, msg: Float64MultiArray) -> None:
        if msg.layout.dim and msg.layout.dim[0].label == STATE_LABEL:
            self.latest_state = msg.data

    def on_direction(self, msg: Vector3Stamped) -> None:
        heading_deg = math.degrees(math.atan2(msg.vector.y, msg.vector.x))
        self.get_logger().info(f'fall direction: {heading_deg:.0f} deg from the heading '
                               f'(frame {msg.header.frame_id})')

    def log_state(self) -> None:
        s = self.latest_state
        if s is not None:
            self.get_logger().info(
                f't = {s[T]:.3f} s, {STATUS_NAMES.get(int(s[STATUS]), "?")}, '
                f'falling {bool(s[FALLING])}, latched {bool(s[LATCHED])}, '
                f'time to fall {s[TIME_TO_FALL]:.2f} s')


def main(args=None) -> int:
    argv = sys.argv[1:] if args is None else args
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--exit-on-fall', action='store_true',
                        help='exit (code 0) when the trigger says falling')
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
