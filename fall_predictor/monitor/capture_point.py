"""The capture point's signed distance to the support polygon, per measurement.

Used by the capture-point baseline (:mod:`fall_predictor.learning.baselines`) and computed
with the features, from the same (true or estimated) state, by the feature cache
(:mod:`fall_predictor.data.dataset`).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from fall_predictor.monitor.geometry import (closest_point_on_boundary, convex_hull,
                                             point_segment_distance, signed_edge_distances)
from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2, Measurement


def signed_distance_to_support(px: float, py: float, hull: list[tuple[float, float]]) -> float:
    """Signed distance [m] of ``(px, py)`` to a convex hull from :func:`convex_hull`.

    Negative inside (minus the depth), positive outside, zero on the boundary; a segment or a
    point has no inside; no support at all (empty hull) is ``+inf``.
    """
    if not hull:
        return math.inf
    if len(hull) == 1:
        return math.hypot(px - hull[0][0], py - hull[0][1])
    if len(hull) == 2:
        (ax, ay), (bx, by) = hull
        return point_segment_distance(px, py, ax, ay, bx, by)
    depth = min(signed_edge_distances(px, py, hull))
    if depth >= 0.0:
        return -depth
    qx, qy = closest_point_on_boundary(px, py, hull)
    return math.hypot(px - qx, py - qy)


def capture_point_distances(measurements: Sequence[Measurement],
                            total_mass_kg: float,
                            gravity_m_s2: float = STANDARD_GRAVITY_M_S2) -> np.ndarray:
    """Per measurement: signed distance [m] of the capture point to the support polygon.

    Capture point (world, horizontal): ``xi = c_xy + (p_xy / m) / omega`` with
    ``omega = sqrt(g / c_z)`` (c: CoM [m], p: linear momentum [kg m/s], m: total mass [kg]).
    Support polygon: convex hull of all left and right foot contact points. Positive outside,
    negative inside (:func:`signed_distance_to_support`); ``+inf`` with no foot contact or a
    CoM at or below the ground.
    """
    out = np.empty(len(measurements))
    for i, m in enumerate(measurements):
        com_x, com_y, com_z = (float(v) for v in m.com)
        contacts = [(float(x), float(y)) for x, y, _ in m.left_contacts] + \
                   [(float(x), float(y)) for x, y, _ in m.right_contacts]
        if com_z <= 0.0 or not contacts:
            out[i] = math.inf
            continue
        omega = math.sqrt(gravity_m_s2 / com_z)
        xi_x = com_x + float(m.lin_mom[0]) / total_mass_kg / omega
        xi_y = com_y + float(m.lin_mom[1]) / total_mass_kg / omega
        out[i] = signed_distance_to_support(xi_x, xi_y, convex_hull(contacts))
    return out
