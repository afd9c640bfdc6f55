import math

import numpy as np
import pytest

from fall_predictor.monitor.contact_modes import (ContactMode, classify_contact_mode,
                                          classify_contact_mode_and_cop, mode_from_parts)
from fall_predictor.monitor.records import CONTACT_MODE_NAMES, Measurement

M = ContactMode
LENGTH, WIDTH = 0.225, 0.157            # method §1 foot sole
HL, HW = LENGTH / 2, WIDTH / 2
LEFT_FOOT = (0.0, 0.1, 0.0)             # sole centre x, y, yaw
RIGHT_FOOT = (0.0, -0.1, 0.0)
NO_CONTACT = np.zeros((0, 3))


def corners(foot, which='all'):
    """World (x, y) of a sole's corners; ``which`` picks e.g. the front edge ('f') or the
    front-left corner ('fl') in the foot's own frame."""
    cx, cy, yaw = foot
    local = {'fl': (HL, HW), 'fr': (HL, -HW), 'bl': (-HL, HW), 'br': (-HL, -HW)}
    picks = {'all': ('fl', 'fr', 'br', 'bl'), 'f': ('fl', 'fr'), 'b': ('bl', 'br'),
             'l': ('fl', 'bl'), 'r': ('fr', 'br')}.get(which, (which,))
    c, s = math.cos(yaw), math.sin(yaw)
    return [(cx + c * lx - s * ly, cy + s * lx + c * ly) for lx, ly in (local[p] for p in picks)]


def contacts(points, force=100.0):
    return np.array([[x, y, force] for x, y in points]) if points else NO_CONTACT


def local_point(foot, lx, ly):
    """A point given in a sole's frame, in world coordinates."""
    cx, cy, yaw = foot
    c, s = math.cos(yaw), math.sin(yaw)
    return cx + c * lx - s * ly, cy + s * lx + c * ly


def meas(left=(), right=(), cop=(0.0, 0.0), heading=0.0, left_foot=LEFT_FOOT,
         right_foot=RIGHT_FOOT, left_force=100.0, right_force=100.0):
    return Measurement(
        t=0.0, com=np.array([0.0, 0.0, 0.59]), lin_mom=np.zeros(3), ang_mom=np.zeros(3),
        heading=heading, cop=np.array([cop[0], cop[1], 0.0]),
        left_contacts=contacts(list(left), left_force),
        right_contacts=contacts(list(right), right_force),
        left_foot=np.array(left_foot, dtype=float), right_foot=np.array(right_foot, dtype=float),
        non_foot_contact=False)


def rotated(m, theta, pivot=(0.37, -0.21)):
    """The same configuration turned by ``theta`` about a vertical axis through ``pivot``."""
    c, s = math.cos(theta), math.sin(theta)

    def pt(x, y):
        dx, dy = x - pivot[0], y - pivot[1]
        return pivot[0] + c * dx - s * dy, pivot[1] + s * dx + c * dy

    def rows(a):
        return np.array([[*pt(x, y), f] for x, y, f in a]) if len(a) else NO_CONTACT

    def foot(f):
        return np.array([*pt(f[0], f[1]), f[2] + theta])

    return Measurement(
        t=m.t, com=np.array([*pt(m.com[0], m.com[1]), m.com[2]]),
        lin_mom=np.array([c * m.lin_mom[0] - s * m.lin_mom[1], s * m.lin_mom[0] + c * m.lin_mom[1],
                          m.lin_mom[2]]),
        ang_mom=np.array([c * m.ang_mom[0] - s * m.ang_mom[1], s * m.ang_mom[0] + c * m.ang_mom[1],
                          m.ang_mom[2]]),
        heading=m.heading + theta, cop=np.array([*pt(m.cop[0], m.cop[1]), m.cop[2]]),
        left_contacts=rows(m.left_contacts), right_contacts=rows(m.right_contacts),
        left_foot=foot(m.left_foot), right_foot=foot(m.right_foot),
        non_foot_contact=m.non_foot_contact)


L_FLAT, R_FLAT = corners(LEFT_FOOT), corners(RIGHT_FOOT)
YAWED_LEFT = (0.05, 0.12, 0.5)          # a left foot turned 28.6 deg from the heading
D = 0.004                               # well within the default 1 cm edge tolerance

