"""The closed-loop stabilizer of C_bal (fall_predictor.robot.stabilizer): each stage against a
hand-computed answer, and the closed loop on the simulated robot with a wrong model."""
import math

import numpy as np
import pytest

from fall_predictor.monitor.records import Measurement
from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.robot.balance_controller import BalanceController, GaitConfig, ReflexConfig
from fall_predictor.robot.stabilizer import Stabilizer, StabilizerConfig, foot_wrench
from fall_predictor.sim.pybullet_world import PybulletWorld

OMEGA = math.sqrt(9.81 / 0.59)
LEFT, RIGHT = np.array([0.0, 0.1]), np.array([0.0, -0.1])
FEET = {'l': LEFT, 'r': RIGHT}


def measurement(com_xy, vel_xy=(0.0, 0.0), left=None, right=None) -> Measurement:
    mass = rm.TOTAL_MASS_KG
    empty = np.zeros((0, 3))
    return Measurement(t=0.0, com=np.array([*com_xy, 0.59]), lin_mom=mass * np.array([*vel_xy, 0.0]),
                       ang_mom=np.zeros(3), heading=0.0, cop=np.full(3, np.nan),
                       left_contacts=empty if left is None else np.asarray(left, float),
                       right_contacts=empty if right is None else np.asarray(right, float),
                       left_foot=np.array([*LEFT, 0.0]), right_foot=np.array([*RIGHT, 0.0]),
                       non_foot_contact=False)


def centred(foot, force):
    """Four contact points around ``foot`` carrying ``force`` with their CoP at the foot centre."""
    return [[foot[0] + dx, foot[1] + dy, force / 4] for dx in (-0.05, 0.05) for dy in (-0.03, 0.03)]


def test_foot_wrench_is_the_force_weighted_centre():
    force, cop = foot_wrench(np.array([[0.0, 0.0, 100.0], [0.1, 0.0, 300.0]]))
    assert force == 400.0 and cop == pytest.approx([0.075, 0.0])
    force, cop = foot_wrench(np.zeros((0, 3)))
    assert force == 0.0 and np.isnan(cop).all()


def test_desired_zmp_is_pattern_zmp_plus_gain_times_dcm_error():
    config = StabilizerConfig(dcm_gain=2.0, dcm_integral_gain=0.0)
    stabilizer = Stabilizer(config, OMEGA, 0.001, rm.TOTAL_MASS_KG)
    # CoM 1 cm ahead of the pattern and moving forward at 0.05 m/s: xi error = 0.01 + 0.05/omega.
    m = measurement((0.01, 0.0), (0.05, 0.0), centred(LEFT, 200), centred(RIGHT, 200))
    stabilizer.update(m, np.zeros(2), np.zeros(2), np.zeros(2), FEET, frozenset())
    error = 0.01 + 0.05 / OMEGA
    assert stabilizer.dcm_error == pytest.approx([error, 0.0])
    assert stabilizer.desired_zmp == pytest.approx([2.0 * error, 0.0])


def test_desired_zmp_stays_inside_the_support_polygon():
    config = StabilizerConfig(dcm_integral_gain=0.0)
    stabilizer = Stabilizer(config, OMEGA, 0.001, rm.TOTAL_MASS_KG)
    m = measurement((0.5, 0.0), (1.0, 0.0), centred(LEFT, 200), centred(RIGHT, 200))
    stabilizer.update(m, np.zeros(2), np.zeros(2), np.zeros(2), FEET, frozenset())
    # The soles reach rm.SOLE_LENGTH_M / 2 ahead of their centres; minus the margin.
    assert stabilizer.desired_zmp[0] == pytest.approx(rm.SOLE_LENGTH_M / 2 - config.support_margin_m)


