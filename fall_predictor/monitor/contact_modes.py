"""Foot contact modes (method §7): where the CoP sits in the support polygon.

The support is the set of feet with at least one ground contact (a row in
``Measurement.left_contacts`` / ``right_contacts``); the support polygon is the convex hull of
all their contact points (x, y). The CoP is then classified relative to that polygon:

* farther than ``edge_tolerance_m`` from every edge: ``INSIDE``;
* within the tolerance of one edge: on that edge; of two edges: on their corner.

An edge's direction label comes from its outward normal expressed in the heading frame
(x along the pelvis yaw, y to the left): within +-45 deg of +x is ``FRONT``, of -x ``BACK``,
of +y ``LEFT``, of -y ``RIGHT`` (at exactly 45 deg the x axis wins). A corner combines the
labels of its two edges; should they disagree on one axis (possible only on slivers), the
nearer edge wins.

Degenerate polygons (a foot tipped onto one edge gives two contact points; a foot on one
corner gives a single point): the CoP lies on the segment or point; the segment's outward
normal is the one pointing away from the centre of the sole(s) in contact, i.e. towards the
side the robot is rolling over, and its ends act as corners (a CoP within the tolerance of an
end also gets the end's direction along the segment). For a single point both components of
the direction from the sole centre(s) to the point are classified.

A CoP clearly outside the polygon can only come from numerical error (it is a weighted mean of
the contact points); it is moved to the closest point of the polygon's boundary. A NaN CoP
with contacts falls back to the normal-force-weighted mean of the contact points.

**Folding rule** (method §7 lists 16 modes, not every combination): any direction component not
listed for the support is dropped; if nothing is left, the mode is ``INSIDE`` of that support.
The listed components are FRONT and BACK for every support, plus LEFT for the left foot alone
and RIGHT for the right foot alone. So ``L-RIGHT -> L-INSIDE``, ``L-FRONT-RIGHT -> L-FRONT``,
``R-BACK-LEFT -> R-BACK``, ``LR-LEFT`` and ``LR-RIGHT -> LR-INSIDE``,
``LR-FRONT-LEFT -> LR-FRONT``. No contact at all is ``OUTSIDE``.

**Double-stance edges fold by their sagittal sign**: on a staggered double stance the
support polygon has diagonal edges whose outward normal is closer to +-y than to +-x; a CoP on
such an edge is tipping over it, not inside. Such an LR edge is folded to FRONT or BACK by the
sign of its outward normal's sagittal (heading-frame x) component, unless that component is
below ``sin(LR_LATERAL_EDGE_DEG)`` of the normal's length (a purely lateral edge, the outer side
of a foot when the feet are side by side), which stays LR-INSIDE as before.
"""
from __future__ import annotations

import math
from enum import IntEnum
from typing import Optional

import numpy as np

from fall_predictor.monitor.geometry import (GEOMETRY_TOL_M, Point, closest_point_on_segment, convex_hull,
                       edges_near_point)
from fall_predictor.monitor.records import CONTACT_MODE_NAMES, Measurement


class ContactMode(IntEnum):
    """The 16 contact modes; values are the indices into :data:`CONTACT_MODE_NAMES`."""

    LR_INSIDE = 0
    LR_FRONT = 1
    LR_BACK = 2
    L_INSIDE = 3
    L_FRONT = 4
    L_BACK = 5
    L_LEFT = 6
    L_FRONT_LEFT = 7
    L_BACK_LEFT = 8
    R_INSIDE = 9
    R_FRONT = 10
    R_BACK = 11
    R_RIGHT = 12
    R_FRONT_RIGHT = 13
    R_BACK_RIGHT = 14
    OUTSIDE = 15

    @property
    def label(self) -> str:
        """The method §7 spelling, e.g. ``'L-FRONT-LEFT'``."""
        return CONTACT_MODE_NAMES[self.value]


#: Supports, and the direction components of the heading frame.
SUPPORTS = ('L', 'R', 'LR')
X_SIDES = ('FRONT', 'BACK')
Y_SIDES = ('LEFT', 'RIGHT')

#: The only LEFT/RIGHT component method §7 lists per support (the outer side of a single foot).
_LISTED_Y_SIDE: dict[str, Optional[str]] = {'L': 'LEFT', 'R': 'RIGHT', 'LR': None}

#: An LR edge whose outward normal is within this angle [deg] of +-y is purely lateral and folds
#: to LR-INSIDE; a more tilted lateral edge folds to FRONT/BACK by its sagittal sign.
LR_LATERAL_EDGE_DEG = 10.0
_LR_SAGITTAL_MIN = math.sin(math.radians(LR_LATERAL_EDGE_DEG))


