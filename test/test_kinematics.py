"""Closed-form leg IK inverts FK, and FK agrees with PyBullet's kinematics of the URDF."""
import numpy as np
import pybullet as pb
import pytest

from fall_predictor.robot import kinematics as kin
from fall_predictor.profiles import asimo_like_urdf as rm


def _random_leg_angles(rng):
    return np.array([rng.uniform(-0.4, 0.4), rng.uniform(-0.3, 0.3), rng.uniform(-1.2, 0.3),
                     rng.uniform(0.1, 2.0), rng.uniform(-0.8, 0.8), rng.uniform(-0.4, 0.4)])


def test_ik_inverts_fk():
    rng = np.random.default_rng(0)
    for _ in range(500):
        q = _random_leg_angles(rng)
        body_rot = kin.rot_z(rng.uniform(-1, 1)) @ kin.rot_y(rng.uniform(-0.2, 0.2))
        hip = rng.uniform(-1, 1, 3)
        ankle, foot_rot = kin.leg_fk(hip, body_rot, q)
        assert np.allclose(kin.leg_ik(hip, body_rot, ankle, foot_rot), q, atol=1e-9)


def test_unreachable_ankle_gives_a_straight_leg_towards_it():
    hip = np.array([0.0, 0.0, 1.0])
    q = kin.leg_ik(hip, np.eye(3), np.array([0.0, 0.0, 0.0]), np.eye(3))
    assert q[3] == pytest.approx(0.0)


def test_fk_matches_pybullet():
    client = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(str(rm.SIM_URDF_PATH), [0, 0, 1], useFixedBase=1,
                           flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
        rng = np.random.default_rng(3)
        for side in rm.SIDES:
            q = _random_leg_angles(rng)
            for j, name in enumerate(rm.LEG_JOINTS):
                pb.resetJointState(body, rm.JOINT_NAMES.index(f'{side}_{name}'), q[j], physicsClientId=client)
            ankle, foot_rot = kin.leg_fk(kin.hip_position(np.array([0, 0, 1.0]), np.eye(3), side), np.eye(3), q)
            state = pb.getLinkState(body, rm.JOINT_NAMES.index(f'{side}_ankle_roll'),
                                    computeForwardKinematics=1, physicsClientId=client)
            assert np.allclose(state[4], ankle, atol=1e-9)
            assert np.allclose(np.array(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3), foot_rot, atol=1e-9)
    finally:
        pb.disconnect(client)


def test_parallel_case_matches_the_general_ik():
    rng = np.random.default_rng(5)
    for _ in range(300):
        yaw = rng.uniform(-1.0, 1.0)
        rot = kin.rot_z(yaw)
        hip = rng.uniform(-0.2, 0.2, 3) + np.array([0.0, 0.0, 0.55])
        ankle = hip + rot @ np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.15, 0.15), -rng.uniform(0.35, 0.5)])
        general = kin.leg_ik(hip, rot, ankle, rot)
        assert np.allclose(kin.leg_ik_parallel(tuple(hip), tuple(ankle), yaw), general, atol=1e-9)