# (name, measurement, expected mode): each of the 16 modes at least once.
CASES = [
    # Both feet flat, side by side: one rectangle 0.225 x 0.357.
    ('LR inside', meas(L_FLAT, R_FLAT, cop=(0.0, 0.0)), M.LR_INSIDE),
    ('LR front edge', meas(L_FLAT, R_FLAT, cop=(HL - D, 0.02)), M.LR_FRONT),
    ('LR back edge', meas(L_FLAT, R_FLAT, cop=(-HL, -0.05)), M.LR_BACK),
    ('LR left edge folds', meas(L_FLAT, R_FLAT, cop=(0.0, 0.1 + HW - D)), M.LR_INSIDE),
    ('LR right edge folds', meas(L_FLAT, R_FLAT, cop=(0.0, -0.1 - HW)), M.LR_INSIDE),
    ('LR front-left corner folds', meas(L_FLAT, R_FLAT, cop=(HL, 0.1 + HW)), M.LR_FRONT),
    ('LR back-right corner folds', meas(L_FLAT, R_FLAT, cop=(-HL + D, -0.1 - HW + D)),
     M.LR_BACK),
    # Staggered stance, left foot ahead: the hull has diagonal edges.
    ('LR staggered front', meas(corners((0.15, 0.1, 0.0)), R_FLAT, cop=(0.15 + HL, 0.1)),
     M.LR_FRONT),
    # left foot 0.3 m ahead; the diagonal edges' normals are nearer +-y than +-x but
    # fold by their sagittal sign (the back-left diagonal faces -x, the front-right one +x).
    ('LR staggered back-left diagonal', meas(corners((0.3, 0.1, 0.0)), R_FLAT,
                                             cop=(0.15 - HL, WIDTH / 2)), M.LR_BACK),
    ('LR staggered front-right diagonal', meas(corners((0.3, 0.1, 0.0)), R_FLAT,
                                               cop=(0.15 + HL, -WIDTH / 2)), M.LR_FRONT),
    # ... while the outer side of the leading foot stays a lateral edge: LR-INSIDE.
    ('LR staggered outer side', meas(corners((0.3, 0.1, 0.0)), R_FLAT,
                                     cop=(0.3, 0.1 + HW - D)), M.LR_INSIDE),
    # Both feet on their toes: four collinear contacts, a segment hull.
    ('LR both on toes', meas(corners(LEFT_FOOT, 'f'), corners(RIGHT_FOOT, 'f'), cop=(HL, 0.0)),
     M.LR_FRONT),
    ('LR both on heels', meas(corners(LEFT_FOOT, 'b'), corners(RIGHT_FOOT, 'b'), cop=(-HL, 0.05)),
     M.LR_BACK),
    # Left foot flat.
    ('L inside', meas(L_FLAT, cop=(0.0, 0.1)), M.L_INSIDE),
    ('L front', meas(L_FLAT, cop=(HL - D, 0.1)), M.L_FRONT),
    ('L back', meas(L_FLAT, cop=(-HL + D, 0.12)), M.L_BACK),
    ('L left', meas(L_FLAT, cop=(0.03, 0.1 + HW - D)), M.L_LEFT),
    ('L front-left', meas(L_FLAT, cop=(HL - D, 0.1 + HW - D)), M.L_FRONT_LEFT),
    ('L back-left', meas(L_FLAT, cop=(-HL + D, 0.1 + HW)), M.L_BACK_LEFT),
    ('L right edge folds', meas(L_FLAT, cop=(0.0, 0.1 - HW)), M.L_INSIDE),
    ('L front-right folds', meas(L_FLAT, cop=(HL, 0.1 - HW)), M.L_FRONT),
    # Right foot flat.
    ('R inside', meas(right=R_FLAT, cop=(0.01, -0.1)), M.R_INSIDE),
    ('R front', meas(right=R_FLAT, cop=(HL, -0.1)), M.R_FRONT),
    ('R back', meas(right=R_FLAT, cop=(-HL + D, -0.08)), M.R_BACK),
    ('R right', meas(right=R_FLAT, cop=(0.0, -0.1 - HW + D)), M.R_RIGHT),
    ('R front-right', meas(right=R_FLAT, cop=(HL, -0.1 - HW)), M.R_FRONT_RIGHT),
    ('R back-right', meas(right=R_FLAT, cop=(-HL + D, -0.1 - HW + D)), M.R_BACK_RIGHT),
    ('R left edge folds', meas(right=R_FLAT, cop=(0.0, -0.1 + HW)), M.R_INSIDE),
    ('R back-left folds', meas(right=R_FLAT, cop=(-HL, -0.1 + HW - D)), M.R_BACK),
    # Tipped feet: two contacts on one sole edge; the side is away from the sole centre.
    ('L tipped outward', meas(corners(LEFT_FOOT, 'l'), cop=(0.0, 0.1 + HW)), M.L_LEFT),
    ('L tipped outward, front end', meas(corners(LEFT_FOOT, 'l'), cop=(HL - D, 0.1 + HW)),
     M.L_FRONT_LEFT),
    ('L tipped inward folds', meas(corners(LEFT_FOOT, 'r'), cop=(0.0, 0.1 - HW)), M.L_INSIDE),
    ('L on toe edge', meas(corners(LEFT_FOOT, 'f'), cop=(HL, 0.1)), M.L_FRONT),
    ('L on heel edge, outer end', meas(corners(LEFT_FOOT, 'b'), cop=(-HL, 0.1 + HW - D)),
     M.L_BACK_LEFT),
    ('R tipped outward', meas(right=corners(RIGHT_FOOT, 'r'), cop=(0.02, -0.1 - HW)), M.R_RIGHT),
    ('R on toe edge', meas(right=corners(RIGHT_FOOT, 'f'), cop=(HL, -0.1)), M.R_FRONT),
    ('R on heel edge, outer end', meas(right=corners(RIGHT_FOOT, 'b'), cop=(-HL, -0.1 - HW)),
     M.R_BACK_RIGHT),
    # A CoP off the segment (numerical error) is projected onto it.
    ('R tipped outward, CoP off', meas(right=corners(RIGHT_FOOT, 'r'), cop=(0.0, -0.25)),
     M.R_RIGHT),
    # Single contact point: a foot on one corner.
    ('L on front-left corner', meas(corners(LEFT_FOOT, 'fl'), cop=(0.0, 0.0)), M.L_FRONT_LEFT),
    ('L on back-left corner', meas(corners(LEFT_FOOT, 'bl')), M.L_BACK_LEFT),
    ('L on front-right corner folds', meas(corners(LEFT_FOOT, 'fr')), M.L_FRONT),
    ('R on front-right corner', meas(right=corners(RIGHT_FOOT, 'fr')), M.R_FRONT_RIGHT),
    ('R on back-right corner', meas(right=corners(RIGHT_FOOT, 'br')), M.R_BACK_RIGHT),
    # A CoP clearly outside the polygon counts as on the nearest edge or corner.
    ('L CoP ahead of the foot', meas(L_FLAT, cop=(0.3, 0.1)), M.L_FRONT),
    ('L CoP beyond the front-left corner', meas(L_FLAT, cop=(0.3, 0.4)), M.L_FRONT_LEFT),
    # The direction is judged in the heading frame, not the foot frame.
    ('L yawed foot, front edge', meas(corners(YAWED_LEFT), left_foot=YAWED_LEFT,
                                      cop=local_point(YAWED_LEFT, HL, 0.0)), M.L_FRONT),
    ('L yawed foot, heading turned', meas(corners(YAWED_LEFT), left_foot=YAWED_LEFT, heading=-0.5,
                                          cop=local_point(YAWED_LEFT, HL, 0.0)), M.L_LEFT),
    # No contact.
    ('no contact', meas(cop=(math.nan, math.nan)), M.OUTSIDE),
]


