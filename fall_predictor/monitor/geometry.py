"""Small geometry helpers for the 1 kHz paths (2D support polygons, 3-vector cross products).

Inputs are tiny (a support polygon has at most a few dozen contact points, usually 2 to 8),
so everything works on plain Python floats and tuples: for such sizes the per-call overhead of
numpy (array creation, ufunc dispatch) costs more than the arithmetic itself.

Conventions: points are ``(x, y)`` tuples in metres; polygons are lists of vertices in
counter-clockwise (CCW) order without repeating the first vertex; edge ``i`` runs from
``poly[i]`` to ``poly[(i + 1) % n]``. For a CCW polygon the interior lies to the left of
every edge and the outward normal of an edge with direction ``(ex, ey)`` is ``(ey, -ex)``.
"""
from __future__ import annotations

import math
from typing import Iterable

import numpy as np

Point = tuple[float, float]

#: Default geometric tolerance [m]: points closer than this are one point, and a vertex
#: closer than this to the line through its neighbours is dropped as collinear. Far below
#: any contact geometry (centimetres), far above float round-off on metre-scale values.
GEOMETRY_TOL_M = 1e-9


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` of two 3-vectors (``np.cross`` costs ~25 us a call through its axis handling;
    this ~1 us)."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _half_chain(seq: list[Point], tol2: float) -> list[Point]:
    """One monotone chain over x-sorted points: keeps only strict left (CCW) turns, dropping a
    middle point closer than sqrt(tol2) to the line through its neighbours."""
    chain: list[Point] = []
    for b in seq:
        bx, by = b
        while len(chain) >= 2:
            ox, oy = chain[-2]
            ax, ay = chain[-1]
            dx, dy = bx - ox, by - oy
            # cross = (distance of a from line o-b) * |b - o|; compare squares to skip a sqrt.
            cross = (ax - ox) * dy - (ay - oy) * dx
            if cross > 0.0 and cross * cross > tol2 * (dx * dx + dy * dy):
                break
            chain.pop()
        chain.append(b)
    return chain


def convex_hull(points: Iterable[Point], tol: float = GEOMETRY_TOL_M) -> list[Point]:
    """Convex hull of 2D points by Andrew's monotone chain, O(n log n).

    Returns the hull vertices in CCW order starting from the lowest-x (then lowest-y) point,
    with duplicates and collinear points removed: 0 points for empty input, 1 point when all
    points coincide (within ``tol`` [m]), 2 points (the extreme ends) when they are collinear,
    otherwise a proper polygon with at least 3 vertices.
    """
    pts = sorted(points)
    if len(pts) <= 1:
        return pts
    tol2 = tol * tol
    lower = _half_chain(pts, tol2)
    pts.reverse()
    hull = lower[:-1] + _half_chain(pts, tol2)[:-1]
    if len(hull) == 2:
        (ax, ay), (bx, by) = hull
        if (bx - ax) ** 2 + (by - ay) ** 2 <= tol2:
            return [hull[0]]
    return hull


def signed_edge_distances(px: float, py: float, poly: list[Point]) -> list[float]:
    """Signed distance [m] of point ``(px, py)`` to the line through each edge of a CCW polygon.

    Positive inside (to the left of the edge), negative outside; entry ``i`` is for edge ``i``.
    ``poly`` needs at least 3 vertices.
    """
    out = []
    for (ax, ay), (bx, by) in zip(poly, poly[1:] + poly[:1]):
        ex, ey = bx - ax, by - ay
        out.append((ex * (py - ay) - ey * (px - ax)) / math.hypot(ex, ey))
    return out


def closest_point_on_segment(px: float, py: float,
                             ax: float, ay: float, bx: float, by: float) -> Point:
    """Point of segment a-b closest to ``(px, py)``; a degenerate segment returns a."""
    ex, ey = bx - ax, by - ay
    len2 = ex * ex + ey * ey
    if len2 == 0.0:
        return ax, ay
    u = ((px - ax) * ex + (py - ay) * ey) / len2
    u = 0.0 if u < 0.0 else (1.0 if u > 1.0 else u)
    return ax + u * ex, ay + u * ey


def point_segment_distance(px: float, py: float,
                           ax: float, ay: float, bx: float, by: float) -> float:
    """Euclidean distance [m] from ``(px, py)`` to segment a-b."""
    qx, qy = closest_point_on_segment(px, py, ax, ay, bx, by)
    return math.hypot(px - qx, py - qy)


def edge_segment_distances(px: float, py: float, poly: list[Point]) -> list[float]:
    """Euclidean distance [m] from ``(px, py)`` to each edge segment of a polygon (>= 3 points)."""
    return [point_segment_distance(px, py, ax, ay, bx, by)
            for (ax, ay), (bx, by) in zip(poly, poly[1:] + poly[:1])]


def closest_point_on_boundary(px: float, py: float, poly: list[Point]) -> Point:
    """Point of a polygon's boundary (>= 3 vertices) closest to ``(px, py)``."""
    best = poly[0]
    best_d2 = math.inf
    for (ax, ay), (bx, by) in zip(poly, poly[1:] + poly[:1]):
        qx, qy = closest_point_on_segment(px, py, ax, ay, bx, by)
        d2 = (px - qx) ** 2 + (py - qy) ** 2
        if d2 < best_d2:
            best, best_d2 = (qx, qy), d2
    return best


def edges_near_point(px: float, py: float, poly: list[Point], tol: float
                     ) -> list[tuple[float, int]]:
    """Edges of a CCW polygon (>= 3 vertices) within ``tol`` [m] of ``(px, py)``, as
    ``(distance, edge index)`` pairs, nearest first.

    A point outside the polygon is first moved to the closest point of its boundary, so the
    edge it is nearest to is always reported (with the distance from the moved point).
    """
    near = []
    tol2 = tol * tol
    for i, ((ax, ay), (bx, by)) in enumerate(zip(poly, poly[1:] + poly[:1])):
        ex, ey = bx - ax, by - ay
        cross = ex * (py - ay) - ey * (px - ax)     # inward distance * |e|
        if cross < 0.0:
            qx, qy = closest_point_on_boundary(px, py, poly)
            return sorted((d, j) for j, d in enumerate(edge_segment_distances(qx, qy, poly))
                          if d <= tol)
        # The distance to the edge's line bounds the distance to the edge from below, so the
        # exact segment distance is only needed for the few edges that pass this cheap test.
        if cross * cross <= tol2 * (ex * ex + ey * ey):
            d = point_segment_distance(px, py, ax, ay, bx, by)
            if d <= tol:
                near.append((d, i))
    near.sort()
    return near


def point_in_convex_polygon(px: float, py: float, poly: list[Point], tol: float = 0.0) -> bool:
    """True if ``(px, py)`` lies in the convex hull ``poly`` or within ``tol`` [m] of it.

    Works for any output of :func:`convex_hull`: empty (always False), a point, a segment,
    or a CCW polygon.
    """
    n = len(poly)
    if n == 0:
        return False
    if n == 1:
        return math.hypot(px - poly[0][0], py - poly[0][1]) <= tol
    if n == 2:
        (ax, ay), (bx, by) = poly
        return point_segment_distance(px, py, ax, ay, bx, by) <= tol
    if min(signed_edge_distances(px, py, poly)) >= 0.0:
        return True
    # Outside every edge's line by less than tol is not enough near a vertex: use the true
    # distance to the boundary.
    qx, qy = closest_point_on_boundary(px, py, poly)
    return math.hypot(px - qx, py - qy) <= tol


def to_yaw_frame(x: float, y: float, yaw: float) -> Point:
    """Express a world-frame horizontal vector in a frame rotated by ``yaw`` [rad] about z.

    The frame's x axis points along ``(cos yaw, sin yaw)``; a vector along the heading maps to
    ``(|v|, 0)`` and one to its left to ``(0, |v|)``. Free vectors only: subtract the frame's
    origin first for positions.
    """
    c, s = math.cos(yaw), math.sin(yaw)
    return c * x + s * y, -s * x + c * y


def fused_roll_pitch_of_rotation(rotation) -> tuple[float, float]:
    """Fused roll and pitch [rad] of one orientation given as its rotation matrix (3, 3), body to
    world: :func:`fused_roll_pitch`'s angles, ``roll = asin(R[2, 1])``, ``pitch = asin(-R[2, 0])``."""
    r20, r21 = float(rotation[2][0]), float(rotation[2][1])
    return math.asin(min(1.0, max(-1.0, r21))), math.asin(min(1.0, max(-1.0, -r20)))


def fused_roll_pitch(quat_xyzw: np.ndarray) -> np.ndarray:
    """Fused roll and pitch [rad] (n, 2) of orientations (n, 4): the world z axis seen from the
    body, ``roll = asin(R[2, 1])``, ``pitch = asin(-R[2, 0])`` (R body to world)."""
    q = np.asarray(quat_xyzw, dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q.T
    r20 = 2.0 * (x * z - y * w)
    r21 = 2.0 * (y * z + x * w)
    return np.column_stack([np.arcsin(np.clip(r21, -1.0, 1.0)), np.arcsin(np.clip(-r20, -1.0, 1.0))])
