"""A sole on the ground, as the state estimator sees it (method §10): which of its corners
touch, and the sole's contact points with its normal force split over them.

The part of a loaded sole on the ground is its corners within a tolerance of the lowest one: all
four on a flat sole, an edge or one corner on a tilted one. Its normal force is split over those
corners so that their force-weighted mean is the sole's CoP (bilinear on a flat sole, linear
along an edge), which is what the feature code's contact points carry.

Per sample this runs once per loaded sole, so it works on plain floats (a rotation as nested
lists): numpy's per-call cost on 3-vectors exceeds the arithmetic many times over.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from fall_predictor.monitor.records import SoleGeometry

#: A sole's orientation as rows of floats: a rotation matrix or a homogeneous transform
#: (``ndarray.tolist()``; only the first three columns are read).
Rows = list


def split_force_to_corners(corners: np.ndarray, cop: np.ndarray, fz: float) -> np.ndarray:
    """Normal force ``fz`` split over contact ``corners`` (k, 2) of one sole, in its frame,
    so that the force-weighted mean is ``cop`` (clipped to the corners' hull); (k,) forces."""
    corner_xy = [tuple(c) for c in np.asarray(corners, dtype=float)[:, :2].tolist()]
    cop_x, cop_y = np.asarray(cop, dtype=float).tolist()
    return np.array(_split(corner_xy, _bounds(corner_xy), cop_x, cop_y, fz))


def _bounds(corner_xy: list) -> tuple[float, float, float, float]:
    """The corners' bounding box: x low, y low, x high, y high."""
    xs, ys = [x for x, _ in corner_xy], [y for _, y in corner_xy]
    return min(xs), min(ys), max(xs), max(ys)


def _split(corner_xy: Sequence, bounds: tuple, cop_x: float, cop_y: float,
           fz: float) -> list[float]:
    """:func:`split_force_to_corners` on floats: one corner takes it all; along an edge the
    force splits linearly; four corners (a rectangle, ``bounds``) bilinearly; other counts
    evenly."""
    k = len(corner_xy)
    if k == 1:
        return [fz]
    if k == 2:
        (ax, ay), (bx, by) = corner_xy
        dx, dy = bx - ax, by - ay
        s = ((cop_x - ax) * dx + (cop_y - ay) * dy) / max(dx * dx + dy * dy, 1e-12)
        s = min(1.0, max(0.0, s))
        return [fz * (1.0 - s), fz * s]
    if k == 4:
        lo_x, lo_y, hi_x, hi_y = bounds
        u = min(1.0, max(0.0, (cop_x - lo_x) / max(hi_x - lo_x, 1e-12)))
        w = min(1.0, max(0.0, (cop_y - lo_y) / max(hi_y - lo_y, 1e-12)))
        mid_x, mid_y = (lo_x + hi_x) / 2, (lo_y + hi_y) / 2
        return [fz * (u if x > mid_x else 1.0 - u) * (w if y > mid_y else 1.0 - w)
                for x, y in corner_xy]
    return [fz / k] * k


@dataclass(frozen=True, slots=True)
class GroundPart:
    """The corners of a sole on the ground (all four, an edge or one corner), sole frame."""

    key: tuple[bool, ...]           #: which of the sole's four corners touch
    centre: tuple[float, float]     #: their centre x, y (the sole's underside is at z = 0)
    corners: np.ndarray             #: (k, 3)
    corner_xy: tuple                #: the same corners' x, y as floats
    bounds: tuple                   #: their bounding box: x low, y low, x high, y high
    flat: bool                      #: all four: the sole lies flat


class SoleContacts:
    """Both soles' rectangles (``soles``: per side its :class:`SoleGeometry`) and the tolerance
    within which a corner counts as on the ground [m]."""

    def __init__(self, soles: dict[str, SoleGeometry], tilt_tolerance_m: float) -> None:
        self.tilt_tolerance_m = tilt_tolerance_m
        self._corners = {side: sole.corners() for side, sole in soles.items()}
        self._corner_xy = {side: [tuple(c[:2]) for c in corners.tolist()]
                           for side, corners in self._corners.items()}
        #: Per side: the sole's rectangle, x low, y low, x high, y high (sole frame).
        self._sole_bounds = {side: _bounds(xy) for side, xy in self._corner_xy.items()}
        #: Per side, per ``GroundPart.key``: the part (at most 14 of them).
        self._parts: dict[str, dict[tuple[bool, ...], GroundPart]] = {side: {} for side in soles}

    def ground_part(self, side: str, rows: Rows) -> GroundPart:
        """The part of sole ``side`` on the ground, the sole oriented as ``rows`` in the world."""
        r20, r21 = rows[2][0], rows[2][1]
        (x0, y0), (x1, y1), (x2, y2), (x3, y3) = self._corner_xy[side]
        # Each corner's height relative to the sole origin (the corners lie at z = 0).
        h0, h1, h2, h3 = x0 * r20 + y0 * r21, x1 * r20 + y1 * r21, x2 * r20 + y2 * r21, x3 * r20 + y3 * r21
        lowest = min(h0, h1, h2, h3) + self.tilt_tolerance_m
        key = (h0 <= lowest, h1 <= lowest, h2 <= lowest, h3 <= lowest)
        part = self._parts[side].get(key)
        if part is None:
            corners = self._corners[side][np.array(key)]
            centre = corners.mean(axis=0)
            corner_xy = tuple(tuple(c[:2]) for c in corners.tolist())
            part = self._parts[side][key] = GroundPart(
                key, (float(centre[0]), float(centre[1])), corners, corner_xy, _bounds(corner_xy),
                all(key))
        return part

    def on_sole(self, side: str, cop_x: float, cop_y: float) -> tuple[float, float]:
        """A CoP (sole frame) kept on sole ``side``: a point off the sole moved to its nearest
        point of the sole's rectangle (the CoP of a sole's unilateral contact forces lies under
        it); a point on the sole as it is."""
        lo_x, lo_y, hi_x, hi_y = self._sole_bounds[side]
        if lo_x <= cop_x <= hi_x and lo_y <= cop_y <= hi_y:
            return cop_x, cop_y
        return min(hi_x, max(lo_x, cop_x)), min(hi_y, max(lo_y, cop_y))

    def contacts(self, side: str, part: GroundPart, rows: Rows, origin: tuple[float, float],
                 cop_x: float, cop_y: float, fz: float) -> np.ndarray:
        """(k, 3) contact points x, y [m] (world) with their normal forces [N] of a sole oriented
        as ``rows`` with its origin at ``origin`` (world x, y), its CoP at (``cop_x``, ``cop_y``)
        in the sole frame."""
        (r00, r01), (r10, r11) = rows[0][:2], rows[1][:2]
        ox, oy = origin
        forces = _split(part.corner_xy, part.bounds, cop_x, cop_y, fz)
        flat = []
        for (x, y), f in zip(part.corner_xy, forces):
            flat += (r00 * x + r01 * y + ox, r10 * x + r11 * y + oy, f)
        return np.array(flat).reshape(-1, 3)