def test_enum_matches_the_shared_names():
    assert [m.name for m in ContactMode] == [n.replace('-', '_') for n in CONTACT_MODE_NAMES]
    assert [m.value for m in ContactMode] == list(range(len(CONTACT_MODE_NAMES)))
    assert ContactMode.L_FRONT_LEFT.label == 'L-FRONT-LEFT'


def test_cases_cover_all_16_modes():
    assert {expected for _, _, expected in CASES} == set(ContactMode)


@pytest.mark.parametrize('name, m, expected', CASES, ids=[c[0] for c in CASES])
def test_mode(name, m, expected):
    assert classify_contact_mode(m) == expected


@pytest.mark.parametrize('theta', [0.3, 1.2, -2.5, math.pi, 4.0])
@pytest.mark.parametrize('name, m, expected', CASES, ids=[c[0] for c in CASES])
def test_turning_configuration_and_heading_together_keeps_the_mode(name, m, expected, theta):
    assert classify_contact_mode(rotated(m, theta)) == expected


def test_edge_tolerance():
    m = meas(L_FLAT, cop=(HL - 0.009, 0.1))
    assert classify_contact_mode(m) == M.L_FRONT
    assert classify_contact_mode(m, edge_tolerance_m=0.005) == M.L_INSIDE


def test_nan_cop_falls_back_to_force_weighted_contacts():
    rows = np.array([[HL, 0.1 + HW, 200.0], [HL, 0.1 - HW, 200.0],
                     [-HL, 0.1 - HW, 0.0], [-HL, 0.1 + HW, 0.0]])
    m = meas(L_FLAT, cop=(math.nan, math.nan))
    m.left_contacts = rows
    mode, x, y = classify_contact_mode_and_cop(m)
    assert mode == M.L_FRONT
    assert (x, y) == pytest.approx((HL, 0.1))