def test_ankle_admittance_turns_the_toe_down_to_move_the_cop_forward():
    # Desired ZMP ahead of the measured CoP of a single stance foot: the sole pitches toe-down
    # (+pitch) at the admittance rate times the CoP error.
    config = StabilizerConfig(dcm_gain=2.0, dcm_integral_gain=0.0, ankle_leak_s=1e9)
    stabilizer = Stabilizer(config, OMEGA, 0.001, rm.TOTAL_MASS_KG)
    m = measurement((0.01, 0.1), (0.0, 0.0), centred(LEFT, 400), None)
    corrections = stabilizer.update(m, np.array([0.0, 0.1]), np.zeros(2), LEFT.copy(), FEET, frozenset({'r'}))
    cop_error = stabilizer.desired_zmp[0] - LEFT[0]
    assert cop_error == pytest.approx(0.02)
    assert corrections['l'].pitch_rad == pytest.approx(0.001 * config.cop_admittance_pitch * cop_error)
    assert corrections['r'].pitch_rad == 0.0


def test_force_difference_control_shortens_the_overloaded_leg():
    # The desired ZMP midway between the feet asks for equal forces; the left carries more, so
    # the left sole is raised and the right lowered by as much.
    config = StabilizerConfig(dcm_gain=0.0, dcm_integral_gain=0.0, force_difference_leak_s=1e9)
    stabilizer = Stabilizer(config, OMEGA, 0.001, rm.TOTAL_MASS_KG)
    m = measurement((0.0, 0.0), (0.0, 0.0), centred(LEFT, 300), centred(RIGHT, 100))
    corrections = stabilizer.update(m, np.zeros(2), np.zeros(2), np.zeros(2), FEET, frozenset())
    expected = 0.001 * config.force_difference_admittance * (300 - 100) / 2
    assert corrections['l'].height_m == pytest.approx(expected)
    assert corrections['r'].height_m == pytest.approx(-expected)


def test_invalid_gains_are_refused():
    with pytest.raises(ValueError, match='dcm_gain'):
        StabilizerConfig(dcm_gain=-1.0)
    with pytest.raises(ValueError, match='ankle_leak_s'):
        StabilizerConfig(ankle_leak_s=0.0)


def walk(duration_s: float, stabilizer: StabilizerConfig, **model_error) -> tuple[bool, np.ndarray, np.ndarray]:
    """Walk unpushed (reflex off); returns fallen, the DCM tracking error of every tick and the
    final CoM."""
    with PybulletWorld() as sim:
        controller = BalanceController(GaitConfig(), ReflexConfig(enabled=False), stabilizer=stabilizer,
                                       **model_error)
        q0, torso0 = controller.initial_posture()
        m = sim.reset(q0, torso0)
        errors = []
        while sim.t < duration_s and not m.fallen:
            sim.set_joint_targets(controller.update(m))
            m = sim.step()
            errors.append(float(np.linalg.norm(controller.stabilizer.dcm_error)))
        return m.fallen, np.array(errors), m.com


def test_walks_60_s_with_a_wrong_model():
    # The controller believes the robot 5 % heavier than it is and sees the CoM 2 cm forward.
    gait = GaitConfig()
    fallen, _, com = walk(60.0, StabilizerConfig(), model_mass_kg=1.05 * rm.TOTAL_MASS_KG,
                          com_bias_m=(0.02, 0.0, 0.0))
    assert not fallen
    # ... and still walks: at least 80 % of the planned distance along the planned direction.
    planned_m = (60.0 - gait.initial_stand_s) * gait.step_length_m / (gait.single_support_s + gait.double_support_s)
    assert com[0] > 0.8 * planned_m


def test_feedback_halves_the_dcm_tracking_error():
    # With every feedback gain at zero the same walk tracks the pattern's DCM much worse (it
    # still walks: the stiff legs carry an unpushed slow walk even open loop; see docs/results.md).
    _, closed, _ = walk(12.0, StabilizerConfig())
    _, open_loop, _ = walk(12.0, StabilizerConfig().open_loop())
    assert np.median(closed[2000:]) < 0.5 * np.median(open_loop[2000:])
