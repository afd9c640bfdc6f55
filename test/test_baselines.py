import math
from dataclasses import dataclass

import numpy as np
import pytest

from fall_predictor.learning.baselines import capture_point_curve, com_height_curve, momentum_curve, pareto_front
from fall_predictor.monitor.capture_point import capture_point_distances, signed_distance_to_support
from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2 as GRAVITY
from fall_predictor.monitor.records import FEATURE_NAMES, Measurement, TrajectoryFeatures
from fall_predictor.profiles.asimo_like_urdf import TOTAL_MASS_KG

DT = 0.001
COM_Z = FEATURE_NAMES.index('com_z')
LIN_MOM_X = FEATURE_NAMES.index('lin_mom_x')
LIN_MOM_Y = FEATURE_NAMES.index('lin_mom_y')
T = np.arange(3000) * DT
T_PUSH, T_FALLEN = 1.0, 2.5


def between(start: float, end: float = math.inf) -> np.ndarray:
    return (T >= start - 1e-9) & (T < end - 1e-9)


def trajectory(name: str, fallen: bool, X: np.ndarray) -> TrajectoryFeatures:
    return TrajectoryFeatures(name, T, X, np.zeros(T.size, dtype=int), fallen, T_PUSH, T_PUSH + 0.1,
                              T_FALLEN if fallen else None, 2.0 if fallen else None)


@pytest.fixture
def trajectories() -> list[TrajectoryFeatures]:
    """b0 quiet; b1 dips to 0.50 m with |p_y| = 8 at 1.5 s; f: CoM 0.53 m from 2.0 s, 0.45 m
    from 2.2 s (the guard), 0.30 m from 2.5 s (fallen), p_x = -12 from 2.1 s."""
    quiet = np.zeros((T.size, len(FEATURE_NAMES)))
    quiet[:, COM_Z] = 0.59
    b1 = quiet.copy()
    b1[between(1.5, 1.6), COM_Z] = 0.50
    b1[between(1.5, 1.6), LIN_MOM_Y] = 8.0
    f = quiet.copy()
    f[between(2.0), COM_Z] = 0.53
    f[between(2.2), COM_Z] = 0.45
    f[between(2.5), COM_Z] = 0.30
    f[between(2.1), LIN_MOM_X] = -12.0
    return [trajectory('b0', False, quiet), trajectory('b1', False, b1), trajectory('f', True, f)]


def test_com_height_curve(trajectories):
    curve = com_height_curve(trajectories, [0.30, 0.51, 0.55, 0.60])
    assert [p.threshold for p in curve] == [0.30, 0.51, 0.55, 0.60]
    assert [p.fpr for p in curve] == [0.0, 0.5, 0.5, 1.0]
    # Below the guard height only the guard fires (at 2.2 s); at 0.60 m every state is an
    # alarm, so the prediction is at the push.
    assert [p.tau_lead_s for p in curve] == pytest.approx([0.3, 0.3, 0.5, 1.5])
    assert curve[3].evaluation.n_pre_push_alarms == 3
    # Without the guard a threshold below every CoM height never fires.
    unguarded = com_height_curve(trajectories, [0.30], guard_com_height_m=0.0)
    assert unguarded[0].tau_lead_s == 0.0 and unguarded[0].evaluation.n_missed == 1


def test_momentum_curve(trajectories):
    curve = momentum_curve(trajectories, [10.0, math.inf], [5.0, 10.0])
    assert [p.threshold for p in curve] == [(10.0, 5.0), (10.0, 10.0), (math.inf, 5.0), (math.inf, 10.0)]
    assert [p.fpr for p in curve] == [0.5, 0.0, 0.5, 0.0]
    assert [p.tau_lead_s for p in curve] == pytest.approx([0.4, 0.4, 0.3, 0.3])


