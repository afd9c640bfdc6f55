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


# -- the learned direction ------------------------------------------------------------------

from fall_predictor.learning.direction_training import (DirectionSamples, fit_learned_direction,  # noqa: E402
                                                        turn_targets)
from fall_predictor.learning.mirror import MIRROR_SIGNS  # noqa: E402
from fall_predictor.monitor.fall_direction import (DIRECTION_INPUT_NAMES, FallDirectionError,  # noqa: E402
                                                   LearnedDirection, direction_inputs,
                                                   momentum_direction)
from fall_predictor.monitor.time_to_fall import RegressionTree  # noqa: E402

COM_ACROSS = DIRECTION_INPUT_NAMES.index('com_across')


def test_direction_inputs_see_the_state_from_the_momentum():
    # Momentum along +y; the CoM 0.1 m along +x of the CoP is to the momentum's right.
    x = features(com=(0.1, 0.02, 0.6), momentum=(0.0, 12.0, 0.0))
    x[6:8] = (3.0, -1.0)                    # angular momentum about the CoM, x and y
    inputs = dict(zip(DIRECTION_INPUT_NAMES, direction_inputs(x)))
    assert inputs == pytest.approx({'bearing_cos': 0.0, 'bearing_sin': 1.0, 'lin_mom_xy': 12.0,
                                    'com_z': 0.6, 'com_along': 0.02, 'com_across': -0.1,
                                    'ang_mom_along': -1.0, 'ang_mom_across': -3.0})
    assert direction_inputs(features()) is None             # no momentum: no direction


def test_the_mirror_image_flips_exactly_the_sideways_inputs():
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = rng.normal(size=15)
        plain, mirrored = direction_inputs(x), direction_inputs(x * MIRROR_SIGNS)
        flips = {'bearing_sin', 'com_across', 'ang_mom_along'}     # axial: along flips
        expected = [-v if name in flips else v for name, v in zip(DIRECTION_INPUT_NAMES, plain)]
        assert mirrored == pytest.approx(expected, abs=1e-12)


def _side_tree(turn_rad: float) -> RegressionTree:
    """Turn left by ``turn_rad`` when the CoM is off to the momentum's left, else right."""
    return RegressionTree((COM_ACROSS, -1, -1), (0.0, 0.0, 0.0), (1, -1, -1), (2, -1, -1),
                          (0.0, -turn_rad, turn_rad), n_inputs=len(DIRECTION_INPUT_NAMES))


def test_a_learned_direction_turns_the_momentum_and_round_trips():
    learned = LearnedDirection((_side_tree(0.3), _side_tree(0.2)), bias=0.1)
    x = features(com=(0.0, 0.05, 0.6), momentum=(10.0, 0.0, 0.0))    # CoM to the left
    assert learned.direction(x) == pytest.approx([math.cos(0.6), math.sin(0.6), 0.0])
    x[1] = -0.05                                                      # to the right
    assert learned.direction(x) == pytest.approx([math.cos(-0.4), math.sin(-0.4), 0.0])
    assert np.isnan(learned.direction(features())).all()
    assert LearnedDirection.from_json(learned.to_json()) == learned
    document = learned.to_json()
    document['trees'][0]['feature'][0] = len(DIRECTION_INPUT_NAMES)   # beyond the 8 inputs
    with pytest.raises(FallDirectionError, match=r'trees\[0\]: node 0: feature index 8'):
        LearnedDirection.from_json(document)
    with pytest.raises(FallDirectionError, match='inputs'):
        LearnedDirection.from_json({**learned.to_json(), 'inputs': ['com_x']})
    with pytest.raises(FallDirectionError, match='bias'):
        LearnedDirection((_side_tree(0.3),), bias=math.nan)


def _samples(n: int, seed: int) -> DirectionSamples:
    """Falls whose CoM goes 0.4 rad to the side of the momentum its CoM is off to."""
    rng = np.random.default_rng(seed)
    X = np.zeros((n, 15))
    X[:, 0:2] = rng.normal(0.0, 0.05, (n, 2))
    X[:, 2] = 0.6
    X[:, 3:5] = rng.normal(0.0, 20.0, (n, 2))
    X[:, 6:8] = rng.normal(0.0, 2.0, (n, 2))
    actual = []
    for x in X:
        c, s, *_ , across, _, _ = direction_inputs(x)
        angle = math.atan2(s, c) + (0.4 if across > 0.0 else -0.4)
        actual.append((math.cos(angle), math.sin(angle)))
    return DirectionSamples(X, np.array(actual))


def test_the_fitted_direction_recovers_a_known_turn_and_is_odd_under_the_mirror():
    learned = fit_learned_direction(_samples(400, seed=1))
    fresh = _samples(200, seed=2)
    inputs, turns = turn_targets(fresh)
    predicted = np.array([learned.turn_rad(v) for v in inputs.tolist()])
    away = np.abs(inputs[:, COM_ACROSS]) > 0.01             # not on the split itself
    assert np.median(np.abs(predicted - turns)[away]) < math.radians(3.0)
    mirrored = np.array([learned.turn_rad(v) for v in (inputs * [1, -1, 1, 1, 1, -1, -1, 1]).tolist()])
    assert np.median(np.abs(mirrored + predicted)[away]) < math.radians(3.0)
    # The momentum alone errs by the whole turn.
    errors = [angular_error_rad(momentum_direction(x, 1.0), a) for x, a in zip(fresh.X, fresh.actual)]
    assert np.median(errors) == pytest.approx(0.4, abs=1e-9)
    with pytest.raises(ValueError, match='too few'):
        fit_learned_direction(_samples(9, seed=3))           # 18 with the mirror images


def test_trees_over_the_15_features_are_not_a_learned_direction():
    tree = RegressionTree((-1,), (0.0,), (-1,), (-1,), (0.5,))          # n_inputs 15
    with pytest.raises(FallDirectionError, match='read the 8 direction inputs, got RegressionTree '
                                                 'over 15 inputs'):
        LearnedDirection((tree,))
