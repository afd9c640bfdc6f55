"""monitor.sole_contact: the part of a sole on the ground and its contact forces."""
import math

import numpy as np
import pinocchio as pin
import pytest

from fall_predictor.monitor.records import SoleGeometry
from fall_predictor.monitor.sole_contact import SoleContacts, split_force_to_corners

SOLE = SoleGeometry('l_sole', 0.2, 0.1)
CORNERS = SOLE.corners()          # front left, front right, back right, back left


def test_force_split_reproduces_the_cop():
    corners = np.array([[0.1, 0.05], [0.1, -0.05], [-0.1, -0.05], [-0.1, 0.05]])
    f = split_force_to_corners(corners, np.array([0.04, -0.01]), 300.0)
    assert f.sum() == pytest.approx(300.0)
    assert f @ corners / f.sum() == pytest.approx([0.04, -0.01])
    edge = split_force_to_corners(corners[:2], np.array([0.1, 0.03]), 100.0)
    assert edge == pytest.approx([80.0, 20.0])
    # A CoP outside the sole is clipped to it; one corner takes it all.
    assert split_force_to_corners(corners[:2], np.array([0.1, 0.5]), 10.0) == pytest.approx([10.0, 0.0])
    assert split_force_to_corners(corners[:1], np.array([0.0, 0.0]), 7.0) == pytest.approx([7.0])


@pytest.mark.parametrize('roll, pitch, touching', [
    (0.0, 0.0, [0, 1, 2, 3]),            # flat
    (0.0, 0.2, [0, 1]),                  # toes down (pitch about y): the front edge
    (0.0, -0.2, [2, 3]),                 # heel down
    (0.2, 0.0, [1, 2]),                  # rolled right side down
    (0.2, 0.2, [1]),                     # front right corner
])
def test_the_part_on_the_ground_is_the_lowest_corners(roll, pitch, touching):
    soles = SoleContacts({'l': SOLE}, tilt_tolerance_m=0.002)
    rot = pin.rpy.rpyToMatrix(roll, pitch, 0.3)
    part = soles.ground_part('l', rot.tolist())
    heights = (CORNERS @ rot.T)[:, 2]
    assert [i for i, t in enumerate(part.key) if t] == touching
    assert heights[touching].max() <= heights.min() + 0.002
    assert part.flat == (len(touching) == 4)
    np.testing.assert_allclose(part.corners, CORNERS[touching])
    assert part.centre == pytest.approx(CORNERS[touching].mean(axis=0)[:2])
    # The same orientation again: the same part, not a new one.
    assert soles.ground_part('l', rot.tolist()) is part


def test_contacts_carry_the_force_at_the_cop_in_the_world():
    soles = SoleContacts({'l': SOLE}, tilt_tolerance_m=0.002)
    yaw = 0.6
    rot = pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    origin = (1.0, -2.0)
    cop = (0.03, -0.02)
    for rows, n in ((rot.tolist(), 4), (pin.rpy.rpyToMatrix(0.0, 0.2, yaw).tolist(), 2)):
        part = soles.ground_part('l', rows)
        c = soles.contacts('l', part, rows, origin, *cop, 400.0)
        assert c.shape == (n, 3)
        assert c[:, 2].sum() == pytest.approx(400.0)
        r = np.array(rows)
        # Each point is its corner carried into the world (x, y).
        np.testing.assert_allclose(c[:, :2], (part.corners @ r.T)[:, :2] + origin, atol=1e-15)
        if n == 4:
            # The force-weighted mean of the points is the CoP carried into the world.
            mean = c[:, 2] @ c[:, :2] / 400.0
            expected = r[:2, :2] @ np.array(cop) + origin
            np.testing.assert_allclose(mean, expected, atol=1e-12)
        else:
            # Along the front edge: the CoP's lateral position, projected on the edge.
            local = (c[:, 2] @ part.corners[:, :2]) / 400.0
            assert local == pytest.approx([0.1, cop[1]])
    assert math.isclose(soles.tilt_tolerance_m, 0.002)
