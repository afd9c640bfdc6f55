import math

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from fall_predictor.monitor.geometry import (closest_point_on_boundary, closest_point_on_segment,
                                     convex_hull, edge_segment_distances, edges_near_point,
                                     point_in_convex_polygon, point_segment_distance,
                                     signed_edge_distances, to_yaw_frame)

SQUARE = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]


def _is_ccw(poly):
    area2 = sum(ax * by - bx * ay for (ax, ay), (bx, by) in zip(poly, poly[1:] + poly[:1]))
    return area2 > 0.0


class TestConvexHull:
    def test_empty_and_single(self):
        assert convex_hull([]) == []
        assert convex_hull([(1.0, 2.0)]) == [(1.0, 2.0)]

    def test_duplicates_collapse(self):
        assert convex_hull([(1.0, 2.0)] * 4) == [(1.0, 2.0)]
        assert convex_hull([(1.0, 2.0), (1.0 + 1e-12, 2.0 - 1e-12)]) == [(1.0, 2.0)]

    def test_two_points(self):
        assert convex_hull([(1.0, 0.0), (0.0, 0.0)]) == [(0.0, 0.0), (1.0, 0.0)]

    def test_collinear_points_give_segment_ends(self):
        pts = [(0.3, 0.6), (0.0, 0.0), (0.1, 0.2), (0.2, 0.4), (0.1, 0.2)]
        assert convex_hull(pts) == [(0.0, 0.0), (0.3, 0.6)]

    def test_nearly_collinear_within_tolerance(self):
        assert len(convex_hull([(0.0, 0.0), (0.5, 1e-12), (1.0, 0.0)])) == 2
        assert len(convex_hull([(0.0, 0.0), (0.5, 1e-6), (1.0, 0.0)])) == 3

    def test_square_with_interior_edge_and_duplicate_points(self):
        pts = SQUARE + [(0.5, 0.5), (0.5, 0.0), (1.0, 0.5), (0.0, 0.0), (0.2, 0.9)]
        hull = convex_hull(pts)
        assert hull == [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]

    @pytest.mark.parametrize('seed', range(20))
    def test_matches_scipy_on_random_points(self, seed):
        rng = np.random.default_rng(seed)
        pts = [tuple(p) for p in rng.uniform(-0.3, 0.3, size=(rng.integers(3, 17), 2))]
        hull = convex_hull(pts)
        expected = ConvexHull(np.array(pts)).vertices
        assert sorted(hull) == sorted(pts[i] for i in expected)
        assert _is_ccw(hull)


def test_signed_edge_distances_positive_inside():
    assert signed_edge_distances(0.25, 0.5, SQUARE) == pytest.approx([0.5, 0.75, 0.5, 0.25])
    assert signed_edge_distances(0.5, -0.2, SQUARE)[0] == pytest.approx(-0.2)


def test_segment_helpers():
    assert closest_point_on_segment(0.5, 1.0, 0.0, 0.0, 1.0, 0.0) == (0.5, 0.0)
    assert closest_point_on_segment(-2.0, 1.0, 0.0, 0.0, 1.0, 0.0) == (0.0, 0.0)
    assert closest_point_on_segment(3.0, 1.0, 0.0, 0.0, 1.0, 0.0) == (1.0, 0.0)
    assert closest_point_on_segment(3.0, 1.0, 2.0, 2.0, 2.0, 2.0) == (2.0, 2.0)
    assert point_segment_distance(2.0, 1.0, 0.0, 0.0, 1.0, 0.0) == pytest.approx(math.sqrt(2))


def test_edge_segment_distances_and_boundary_projection():
    assert edge_segment_distances(2.0, 2.0, SQUARE) == pytest.approx(
        [math.hypot(1.0, 2.0), math.sqrt(2), math.sqrt(2), math.hypot(1.0, 2.0)])
    assert closest_point_on_boundary(2.0, 2.0, SQUARE) == pytest.approx((1.0, 1.0))
    assert closest_point_on_boundary(0.5, 0.1, SQUARE) == pytest.approx((0.5, 0.0))


class TestEdgesNearPoint:
    def test_inside(self):
        assert edges_near_point(0.5, 0.5, SQUARE, 0.1) == []
        assert edges_near_point(0.5, 0.95, SQUARE, 0.1) == [(pytest.approx(0.05), 2)]

    def test_corner_nearest_first(self):
        near = edges_near_point(0.97, 0.02, SQUARE, 0.05)
        assert [i for _, i in near] == [0, 1]
        assert [d for d, _ in near] == pytest.approx([0.02, 0.03])

    def test_near_the_line_but_not_the_edge(self):
        # A pentagon whose short top-right edge (index 2) is nearly in line with edge 1.
        poly = [(0.0, 0.0), (1.0, 0.0), (1.0, 0.9), (0.99, 1.0), (0.0, 1.0)]
        assert [i for _, i in edges_near_point(0.995, 0.3, poly, 0.01)] == [1]

    def test_outside_is_moved_to_the_boundary(self):
        assert edges_near_point(1.5, 0.5, SQUARE, 0.01) == [(0.0, 1)]
        assert sorted(i for _, i in edges_near_point(1.5, 1.5, SQUARE, 0.01)) == [1, 2]


class TestPointInConvexPolygon:
    def test_polygon(self):
        assert point_in_convex_polygon(0.5, 0.5, SQUARE)
        assert point_in_convex_polygon(1.0, 0.5, SQUARE)          # on an edge
        assert not point_in_convex_polygon(1.01, 0.5, SQUARE)
        assert point_in_convex_polygon(1.01, 0.5, SQUARE, tol=0.02)

    def test_tolerance_near_a_vertex_is_euclidean(self):
        # Within 0.02 of both edge lines, but 0.028 from the corner.
        assert not point_in_convex_polygon(1.02, 1.02, SQUARE, tol=0.025)
        assert point_in_convex_polygon(1.02, 1.02, SQUARE, tol=0.03)

    def test_degenerate(self):
        assert not point_in_convex_polygon(0.0, 0.0, [])
        assert point_in_convex_polygon(1.0, 1.0, [(1.0, 1.0)])
        assert point_in_convex_polygon(1.0, 1.005, [(1.0, 1.0)], tol=0.01)
        assert not point_in_convex_polygon(1.0, 1.02, [(1.0, 1.0)], tol=0.01)
        seg = [(0.0, 0.0), (1.0, 0.0)]
        assert point_in_convex_polygon(0.5, 0.0, seg)
        assert point_in_convex_polygon(0.5, 0.005, seg, tol=0.01)
        assert not point_in_convex_polygon(1.02, 0.0, seg, tol=0.01)


def test_to_yaw_frame():
    assert to_yaw_frame(1.0, 0.0, 0.0) == (1.0, 0.0)
    assert to_yaw_frame(0.0, 2.0, math.pi / 2) == pytest.approx((2.0, 0.0))   # ahead
    assert to_yaw_frame(1.0, 0.0, math.pi / 2) == pytest.approx((0.0, -1.0))  # to the right
    yaw = 0.7
    assert to_yaw_frame(math.cos(yaw), math.sin(yaw), yaw) == pytest.approx((1.0, 0.0))