def test_momentum_curve_with_history_window(trajectories):
    (point,) = momentum_curve(trajectories, [10.0], [5.0], tau_his_s=0.2)
    assert point.fpr == 0.0                     # b1's 0.1 s excursion is shorter than the window
    # One run from 2.1 s (momentum, joined by the guard at 2.2 s) holds the 0.2 s window at
    # 2.3 s: the guard goes through the window too, so no earlier alarm at 2.2 s.
    assert point.tau_lead_s == pytest.approx(0.2)


def test_capture_point_curve(trajectories):
    distances = [np.full(T.size, -0.05), np.full(T.size, -0.05), np.full(T.size, -0.05)]
    distances[1][between(1.5, 1.6)] = -0.01
    distances[2][between(2.05)] = 0.02
    curve = capture_point_curve(trajectories, distances, [0.0, 0.02, 0.06])
    assert [p.fpr for p in curve] == [0.0, 0.5, 1.0]
    assert [p.tau_lead_s for p in curve] == pytest.approx([0.45, 0.45, 1.5])
    with pytest.raises(ValueError):
        capture_point_curve(trajectories, distances[:2], [0.0])
    with pytest.raises(ValueError):
        capture_point_curve(trajectories, [d[:-1] for d in distances], [0.0])


def measurement(lin_mom_x: float, left: list, right: list, com_z: float = 0.59) -> Measurement:
    def contacts(points):
        return np.array([[x, y, 50.0] for x, y in points]).reshape(-1, 3)
    return Measurement(t=0.0, com=np.array([0.0, 0.0, com_z]), lin_mom=np.array([lin_mom_x, 0.0, 0.0]),
                       ang_mom=np.zeros(3), heading=0.0, cop=np.zeros(3),
                       left_contacts=contacts(left), right_contacts=contacts(right),
                       left_foot=np.zeros(3), right_foot=np.zeros(3), non_foot_contact=False)


def test_capture_point_distances():
    omega = math.sqrt(GRAVITY / 0.59)
    momentum_for_xi_03 = 0.3 * TOTAL_MASS_KG * omega        # puts the capture point at x = 0.3 m
    left = [(-0.1, 0.0), (0.1, 0.0), (0.1, 0.1), (-0.1, 0.1)]
    right = [(-0.1, -0.1), (0.1, -0.1), (0.1, 0.0)]
    distances = capture_point_distances([
        measurement(0.0, left, right),                  # at the centre of a 0.2 m square: depth 0.1
        measurement(momentum_for_xi_03, left, right),   # 0.2 m beyond the front edge
        measurement(0.0, [], []),                       # no support at all
        measurement(0.0, [(0.0, 0.05)], []),            # a single contact point
        measurement(0.0, [(-0.1, 0.05), (0.1, 0.05)], [], com_z=0.3),   # a segment
    ], total_mass_kg=TOTAL_MASS_KG)
    assert distances == pytest.approx([-0.1, 0.2, math.inf, 0.05, 0.05])


def test_signed_distance_to_support_outside_a_corner():
    square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    assert signed_distance_to_support(2.0, 2.0, square) == pytest.approx(math.sqrt(2.0))
    assert signed_distance_to_support(0.5, 0.25, square) == pytest.approx(-0.25)
    assert signed_distance_to_support(1.0, 0.5, square) == pytest.approx(0.0)
    assert signed_distance_to_support(0.0, 0.0, []) == math.inf


@dataclass
class Point:
    fpr: float
    tau_lead_s: float


def test_pareto_front():
    points = [Point(0.5, 0.6), Point(0.1, 0.3), Point(0.1, 0.4), Point(0.0, 0.1), Point(0.3, 0.35),
              Point(0.5, 0.6), Point(0.7, 0.55), Point(math.nan, 9.0), Point(1.0, 1.0)]
    front = pareto_front(points)
    assert [(p.fpr, p.tau_lead_s) for p in front] == [(0.0, 0.1), (0.1, 0.4), (0.5, 0.6), (1.0, 1.0)]
    assert front[2] is points[0]
    assert pareto_front([]) == []
