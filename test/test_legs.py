"""Leg inverse kinematics (robot/legs.py) against the URDF's own forward kinematics: the sole poses
of known leg angles are solved back to those poses, by the closed form (ASIMO-like robot) and by
the numeric solver on each leg's chain (G1), for single targets, for a smooth 1 kHz swing (the
extrapolated warm start) and across a jump."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from fall_predictor.profiles.profile import load_profile
from fall_predictor.robot.legs import ClosedFormLegs, NumericLegs, leg_solver


def _sole_pose(robot, profile, side: str, leg: np.ndarray) -> tuple[pin.SE3, pin.SE3]:
    """Base and sole poses of the whole robot (free flyer at identity) with ``leg`` on ``side``."""
    model = robot.model
    data = model.createData()
    q = pin.neutral(model)
    q[[model.joints[model.getJointId(j)].idx_q for j in profile.leg_joints(side)]] = leg
    pin.framesForwardKinematics(model, data, q)
    return data.oMi[1].copy(), data.oMf[robot.sole_ids[side]].copy()


def _reached(robot, profile, side, leg, sole) -> float:
    _, got = _sole_pose(robot, profile, side, leg)
    return float(np.abs(pin.log6(got.actInv(sole)).vector).max())


@pytest.mark.parametrize('name, kind', [('asimo_like', ClosedFormLegs), ('g1', NumericLegs)])
def test_solved_legs_reach_the_sole_poses_of_known_angles(name, kind):
    profile = load_profile(name)
    legs = leg_solver(profile)
    assert isinstance(legs, kind)
    robot = legs.robot
    rng = np.random.default_rng(4)
    # A crouched leg (the knee bent), each joint moved a little: poses a walk asks for.
    crouch = {'asimo_like': np.array([0.0, 0.0, -0.4, 0.8, -0.4, 0.0]),
              'g1': np.array([-0.3, 0.0, 0.0, 0.6, -0.3, 0.0])}[name]
    for side in ('l', 'r'):
        for _ in range(20):
            leg = crouch + rng.uniform(-0.15, 0.15, 6)
            base, sole = _sole_pose(robot, profile, side, leg)
            solved = legs.solve(side, base.translation, base.rotation, sole.translation, sole.rotation)
            assert _reached(robot, profile, side, solved, sole) < 1e-4
            assert np.abs(solved - leg).max() < 1e-3      # the same branch (knee forward)


def test_numeric_legs_track_a_smooth_swing_and_a_jump():
    profile = load_profile('g1')
    legs = leg_solver(profile)
    robot = legs.robot
    base, sole0 = _sole_pose(robot, profile, 'l', np.array([-0.3, 0.0, 0.0, 0.6, -0.3, 0.0]))
    errors = []
    for k in range(600):       # 0.6 s of a swing at 1 kHz: up 4 cm, forward 8 cm
        s = k / 599
        target = sole0.copy()
        target.translation = sole0.translation + [0.08 * (0.5 - 0.5 * np.cos(np.pi * s)), 0.0,
                                                  0.04 * (0.5 - 0.5 * np.cos(2 * np.pi * s))]
        leg = legs.solve('l', base.translation, base.rotation, target.translation, target.rotation)
        errors.append(_reached(robot, profile, 'l', leg, target))
    assert max(errors) < 2e-5
    # A jump of 5 cm (a new plan): the extrapolation from the swing is wrong, the solve is not.
    target = sole0.copy()
    target.translation = sole0.translation + [0.0, 0.05, 0.0]
    leg = legs.solve('l', base.translation, base.rotation, target.translation, target.rotation)
    assert _reached(robot, profile, 'l', leg, target) < 2e-5


def test_a_leg_solved_for_two_base_attitudes_each_tick_follows_each_from_its_own_solutions():
    """The reflex step's swing leg is solved twice a tick: for the upright base and for the
    measured tilt. Each stream is warm-started from its own last solutions: solved interleaved,
    the upright stream gives exactly what it gives alone, the tilted one reaches its targets on
    the walking branch (warm-started from the other stream's
    solution, the previous solver missed these targets by up to 0.58 and moved the leg by up to
    2.9 rad in one tick, onto another branch with the hip at its limits)."""
    profile = load_profile('g1')
    robot = leg_solver(profile).robot
    base, sole0 = _sole_pose(robot, profile, 'r', np.array([-0.2, 0.0, 0.0, 0.4, -0.2, 0.0]))
    tilted = base.rotation @ pin.utils.rpyToMatrix(0.0, 0.45, 0.0)      # 26 deg of pitch
    interleaved, alone_upright = leg_solver(profile), leg_solver(profile)
    for k in range(400):       # the sole reaches 10 cm back and returns
        target = sole0.translation + [-0.10 * np.sin(np.pi * k / 399), 0.0, 0.0]
        up = interleaved.solve('r', base.translation, base.rotation, target, sole0.rotation)
        tilt = interleaved.solve('r', base.translation, tilted, target, sole0.rotation, stream='tilted')
        assert interleaved.last_error < 2e-5
        np.testing.assert_array_equal(
            up, alone_upright.solve('r', base.translation, base.rotation, target, sole0.rotation))
        for leg in (up, tilt):          # the walking branch: knee bent forward, hip not twisted
            assert leg[3] > 0.0 and abs(leg[1]) < 0.2 and abs(leg[2]) < 0.2
