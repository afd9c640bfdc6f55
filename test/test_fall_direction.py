"""Tests of the capture-point fall direction against hand-computed pendulum values."""
import math

import numpy as np
import pytest

from fall_predictor.monitor.fall_direction import angular_error_rad, capture_point_direction


def features(com=(0.0, 0.0, 0.6), momentum=(0.0, 0.0, 0.0)):
    x = np.zeros(15)
    x[0:3] = com
    x[3:6] = momentum
    return x


def test_forward_velocity_points_forward():
    # CoM above the CoP moving forward: the capture point is straight ahead.
    d = capture_point_direction(features(momentum=(10.0, 0.0, 0.0)), mass_kg=50.0)
    np.testing.assert_allclose(d, [1.0, 0.0, 0.0], atol=1e-12)


def test_offset_and_velocity_combine_as_the_pendulum_says():
    # c = (0, 0.02), v = (-0.3, 0) m/s at 0.6 m: omega = sqrt(9.81/0.6), xi = c + v/omega.
    mass, height = 40.0, 0.6
    omega = math.sqrt(9.81 / height)
    xi = np.array([-0.3 / omega, 0.02])
    d = capture_point_direction(features(com=(0.0, 0.02, height),
                                         momentum=(-0.3 * mass, 0.0, 0.0)), mass_kg=mass)
    np.testing.assert_allclose(d[:2], xi / np.linalg.norm(xi), atol=1e-12)
    assert d[2] == 0.0


def test_undefined_direction_is_nan():
    assert np.isnan(capture_point_direction(features(), mass_kg=50.0)).all()
    assert np.isnan(capture_point_direction(features(com=(np.nan, 0, 0.6)), 50.0)).all()
    with pytest.raises(ValueError):
        capture_point_direction(features(), mass_kg=0.0)


def test_angular_error_wraps_around_pi():
    assert angular_error_rad((1, 0), (0, 1)) == pytest.approx(math.pi / 2)
    assert angular_error_rad((math.cos(3.0), math.sin(3.0)), (math.cos(-3.0), math.sin(-3.0))) \
        == pytest.approx(2 * math.pi - 6.0)
    assert angular_error_rad((-1, 0), (1, 0)) == pytest.approx(math.pi)
