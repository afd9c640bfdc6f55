"""What the monitor sees at one sample, in the world frame: for RViz or Foxglove markers and plots.

:func:`monitor_view` turns a :class:`~fall_predictor.monitor.records.Measurement` and the monitor's
state into the support polygon (the convex hull of the soles' contact points), the CoP, the CoM's
ground projection, the capture point (``xi = c + v / omega``, ``omega = sqrt(g / c_z)``, with ``v``
the CoM velocity from the linear momentum and the robot's mass) and the predicted fall direction,
turned from the heading frame into the world frame. ``ros/markers.py`` draws it as a MarkerArray,
``scripts/render_monitor_view.py`` as a figure.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from fall_predictor.monitor.fall_monitor import MonitorState
from fall_predictor.monitor.geometry import convex_hull
from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2, Measurement

Point2 = tuple[float, float]


@dataclass(frozen=True)
class MonitorView:
    """The monitor's picture of one sample (world frame, metres)."""

    support_polygon: list[Point2]       #: convex hull of the contact points (empty: no contact)
    cop: Optional[Point2]               #: centre of pressure (None: no contact)
    com_ground: Point2                  #: the CoM's projection on the ground
    com_height_m: float
    capture_point: Point2
    fall_direction: Optional[Point2]    #: unit, world frame; None when none is predicted
    state: MonitorState


def monitor_view(m: Measurement, state: MonitorState, mass_kg: float) -> MonitorView:
    """The view of measurement ``m`` with the monitor's ``state`` (robot mass ``mass_kg``)."""
    rows = np.vstack([m.left_contacts, m.right_contacts]).reshape(-1, 3)
    polygon = convex_hull([(float(x), float(y)) for x, y, _ in rows]) if len(rows) else []
    cop = None if math.isnan(float(m.cop[0])) else (float(m.cop[0]), float(m.cop[1]))
    cx, cy, cz = (float(v) for v in m.com)
    omega = math.sqrt(STANDARD_GRAVITY_M_S2 / max(cz, 1e-3))
    vx, vy = float(m.lin_mom[0]) / mass_kg, float(m.lin_mom[1]) / mass_kg
    direction = None
    dx, dy = state.fall_direction
    if math.isfinite(dx) and math.isfinite(dy):
        c, s = math.cos(m.heading), math.sin(m.heading)
        direction = (c * dx - s * dy, s * dx + c * dy)
    return MonitorView(polygon, cop, (cx, cy), cz, (cx + vx / omega, cy + vy / omega), direction,
                       state)
