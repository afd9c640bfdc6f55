"""monitor.rotations against Pinocchio's rotations (an independent implementation)."""
import math

import numpy as np
import pinocchio as pin
import pytest

from fall_predictor.monitor import rotations

RNG = np.random.default_rng(7)


def _random_quaternions(n: int) -> list[tuple]:
    q = RNG.normal(size=(n, 4))
    return [tuple(row) for row in (q / np.linalg.norm(q, axis=1, keepdims=True)).tolist()]


def _pin_matrix(q) -> np.ndarray:
    return pin.Quaternion(np.array(q)).normalized().matrix()


@pytest.mark.parametrize('q', _random_quaternions(20))
def test_matrix_and_yaw_match_pinocchio(q):
    np.testing.assert_allclose(rotations.matrix(q), _pin_matrix(q), atol=1e-14)
    r = _pin_matrix(q)
    assert rotations.yaw(q) == pytest.approx(math.atan2(r[1, 0], r[0, 0]), abs=1e-13)


def test_product_is_the_matrix_product_and_the_conjugate_inverts():
    for a, b in zip(_random_quaternions(20), _random_quaternions(20)):
        np.testing.assert_allclose(rotations.matrix(rotations.multiply(a, b)),
                                   _pin_matrix(a) @ _pin_matrix(b), atol=1e-14)
        np.testing.assert_allclose(rotations.matrix(rotations.multiply(a, rotations.conjugate(a))),
                                   np.eye(3), atol=1e-14)


@pytest.mark.parametrize('angle', [0.0, 1e-14, 1e-7, 0.3, 2.0, math.pi - 1e-9])
def test_exponential_and_logarithm_match_pinocchio(angle):
    axis = RNG.normal(size=3)
    v = angle * axis / np.linalg.norm(axis)
    q = rotations.from_rotation_vector(*v.tolist())
    np.testing.assert_allclose(rotations.matrix(q), pin.exp3(v), atol=1e-14)
    assert math.sqrt(sum(c * c for c in q)) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(rotations.rotation_vector(q), v, atol=1e-12)
    # q and -q are one rotation: the logarithm is the short way round for both.
    np.testing.assert_allclose(rotations.rotation_vector(tuple(-c for c in q)), v, atol=1e-12)


def test_rotation_vector_is_pinocchios_log():
    for q in _random_quaternions(20):
        np.testing.assert_allclose(rotations.rotation_vector(q), pin.log3(_pin_matrix(q)),
                                   atol=1e-12)


def test_about_z_and_normalized():
    np.testing.assert_allclose(rotations.matrix(rotations.about_z(0.7)), pin.rpy.rpyToMatrix(0, 0, 0.7),
                               atol=1e-15)
    assert rotations.normalized((0.0, 0.0, 0.0, 3.0)) == (0.0, 0.0, 0.0, 1.0)
    assert rotations.yaw(rotations.about_z(-2.5)) == pytest.approx(-2.5, abs=1e-15)


def test_from_matrix_inverts_matrix_to_full_precision_even_near_upright():
    """Random rotations come back to 1e-15 (sign: w >= 0), every branch of Shepperd's method
    (each component the largest in turn) included; a rotation of 1e-9 rad about x comes back
    as 1e-9 rad, where a square root per component would be ~1e-8 off."""
    rng = np.random.default_rng(11)
    qs = [tuple(v) for v in rng.normal(size=(200, 4))]
    qs += [(1.0, 0.01, 0.02, 0.03), (0.01, 1.0, 0.02, 0.03), (0.01, 0.02, 1.0, 0.03),
           (0.01, 0.02, 0.03, 1.0), (0.0, 0.0, 1.0, 0.0)]
    for q in qs:
        q = rotations.normalized(q)
        expected = np.array(q) * (1.0 if q[3] >= 0.0 else -1.0)
        np.testing.assert_allclose(rotations.from_matrix(rotations.matrix(q)), expected, atol=1e-15)
    tiny = rotations.from_rotation_vector(1e-9, 0.0, 0.0)
    back = rotations.from_matrix(rotations.matrix(tiny))
    assert np.array(rotations.rotation_vector(back)) == pytest.approx([1e-9, 0.0, 0.0], rel=1e-6, abs=1e-17)
