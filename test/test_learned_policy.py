"""The learned policy as a controller: Unitree's G1 policy from sensor samples to joint targets,
against torch run on Unitree's own observation formulas (``g1s_*`` in the fixtures)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from fall_predictor.monitor.sensor_records import SensorSample
from fall_predictor.robot.learned_policy import LearnedPolicy
from fall_predictor.robot.policy_config import PolicyConfigError, read_policy_config

FIXTURES = Path(__file__).resolve().parent / 'fixtures' / 'policies'
SHIPPED = (Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles' / 'g1_12dof'
           / 'controllers' / 'unitree_rl_gym' / 'policy.yaml')
REFS = np.load(FIXTURES / 'references.npz')
DEFAULT = np.array([-0.1, 0.0, 0.0, 0.3, -0.2, 0.0] * 2)


@pytest.fixture(scope='module')
def policy() -> LearnedPolicy:
    return LearnedPolicy.from_yaml(SHIPPED)


def sample(k: int, order: np.ndarray, names: tuple[str, ...], extra: int = 0) -> SensorSample:
    """The fixture's k-th sensor reading with the joints in ``order`` (plus ``extra`` arm joints)."""
    q = np.concatenate([REFS['g1s_q'][k][order], np.full(extra, 9.0)])
    dq = np.concatenate([REFS['g1s_dq'][k][order], np.full(extra, 9.0)])
    arms = tuple(f'arm_{j}' for j in range(extra))
    return SensorSample(t=float(REFS['g1s_t'][k]), joint_names=tuple(names[i] for i in order) + arms,
                        q=q, dq=dq, imu_quat_xyzw=REFS['g1s_quat_xyzw'][k], gyro_rad_s=REFS['g1s_gyro'][k],
                        accel_m_s2=np.zeros(3))


def test_what_a_caller_needs(policy):
    assert policy.period_s == pytest.approx(0.02) and policy.physics_dt_s == 0.002
    assert policy.joint_names[0] == 'left_hip_pitch_joint' and len(policy.joint_names) == 12
    assert policy.default_posture['left_knee_joint'] == 0.3
    assert policy.default_posture['right_ankle_pitch_joint'] == -0.2
    np.testing.assert_array_equal(policy.kp, [100, 100, 100, 150, 40, 40] * 2)
    np.testing.assert_array_equal(policy.kd, [2, 2, 2, 4, 2, 2] * 2)
    assert policy.tau_limit is None
    assert 'unitree_rl_gym observation of 47' in policy.describe() and '50 Hz' in policy.describe()


def test_sensors_to_targets_equal_torch_over_60_steps(policy):
    """Joints in a shuffled order with arm joints the policy ignores, matched by name; the
    observation, the network state and the fed-back last action as Unitree's loop makes them."""
    names = policy.joint_names
    order = np.random.default_rng(2).permutation(12)
    policy.reset(start_s=0.0)
    targets = np.stack([policy.act(float(REFS['g1s_t'][k]), sample(k, order, names, extra=5),
                                   REFS['g1s_command'][k]) for k in range(len(REFS['g1s_t']))])
    want = REFS['g1s_actions'] * 0.25 + DEFAULT
    np.testing.assert_allclose(targets, want, rtol=0, atol=1e-5)
    np.testing.assert_allclose(policy.last_action, REFS['g1s_actions'][-1], rtol=0, atol=4e-5)


def test_reset_restarts_the_network_the_last_action_and_the_gait_clock(policy):
    order = np.arange(12)
    first = sample(0, order, policy.joint_names)
    command = REFS['g1s_command'][0]
    policy.reset(start_s=0.0)
    fresh = policy.act(0.02, first, command)
    for k in range(1, 10):
        policy.act(float(REFS['g1s_t'][k]), sample(k, order, policy.joint_names), REFS['g1s_command'][k])
    policy.reset(start_s=0.0)
    np.testing.assert_array_equal(policy.act(0.02, first, command), fresh)
    policy.reset(start_s=5.0)                   # the gait clock at 0.02 s again, from another start
    np.testing.assert_array_equal(policy.act(5.02, first, command), fresh)
    policy.reset()                              # no start: the first act starts the clock (phase 0)
    assert np.abs(policy.act(0.02, first, command) - fresh).max() > 1e-3


def test_a_missing_joint_is_named(policy):
    names = policy.joint_names
    order = np.array([k for k in range(12) if names[k] != 'right_knee_joint'])
    reading = sample(0, order, names)
    policy.reset()
    with pytest.raises(ValueError, match=r"policy\.yaml: the sensor sample has no joint 'right_knee_joint'"):
        policy.act(0.0, reading, (0.0, 0.0, 0.0))


def test_clipped_actions_and_a_zero_offset():
    config = dataclasses.replace(read_policy_config(SHIPPED), clip_actions=0.1, action_offset='zero')
    policy = LearnedPolicy(config)
    policy.reset(start_s=0.0)
    order = np.arange(12)
    targets = np.stack([policy.act(float(REFS['g1s_t'][k]), sample(k, order, policy.joint_names),
                                   REFS['g1s_command'][k]) for k in range(5)])
    assert np.abs(targets).max() == pytest.approx(0.1 * 0.25)
    assert np.abs(policy.last_action).max() == pytest.approx(0.1)


def test_a_network_that_does_not_fit_is_refused():
    config = dataclasses.replace(read_policy_config(SHIPPED), frame_stack=2)
    with pytest.raises(PolicyConfigError, match='the network takes 47 inputs, the observation has 94'):
        LearnedPolicy(config)
