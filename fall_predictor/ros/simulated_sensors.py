"""The simulator node's sensor publishers (``publish_sensors``): the sensor model of
:mod:`fall_predictor.sim.sensors` on the robot's standard topics, each stream at the rate and stamp
offset of :class:`~fall_predictor.sim.drivers.DriverTiming` (as a robot's drivers publish them),
stamped with simulation time. The sensor model runs at the world's physics step (its noise band
and delay lines are per sample), as offline runs make it (``sim/policy_runs.py``)."""
from __future__ import annotations

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.publisher import Publisher
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from fall_predictor.contract import messages
from fall_predictor.contract.topics import IMU, LEFT_FOOT_WRENCH, RIGHT_FOOT_WRENCH, ROBOT_DESCRIPTION
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher
from fall_predictor.sim.drivers import DriverStreams, DriverTiming
from fall_predictor.sim.sensors import SAMPLE_RATE_HZ, SensorParams, SensorSuite, robot_description


class SimulatedSensors:
    """Publishes the robot description once and the sensor messages of every simulation step."""

    def __init__(self, node: Node, noise_scale: float, seed: int,
                 timing: DriverTiming = DriverTiming(), profile=None,
                 dt_s: float = 1.0 / SAMPLE_RATE_HZ) -> None:
        """``dt_s``: the world's physics step [s], one sensor sample per step."""
        self.params = SensorParams(noise_scale=noise_scale)
        self.dt_s = dt_s
        #: The simulated robot (its joints, IMU frame and foot sensors); None: the default robot.
        self.profile = profile
        self.seed = seed
        self.timing = timing
        self._imu = create_publisher(node, Imu, IMU)
        self._wrenches = {'l': create_publisher(node, WrenchStamped, LEFT_FOOT_WRENCH),
                          'r': create_publisher(node, WrenchStamped, RIGHT_FOOT_WRENCH)}
        self._description = create_publisher(node, String, ROBOT_DESCRIPTION)
        self._description.publish(String(data=robot_description(profile)))
        self.new_world(0)

    def new_world(self, world: int) -> None:
        """Fresh biases, delay lines and driver clocks for a new world (seeded by the seed and
        the world count)."""
        self._suite = SensorSuite(self.params, self.seed * 100003 + world, dt_s=self.dt_s,
                                  profile=self.profile)
        self._drivers = DriverStreams(self.timing)

    @property
    def imu_subscribed(self) -> bool:
        """Whether a subscriber of ``imu/data`` is matched."""
        return self._imu.get_subscription_count() > 0

    def publish(self, sim, joint_state_pub: Publisher) -> int:
        """The messages of ``sim``'s current step (joint states on ``joint_state_pub``); returns
        how many joint state messages went out."""
        joint_messages = 0
        for stream, reading in self._drivers.push(self._suite.read(sim.sensor_truth())):
            if stream == 'joints':
                joint_state_pub.publish(messages.joint_state_msg(ros_qos.TYPES, reading))
                joint_messages += 1
            elif stream == 'imu':
                self._imu.publish(messages.imu_msg(ros_qos.TYPES, reading))
            else:
                self._wrenches[stream].publish(messages.wrench_msg(ros_qos.TYPES, reading))
        return joint_messages