def mode_from_parts(support: str, x_side: Optional[str], y_side: Optional[str]) -> ContactMode:
    """Contact mode of a support (``'L'``, ``'R'``, ``'LR'``) and a CoP location given by its
    sagittal (``'FRONT'``/``'BACK'``/None) and frontal (``'LEFT'``/``'RIGHT'``/None) components,
    applying the folding rule of the module docstring."""
    if support not in SUPPORTS or x_side not in (None, *X_SIDES) or y_side not in (None, *Y_SIDES):
        raise ValueError(f'unknown contact configuration {(support, x_side, y_side)!r}')
    # Folding rule: drop a frontal component the mode list does not have for this support.
    if y_side != _LISTED_Y_SIDE[support]:
        y_side = None
    parts = [p for p in (x_side, y_side) if p is not None] or ['INSIDE']
    return ContactMode(CONTACT_MODE_NAMES.index('-'.join([support, *parts])))


# Precomputed so that the 1 kHz path does a dict look-up instead of string work.
_MODE_TABLE: dict[tuple[str, Optional[str], Optional[str]], int] = {
    (sup, xs, ys): int(mode_from_parts(sup, xs, ys))
    for sup in SUPPORTS for xs in (None, *X_SIDES) for ys in (None, *Y_SIDES)
}


def float_list(a: object, length: int, name: str) -> list[float]:
    """``a`` as a list of ``length`` Python floats; ValueError on a wrong shape."""
    if type(a) is not np.ndarray:
        a = np.asarray(a, dtype=float)
    if a.shape != (length,):
        raise ValueError(f'{name} must have shape ({length},), got {a.shape}')
    return a.astype(float, copy=False).tolist()


def _contact_rows(a: object, name: str) -> list[list[float]]:
    """Contact rows ``[x, y, normal_force]`` of one foot; ValueError on bad shape or values."""
    if type(a) is not np.ndarray:
        a = np.asarray(a, dtype=float)
    if a.size == 0:
        return []
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f'{name} must have shape (k, 3), got {a.shape}')
    rows = a.tolist()
    for x, y, f in rows:
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(f)):
            raise ValueError(f'{name} contains a non-finite value: {rows}')
    return rows


def _cop_xy(cop: object, rows: list[list[float]]) -> Point:
    """The measured CoP (x, y), or the force-weighted mean of the contacts if it is NaN."""
    x, y, _ = float_list(cop, 3, 'cop')
    if math.isfinite(x) and math.isfinite(y):
        return x, y
    total = sum(r[2] for r in rows)
    if total > 0.0:
        return sum(r[0] * r[2] for r in rows) / total, sum(r[1] * r[2] for r in rows) / total
    # No usable force (e.g. contacts reported inside the contact margin): plain mean.
    return sum(r[0] for r in rows) / len(rows), sum(r[1] for r in rows) / len(rows)


def _sides_from_normals(normals: list[Point], c: float, s: float
                        ) -> tuple[Optional[str], Optional[str]]:
    """Direction components of outward normals (world frame, nearest edge first) in the
    heading frame with cos/sin of the heading ``c``, ``s``. The first normal on an axis wins."""
    x_side = y_side = None
    for nx, ny in normals:
        hx, hy = c * nx + s * ny, -s * nx + c * ny
        if abs(hx) >= abs(hy):
            if x_side is None:
                x_side = 'FRONT' if hx > 0.0 else 'BACK'
        elif y_side is None:
            y_side = 'LEFT' if hy > 0.0 else 'RIGHT'
    return x_side, y_side


def lr_lateral_edge_fold(normals: list[Point], c: float, s: float) -> Optional[str]:
    """The sagittal fold (``'FRONT'``/``'BACK'``) of a double stance whose CoP lies only on
    lateral edges (outward normals nearer +-y than +-x): the sign of the nearest such edge's
    sagittal component, or None when that edge is purely lateral (within
    :data:`LR_LATERAL_EDGE_DEG` of +-y) or some edge is already sagittal."""
    for nx, ny in normals:
        hx, hy = c * nx + s * ny, -s * nx + c * ny
        if abs(hx) >= abs(hy):
            return None
    for nx, ny in normals:
        hx = c * nx + s * ny
        if abs(hx) > _LR_SAGITTAL_MIN * math.hypot(nx, ny):
            return 'FRONT' if hx > 0.0 else 'BACK'
    return None


