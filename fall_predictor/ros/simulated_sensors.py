"""The simulator node's sensor publishers (``publish_sensors``): the sensor model of
:mod:`fall_predictor.sim.sensors` on the robot's standard topics."""
from __future__ import annotations

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.publisher import Publisher
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from fall_predictor.data.topics import IMU, LEFT_FOOT_WRENCH, RIGHT_FOOT_WRENCH, ROBOT_DESCRIPTION
from fall_predictor.ros.common import create_publisher
from fall_predictor.ros.sensor_conversions import reading_to_msgs
from fall_predictor.sim.sensors import SensorParams, SensorSuite, robot_description, sensor_truth


class SimulatedSensors:
    """Publishes the robot description once and one sensor sample per simulation step."""

    def __init__(self, node: Node, noise_scale: float, seed: int) -> None:
        self.params = SensorParams(noise_scale=noise_scale)
        self.seed = seed
        self._imu = create_publisher(node, Imu, IMU)
        self._left = create_publisher(node, WrenchStamped, LEFT_FOOT_WRENCH)
        self._right = create_publisher(node, WrenchStamped, RIGHT_FOOT_WRENCH)
        self._description = create_publisher(node, String, ROBOT_DESCRIPTION)
        self._description.publish(String(data=robot_description()))
        self._suite = SensorSuite(self.params, seed)

    def new_world(self, world: int) -> None:
        """Fresh biases and delay lines for a new world (seeded by the seed and world count)."""
        self._suite = SensorSuite(self.params, self.seed * 100003 + world)

    def publish(self, sim, joint_state_pub: Publisher) -> None:
        """The readings of ``sim``'s current step (joint states on ``joint_state_pub``)."""
        joints, imu, left, right = reading_to_msgs(self._suite.read(sensor_truth(sim)))
        joint_state_pub.publish(joints)
        self._imu.publish(imu)
        self._left.publish(left)
        self._right.publish(right)