def test_nan_cop_without_force_uses_the_plain_mean():
    mode, x, y = classify_contact_mode_and_cop(meas(L_FLAT, cop=(math.nan, 0.0), left_force=0.0))
    assert mode == M.L_INSIDE
    assert (x, y) == pytest.approx((0.0, 0.1))


def test_returns_the_cop_used_and_nan_when_outside():
    assert classify_contact_mode_and_cop(meas(L_FLAT, cop=(0.01, 0.12)))[1:] == (0.01, 0.12)
    mode, x, y = classify_contact_mode_and_cop(meas(cop=(math.nan, math.nan)))
    assert mode == M.OUTSIDE and math.isnan(x) and math.isnan(y)


class TestFoldingRule:
    @pytest.mark.parametrize('support, x, y, expected', [
        ('L', None, 'RIGHT', M.L_INSIDE),
        ('L', 'FRONT', 'RIGHT', M.L_FRONT),
        ('R', 'BACK', 'LEFT', M.R_BACK),
        ('R', None, 'LEFT', M.R_INSIDE),
        ('LR', None, 'LEFT', M.LR_INSIDE),
        ('LR', None, 'RIGHT', M.LR_INSIDE),
        ('LR', 'FRONT', 'LEFT', M.LR_FRONT),
        ('LR', 'BACK', 'RIGHT', M.LR_BACK),
    ])
    def test_unlisted_components_are_dropped(self, support, x, y, expected):
        assert mode_from_parts(support, x, y) == expected

    def test_listed_modes_map_to_themselves(self):
        for mode in ContactMode:
            if mode is M.OUTSIDE:
                continue
            support, *parts = mode.label.split('-')
            x = next((p for p in parts if p in ('FRONT', 'BACK')), None)
            y = next((p for p in parts if p in ('LEFT', 'RIGHT')), None)
            assert mode_from_parts(support, x, y) == mode

    def test_unknown_parts_raise(self):
        with pytest.raises(ValueError):
            mode_from_parts('X', None, None)
        with pytest.raises(ValueError):
            mode_from_parts('L', 'LEFT', None)


class TestValidation:
    def test_wrong_contact_shape(self):
        m = meas(L_FLAT)
        m.left_contacts = np.zeros((4, 2))
        with pytest.raises(ValueError, match='left_contacts'):
            classify_contact_mode(m)

    def test_non_finite_contact(self):
        m = meas(right=R_FLAT)
        m.right_contacts[1, 0] = math.nan
        with pytest.raises(ValueError, match='right_contacts'):
            classify_contact_mode(m)

    def test_non_finite_heading(self):
        with pytest.raises(ValueError, match='heading'):
            classify_contact_mode(meas(L_FLAT, heading=math.inf))

    def test_empty_contacts_of_any_shape_mean_no_contact(self):
        m = meas(L_FLAT, cop=(0.0, 0.1))
        m.right_contacts = np.array([])
        assert classify_contact_mode(m) == M.L_INSIDE