def _polygon_normals(px: float, py: float, hull: list[Point], tol: float) -> list[Point]:
    """Outward normals of the hull edges within ``tol`` of the CoP, nearest first."""
    normals = []
    for _, i in edges_near_point(px, py, hull, tol):
        (ax, ay), (bx, by) = hull[i], hull[(i + 1) % len(hull)]
        normals.append((by - ay, ax - bx))      # CCW polygon: outward is the edge turned right
    return normals


def _segment_normals(px: float, py: float, hull: list[Point], centre: Point, tol: float
                     ) -> list[Point]:
    """Outward directions of a segment hull at the CoP, nearest first: the side away from the
    sole centre, then the segment's direction at an end within ``tol`` of the CoP."""
    (ax, ay), (bx, by) = hull
    qx, qy = closest_point_on_segment(px, py, ax, ay, bx, by)
    ux, uy = bx - ax, by - ay
    normals = []
    side = (ax - centre[0]) * uy - (ay - centre[1]) * ux    # centre's offset along (uy, -ux)
    if abs(side) > GEOMETRY_TOL_M * math.hypot(ux, uy):
        normals.append((uy, -ux) if side > 0.0 else (-uy, ux))
    ends = sorted([(math.hypot(qx - ax, qy - ay), (-ux, -uy)),
                   (math.hypot(qx - bx, qy - by), (ux, uy))])
    normals.extend(n for d, n in ends if d <= tol)
    return normals


def _sole_centre(m: Measurement, support: str) -> Point:
    """Mean (x, y) of the sole centres of the feet in the support."""
    feet = {'L': [m.left_foot], 'R': [m.right_foot], 'LR': [m.left_foot, m.right_foot]}[support]
    xy = [float_list(f, 3, 'foot pose')[:2] for f in feet]
    return sum(p[0] for p in xy) / len(xy), sum(p[1] for p in xy) / len(xy)


def classify_contact_mode_and_cop(m: Measurement, edge_tolerance_m: float = 0.01
                                  ) -> tuple[int, float, float]:
    """Contact mode index of ``m`` and the CoP (x, y) [m] the classification used.

    The CoP is ``m.cop[:2]``, or the contact-force-weighted mean of the contact points when
    that is NaN; it is (NaN, NaN) in mode OUTSIDE. ``edge_tolerance_m`` [m] is the distance
    within which the CoP counts as on an edge. Raises ValueError on malformed contacts, CoP,
    heading or (for degenerate polygons) sole poses.
    """
    left = _contact_rows(m.left_contacts, 'left_contacts')
    right = _contact_rows(m.right_contacts, 'right_contacts')
    if left and right:
        support, rows = 'LR', left + right
    elif left or right:
        support, rows = ('L', left) if left else ('R', right)
    else:
        return int(ContactMode.OUTSIDE), math.nan, math.nan
    cop_x, cop_y = _cop_xy(m.cop, rows)
    heading = float(m.heading)
    if not math.isfinite(heading):
        raise ValueError(f'heading must be finite, got {heading}')
    c, s = math.cos(heading), math.sin(heading)

    hull = convex_hull([(r[0], r[1]) for r in rows])
    if len(hull) >= 3:
        normals = _polygon_normals(cop_x, cop_y, hull, edge_tolerance_m)
        x_side, y_side = _sides_from_normals(normals, c, s)
        if support == 'LR' and x_side is None and y_side is not None:
            x_side = lr_lateral_edge_fold(normals, c, s)
    elif len(hull) == 2:
        x_side, y_side = _sides_from_normals(
            _segment_normals(cop_x, cop_y, hull, _sole_centre(m, support), edge_tolerance_m),
            c, s)
    else:
        # A single contact point: classify both components of the direction sole -> point.
        cx, cy = _sole_centre(m, support)
        vx, vy = hull[0][0] - cx, hull[0][1] - cy
        hx, hy = c * vx + s * vy, -s * vx + c * vy
        x_side = None if abs(hx) <= GEOMETRY_TOL_M else ('FRONT' if hx > 0.0 else 'BACK')
        y_side = None if abs(hy) <= GEOMETRY_TOL_M else ('LEFT' if hy > 0.0 else 'RIGHT')
    return _MODE_TABLE[(support, x_side, y_side)], cop_x, cop_y


def classify_contact_mode(m: Measurement, edge_tolerance_m: float = 0.01) -> int:
    """Contact mode index (into :data:`CONTACT_MODE_NAMES`) of one measurement; see the module
    docstring for the rules and :func:`classify_contact_mode_and_cop` for the errors."""
    return classify_contact_mode_and_cop(m, edge_tolerance_m)[0]
