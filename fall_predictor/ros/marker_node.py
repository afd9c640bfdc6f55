"""monitor_markers: what the monitor sees, for RViz or Foxglove (off unless started).

Subscribes to ``fall_predictor/measurement`` and ``fall_predictor/state`` and publishes, at most
``rate_hz`` times a second, ``fall_predictor/markers`` (``visualization_msgs/MarkerArray``, in the
measurement's frame, ``odom``): the support polygon, the CoP, the CoM's ground projection, the
capture point, the predicted fall direction and the status text
(:func:`~fall_predictor.monitor.view.monitor_view`). A separate process, so that drawing never
costs the monitor a sample; start it with ``monitor.launch.py markers:=true`` or
``ros2 run fall_predictor monitor_markers``.
"""
from __future__ import annotations

from typing import Optional

from rclpy.node import Node
from visualization_msgs.msg import MarkerArray

from fall_predictor.contract import messages
from fall_predictor.contract.topics import MARKERS, MEASUREMENT, STATE
from fall_predictor.monitor.fall_monitor import MonitorState
from fall_predictor.monitor.view import monitor_view
from fall_predictor.msg import FallState, Measurement
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.health import HANDLED_ERRORS, InputErrors, guarded, steady_clock
from fall_predictor.ros.markers import view_markers
from fall_predictor.ros.parameters import ParamSpec, declare_parameters
from fall_predictor.ros.robots import ROBOT_PARAM, profile_for
from fall_predictor.ros.runner import run_node

NODE_NAME = 'monitor_markers'
PARAMS = (ROBOT_PARAM,
          ParamSpec('rate_hz', 10.0, 'largest marker rate [Hz]', 0.1, 100.0, read_only=True))


class MarkerNode(Node):
    """Latest measurement + latest state -> markers, on a timer (see the module docs)."""

    def __init__(self, **kwargs: object) -> None:
        super().__init__(NODE_NAME, **kwargs)
        p = declare_parameters(self, PARAMS)
        self._mass_kg = profile_for(str(p['robot'])).total_mass_kg
        self._bad_inputs = InputErrors(self)
        self._measurement: Optional[messages.StampedMeasurement] = None
        self._state: Optional[tuple[int, MonitorState]] = None
        self._published_ns: Optional[int] = None
        self._pub = create_publisher(self, MarkerArray, MARKERS)
        create_subscription(self, Measurement, MEASUREMENT, self._on_measurement)
        create_subscription(self, FallState, STATE, self._on_state)
        self.create_timer(1.0 / float(p['rate_hz']), self._draw, clock=steady_clock())
        self.count = 0

    @guarded('measurement')
    def _on_measurement(self, msg: Measurement) -> None:
        decoded = messages.measurement_from_msg(msg)
        if decoded.measurement is not None:
            self._measurement = decoded

    @guarded('state')
    def _on_state(self, msg: FallState) -> None:
        self._state = messages.fall_state_from_msg(msg)

    def _draw(self) -> None:
        if self._measurement is None or self._state is None:
            return
        stamp_ns = self._measurement.stamp_ns
        if stamp_ns == self._published_ns:
            return
        try:
            view = monitor_view(self._measurement.measurement, self._state[1], self._mass_kg)
            self._pub.publish(view_markers(view, ros_qos.stamp(stamp_ns), self._measurement.frame_id))
        except HANDLED_ERRORS as error:
            self._bad_inputs.reject('markers', error)
            return
        self._published_ns = stamp_ns
        self.count += 1


def main(args: Optional[list[str]] = None) -> int:
    """Entry point: ``python -m fall_predictor.ros.marker_node --ros-args ...``."""
    return run_node(MarkerNode, NODE_NAME, args)


if __name__ == '__main__':
    raise SystemExit(main())
