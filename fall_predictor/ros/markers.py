"""The monitor's view (:mod:`fall_predictor.monitor.view`) as a ``visualization_msgs/MarkerArray``
for RViz or Foxglove: the support polygon, the CoP, the CoM's ground projection, the capture point,
the predicted fall direction and the status, in the estimator's world frame."""
from __future__ import annotations

from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import Point, Vector3
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from fall_predictor.monitor.fall_monitor import STATUS_OK
from fall_predictor.monitor.view import MonitorView

NAMESPACE = 'fall_predictor'
#: Marker ids, one per element.
POLYGON, COP, COM, CAPTURE_POINT, DIRECTION, STATUS = range(6)
_GREEN, _RED, _BLUE, _ORANGE, _WHITE = ((0.1, 0.8, 0.2), (0.9, 0.1, 0.1), (0.2, 0.4, 1.0),
                                        (1.0, 0.6, 0.0), (1.0, 1.0, 1.0))
#: Length of the fall direction arrow [m].
ARROW_M = 0.3


def _marker(kind: int, marker_id: int, stamp: Time, frame: str, rgb, scale: tuple) -> Marker:
    m = Marker(type=kind, id=marker_id, ns=NAMESPACE, action=Marker.ADD,
               scale=Vector3(x=scale[0], y=scale[1], z=scale[2]),
               color=ColorRGBA(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0),
               lifetime=Duration(sec=1))
    m.header.stamp, m.header.frame_id = stamp, frame
    m.pose.orientation.w = 1.0
    return m


def _deleted(marker_id: int, stamp: Time, frame: str) -> Marker:
    m = Marker(id=marker_id, ns=NAMESPACE, action=Marker.DELETE)
    m.header.stamp, m.header.frame_id = stamp, frame
    return m


def _sphere(marker_id: int, xy, stamp: Time, frame: str, rgb, diameter_m: float = 0.04) -> Marker:
    m = _marker(Marker.SPHERE, marker_id, stamp, frame, rgb, (diameter_m,) * 3)
    m.pose.position = Point(x=float(xy[0]), y=float(xy[1]), z=0.0)
    return m


def view_markers(view: MonitorView, stamp: Time, frame: str) -> MarkerArray:
    """The markers of one view, stamped ``stamp`` (the sample's) in ``frame`` (the world)."""
    markers = []
    if view.support_polygon:
        polygon = _marker(Marker.LINE_STRIP, POLYGON, stamp, frame, _GREEN, (0.01, 0.0, 0.0))
        closed = [*view.support_polygon, view.support_polygon[0]]
        polygon.points = [Point(x=float(x), y=float(y), z=0.0) for x, y in closed]
        markers.append(polygon)
    else:
        markers.append(_deleted(POLYGON, stamp, frame))
    markers.append(_sphere(COP, view.cop, stamp, frame, _RED) if view.cop is not None
                   else _deleted(COP, stamp, frame))
    markers.append(_sphere(COM, view.com_ground, stamp, frame, _BLUE))
    markers.append(_sphere(CAPTURE_POINT, view.capture_point, stamp, frame, _ORANGE))
    if view.fall_direction is not None:
        arrow = _marker(Marker.ARROW, DIRECTION, stamp, frame, _RED, (0.02, 0.04, 0.05))
        x, y = view.com_ground
        dx, dy = view.fall_direction
        arrow.points = [Point(x=x, y=y, z=0.0), Point(x=x + ARROW_M * dx, y=y + ARROW_M * dy, z=0.0)]
        markers.append(arrow)
    else:
        markers.append(_deleted(DIRECTION, stamp, frame))
    state = view.state
    text = _marker(Marker.TEXT_VIEW_FACING, STATUS, stamp, frame, _WHITE if state.status == STATUS_OK
                   else _ORANGE, (0.0, 0.0, 0.06))
    text.pose.position = Point(x=view.com_ground[0], y=view.com_ground[1], z=view.com_height_m + 0.3)
    text.text = state.word + (f': {state.reason}' if state.reason else '') + (
        ' (latched)' if state.latched and state.status == STATUS_OK else '')
    markers.append(text)
    return MarkerArray(markers=markers)

