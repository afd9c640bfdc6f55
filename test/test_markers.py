"""What the monitor sees (monitor/view.py) and its markers (ros/markers.py, ros/marker_node.py)."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from visualization_msgs.msg import Marker, MarkerArray

from fall_predictor.contract import messages
from fall_predictor.contract.topics import MARKERS, MEASUREMENT, STATE
from fall_predictor.monitor.fall_monitor import STATUS_DEGRADED, STATUS_OK, MonitorState
from fall_predictor.monitor.records import Measurement
from fall_predictor.monitor.view import monitor_view
from fall_predictor.msg import FallState
from fall_predictor.msg import Measurement as MeasurementMsg
from fall_predictor.ros import conversions as ros_qos
from fall_predictor.ros.endpoints import create_publisher, create_subscription
from fall_predictor.ros.marker_node import MarkerNode
from fall_predictor.ros.markers import CAPTURE_POINT, COM, COP, DIRECTION, POLYGON, STATUS, view_markers
from fall_predictor.ros.runner import spin_until
from test_nodes_support import ros_context, test_domain_id

MASS_KG = 40.0


def measurement(heading: float = 0.0) -> Measurement:
    """Standing on both soles (two 0.2 x 0.1 m rectangles), CoM 0.6 m high moving at 0.5 m/s in x."""
    left = np.array([[0.1, 0.15, 100.0], [-0.1, 0.15, 100.0], [-0.1, 0.05, 100.0], [0.1, 0.05, 100.0]])
    right = left * [1.0, -1.0, 1.0]
    return Measurement(t=1.0, com=np.array([0.02, 0.0, 0.6]), lin_mom=np.array([20.0, 0.0, 0.0]),
                       ang_mom=np.zeros(3), heading=heading, cop=np.array([0.01, 0.0, 0.0]),
                       left_contacts=left, right_contacts=right, left_foot=np.array([0.0, 0.1, 0.0]),
                       right_foot=np.array([0.0, -0.1, 0.0]), non_foot_contact=False,
                       torso_rotation=np.eye(3))


def test_the_view_holds_the_support_polygon_cop_com_and_capture_point():
    state = MonitorState(STATUS_OK, '', True, True, fall_direction=(0.0, 1.0))
    view = monitor_view(measurement(heading=math.pi / 2), state, MASS_KG)
    assert sorted(view.support_polygon) == sorted([(0.1, 0.15), (-0.1, 0.15), (-0.1, -0.15),
                                                   (0.1, -0.15)])
    assert view.cop == (0.01, 0.0) and view.com_ground == (0.02, 0.0)
    omega = math.sqrt(9.81 / 0.6)                       # xi = c + v / omega, v = 20 / 40 m/s
    assert view.capture_point == pytest.approx((0.02 + 0.5 / omega, 0.0))
    # Heading pi/2: the heading frame's +y is the world's -x.
    assert view.fall_direction == pytest.approx((-1.0, 0.0))


def test_markers_draw_the_view_and_delete_what_is_not_there():
    state = MonitorState(STATUS_DEGRADED, 'no /imu/data within 5 ms of /joint_states')
    view = monitor_view(measurement(), state, MASS_KG)
    markers = {m.id: m for m in view_markers(view, ros_qos.stamp(1_000_000_000), 'odom').markers}
    assert markers[POLYGON].type == Marker.LINE_STRIP and len(markers[POLYGON].points) == 5
    assert (markers[COP].pose.position.x, markers[COM].pose.position.x) == (0.01, 0.02)
    assert markers[CAPTURE_POINT].pose.position.x == pytest.approx(view.capture_point[0])
    assert markers[DIRECTION].action == Marker.DELETE             # no direction predicted
    assert markers[STATUS].text == 'degraded: no /imu/data within 5 ms of /joint_states'
    assert {m.header.frame_id for m in markers.values()} == {'odom'}


def test_the_marker_node_draws_the_latest_sample_at_its_rate():
    rate_hz = 10.0
    with ros_context(test_domain_id(172)) as context:
        node = MarkerNode(context=context, parameter_overrides=[Parameter('rate_hz', value=rate_hz)])
        io = Node('markers_io', context=context)
        got: list[MarkerArray] = []
        create_subscription(io, MarkerArray, MARKERS, got.append)
        m_pub = create_publisher(io, MeasurementMsg, MEASUREMENT)
        s_pub = create_publisher(io, FallState, STATE)
        executor = SingleThreadedExecutor(context=context)
        for n in (node, io):
            executor.add_node(n)
        last_stamp = None
        try:
            assert spin_until(executor, lambda: m_pub.get_subscription_count() and
                              s_pub.get_subscription_count(), 10.0)
            started_s = time.monotonic()
            for k in range(50):
                stamp = 1_000_000_000 + k * 1_000_000
                last_stamp = ros_qos.stamp(stamp)
                m_pub.publish(messages.measurement_msg(ros_qos.TYPES, stamp, 'odom', measurement()))
                s_pub.publish(messages.fall_state_msg(ros_qos.TYPES, stamp, 'base_footprint',
                                                      MonitorState(STATUS_OK, '', True, True,
                                                                   fall_direction=(1.0, 0.0))))
                spin_until(executor, lambda: False, 0.002)
            # The newest sample is drawn at the next tick after it arrived.
            assert spin_until(executor, lambda: got and got[-1].markers[0].header.stamp == last_stamp,
                              5.0)
            elapsed_s = time.monotonic() - started_s
        finally:
            executor.shutdown()
            node.destroy_node()
            io.destroy_node()
    # The timer's ticks bound the arrays, however long a loaded machine took to send the 50
    # samples (a tick draws only a sample it has not drawn; rcl skips missed periods): the ticks
    # due in the window, plus one due before it and run late. ~0.1 s of sending -> one to three.
    assert 1 <= len(got) <= math.floor(elapsed_s * rate_hz) + 2
    markers = {m.id: m for m in got[-1].markers}
    assert markers[DIRECTION].action == Marker.ADD and markers[STATUS].text == 'falling (latched)'
