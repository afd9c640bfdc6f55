"""Joint servos (fall_predictor.robot.actuation) and their use by the simulator: the PD law and
torque-speed envelope against hand-computed values, and the simulated drives' limits."""
import math

import numpy as np
import pybullet as pb
import pytest

from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.robot.actuation import SERVO_GAINS, joint_group, servo_arrays, servo_torques
from fall_predictor.robot.balance_controller import BalanceController
from fall_predictor.sim.pybullet_world import PybulletWorld, PybulletConfig

KNEE = rm.JOINT_NAMES.index('l_knee_pitch')
ELBOW = rm.JOINT_NAMES.index('l_elbow_pitch')


def test_every_joint_has_servo_gains():
    assert {joint_group(n) for n in rm.JOINT_NAMES} <= set(SERVO_GAINS)
    servo = servo_arrays()
    assert np.all(servo.kp > 0) and np.all(servo.kd > 0) and np.all(servo.armature > 0)


def test_pd_law_and_torque_speed_envelope_by_hand():
    servo = servo_arrays()
    kp, kd = servo.kp[KNEE], servo.kd[KNEE]
    effort, rated = servo.effort[KNEE], servo.velocity[KNEE]
    n = len(rm.JOINT_NAMES)

    def knee_torque(error: float, dq: float) -> float:
        q = np.zeros(n)
        target = np.zeros(n)
        target[KNEE] = error
        v = np.zeros(n)
        v[KNEE] = dq
        return float(servo_torques(servo, target, q, v)[KNEE])

    # Small error at rest: the plain PD torque.
    assert knee_torque(0.001, 0.0) == pytest.approx(kp * 0.001)
    assert knee_torque(0.001, 0.1) == pytest.approx(kp * 0.001 - kd * 0.1)
    # Large error at rest: the drive's effort.
    assert knee_torque(1.0, 0.0) == pytest.approx(effort)
    # Driving at half the rated speed: half the effort is left in the direction of motion.
    assert knee_torque(1.0, rated / 2) == pytest.approx(effort / 2)
    # At or beyond the rated speed nothing drives the motion any faster ...
    assert knee_torque(1.0, 1.2 * rated) == pytest.approx(0.0)
    # ... but braking against the motion has the full effort.
    assert knee_torque(-1.0, rated / 2) == pytest.approx(-effort)
    with pytest.raises(ValueError):
        servo_arrays(gain_scale=0.0)


@pytest.fixture(scope='module')
def standing():
    balance = BalanceController()
    q0, torso = balance.initial_posture()
    sim = PybulletWorld(config=PybulletConfig(actuation='pd_torque'))
    first = sim.reset(q0, torso)
    yield sim, q0, first
    sim.close()


def test_simulated_drives_carry_the_rotor_armature(standing):
    sim, _, _ = standing
    servo = servo_arrays()
    urdf_free = PybulletWorld()           # a world with the URDF's own inertias, to compare with
    try:
        robot = pb.loadURDF(str(rm.SIM_URDF_PATH), flags=pb.URDF_USE_INERTIA_FROM_FILE,
                            physicsClientId=urdf_free.client)
        for joint in (KNEE, ELBOW):
            info = pb.getDynamicsInfo(sim.robot, joint, physicsClientId=sim.client)
            bare = pb.getDynamicsInfo(robot, joint, physicsClientId=urdf_free.client)
            axis = np.abs(np.asarray(pb.getJointInfo(sim.robot, joint, physicsClientId=sim.client)[13]))
            added = np.asarray(info[2]) - np.asarray(bare[2])
            assert added == pytest.approx(servo.armature[joint] * axis)
    finally:
        urdf_free.close()


def test_standing_robot_holds_its_posture_under_its_weight(standing):
    sim, q0, first = standing
    sim.set_joint_targets(q0)
    for _ in range(1000):
        m = sim.step()
    q, dq, tau = sim.joint_states()
    legs = slice(0, 12)
    # Stiff position servos: the legs deflect by well under 1.5 deg, the CoM sinks < 2 mm,
    # and the weight rests on the feet.
    assert np.degrees(np.abs(q - q0)[legs]).max() < 1.5
    assert first.com[2] - m.com[2] < 0.002
    total = m.left_contacts[:, 2].sum() + m.right_contacts[:, 2].sum()
    assert total == pytest.approx(sim.total_mass * 9.81, rel=0.02)
    assert np.abs(m.lin_mom).max() < 0.05
    # Gravity loads the knees: the servo's torque is the PD law's on the measured deflection.
    servo = servo_arrays()
    assert tau[KNEE] == pytest.approx(servo.kp[KNEE] * (q0[KNEE] - q[KNEE]) - servo.kd[KNEE] * dq[KNEE],
                                      rel=0.05, abs=0.5)


def test_a_large_step_command_is_limited_to_the_rated_speed(standing):
    sim, q0, _ = standing
    servo = servo_arrays()
    target = q0.copy()
    target[ELBOW] = q0[ELBOW] - 1.5          # a 1.5 rad step of the free-hanging elbow
    sim.set_joint_targets(target)
    speeds = []
    for _ in range(600):
        sim.step()
        speeds.append(abs(sim.joint_states()[1][ELBOW]))
    assert max(speeds) <= servo.velocity[ELBOW] * 1.02
    assert max(speeds) > 0.5 * servo.velocity[ELBOW]       # it did move fast ...
    q = sim.joint_states()[0]
    assert q[ELBOW] == pytest.approx(target[ELBOW], abs=math.radians(2))   # ... and arrived


def test_the_walk_holds_on_the_compliant_servos():
    from fall_predictor.sim.trajectory import run_trajectory
    result = run_trajectory(None, 8.0, world=PybulletWorld(actuation='pd_torque'))
    assert not result.fallen and result.t_reflex is None
    com = result.com
    assert com[-1, 0] > 0.5                                  # it walks forward ...
    assert np.abs(com[:, 2] - com[0, 2]).max() < 0.01        # ... at a steady height
    # Single support alternates between the feet for most of the planned time
    # (5 cycles of 2 x 0.5 s after the 0.5 s stand): early touchdowns only trim it.
    left_only = sum(len(m.left_contacts) > 0 and len(m.right_contacts) == 0 for m in result.measurements)
    right_only = sum(len(m.right_contacts) > 0 and len(m.left_contacts) == 0 for m in result.measurements)
    planned_ms = (8.0 - 0.5) / 1.4 * 500
    assert left_only > 0.8 * planned_ms and right_only > 0.8 * planned_ms
