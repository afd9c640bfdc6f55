"""The policy observation: attitude terms against rotations built independently, Unitree's and
humanoid-gym's frames term by term, frame stacking order and clipping."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fall_predictor.monitor.rotations import from_matrix
from fall_predictor.robot.observations import ObservationBuilder, euler_xyz, projected_gravity
from fall_predictor.robot.policy_config import ObservationTerm, PolicyConfig, read_policy_config

SHIPPED = (Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles' / 'g1_12dof'
           / 'controllers' / 'unitree_rl_gym' / 'policy.yaml')


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_projected_gravity_of_known_tilts():
    assert projected_gravity((0.0, 0.0, 0.0, 1.0)) == pytest.approx((0.0, 0.0, -1.0))
    # Pitched 30 deg nose down (about +y): gravity leans toward the body's +x.
    s = math.sin(math.radians(15))
    assert projected_gravity((0.0, s, 0.0, math.cos(math.radians(15)))) == pytest.approx(
        (math.sin(math.radians(30)), 0.0, -math.cos(math.radians(30))))
    # Rolled 90 deg about +x (left side up): the body's -y axis points down.
    h = math.sqrt(0.5)
    assert projected_gravity((h, 0.0, 0.0, h)) == pytest.approx((0.0, -1.0, 0.0))
    # Yaw alone changes nothing.
    assert projected_gravity((0.0, 0.0, math.sin(1.0), math.cos(1.0))) == pytest.approx((0.0, 0.0, -1.0))


def test_attitude_terms_against_independent_rotations():
    """R = Rz(yaw) Ry(pitch) Rx(roll) from matrices; its quaternion by the monitor's (Shepperd)
    conversion: gravity = R^T (0, 0, -1), Euler angles back, and Unitree's w-first formula."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        roll, yaw = rng.uniform(-3.0, 3.0, 2)
        pitch = rng.uniform(-1.5, 1.5)
        matrix = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
        quat = from_matrix(matrix)
        np.testing.assert_allclose(projected_gravity(quat), matrix.T @ [0.0, 0.0, -1.0], atol=1e-12)
        np.testing.assert_allclose(euler_xyz(quat), (roll, pitch, yaw), atol=1e-9)
        x, y, z, w = quat            # deploy_mujoco.py's get_gravity_orientation, w first
        unitree = (2 * (-z * x + w * y), -2 * (z * y + w * x), 1 - 2 * (w * w + z * z))
        np.testing.assert_allclose(projected_gravity(quat), unitree, atol=1e-12)


def test_unitree_g1_frame_term_by_term():
    config = read_policy_config(SHIPPED)
    builder = ObservationBuilder(config)
    default = np.array(config.default_angles_rad)
    rng = np.random.default_rng(5)
    q, dq, last = default + rng.normal(0, 0.1, 12), rng.normal(0, 2, 12), rng.normal(0, 1, 12)
    gyro, command = np.array([0.3, -0.2, 0.5]), (0.5, -0.1, 0.3)
    pitch = math.radians(10)
    quat = (0.0, math.sin(pitch / 2), 0.0, math.cos(pitch / 2))
    t = 0.5
    obs = builder.build(t, quat, gyro, q, dq, command, last)
    assert obs.dtype == np.float32 and obs.shape == (47,)
    want = np.concatenate([gyro * 0.25, [math.sin(pitch), 0.0, -math.cos(pitch)],
                           np.array(command) * [2.0, 2.0, 0.25], q - default, dq * 0.05, last,
                           [math.sin(2 * math.pi * t / 0.8), math.cos(2 * math.pi * t / 0.8)]])
    np.testing.assert_allclose(obs, want, rtol=1e-6, atol=1e-6)
    # An unnormalised quaternion means the same attitude.
    np.testing.assert_allclose(builder.build(t, np.array(quat) * 3.0, gyro, q, dq, command, last), obs)


def _config(terms, n=2, **kw) -> PolicyConfig:
    return PolicyConfig(source=Path('test.yaml'), policy_path=Path('net.pt'),
                        joint_names=tuple(f'j{k}' for k in range(n)), physics_dt_s=0.001, decimation=10,
                        kp=(1.0,) * n, kd=(0.1,) * n, default_angles_rad=(0.5,) * n,
                        action_scale=(0.25,) * n, observation=tuple(terms), **kw)


def test_humanoid_gym_frame_order_and_euler_angles():
    terms = (ObservationTerm('gait_phase_sin_cos', period_s=0.64), ObservationTerm('command', (2.0, 2.0, 1.0)),
             ObservationTerm('joint_pos'), ObservationTerm('joint_vel', (0.05,)), ObservationTerm('last_action'),
             ObservationTerm('base_ang_vel'), ObservationTerm('base_euler_xyz'))
    builder = ObservationBuilder(_config(terms))
    roll, pitch, yaw = 0.1, -0.2, 2.5
    quat = from_matrix(rot_z(yaw) @ rot_y(pitch) @ rot_x(roll))
    obs = builder.build(0.16, quat, (1.0, 2.0, 3.0), np.array([0.7, 0.4]), np.array([10.0, -20.0]),
                        (0.4, 0.1, -0.2), np.array([0.3, -0.3]))
    want = [1.0, 0.0, 0.8, 0.2, -0.2, 0.2, -0.1, 0.5, -1.0, 0.3, -0.3, 1.0, 2.0, 3.0, roll, pitch, yaw]
    np.testing.assert_allclose(obs, want, atol=1e-6)        # sin, cos of a quarter period: 1, 0


def test_frames_are_stacked_oldest_first_after_zeros_and_reset_forgets_them():
    builder = ObservationBuilder(_config([ObservationTerm('joint_vel')], frame_stack=3))
    args = ((0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0), np.zeros(2))

    def frame(k: float) -> np.ndarray:
        return builder.build(0.0, args[0], args[1], args[2], np.array([k, -k]), (0, 0, 0), np.zeros(2))

    np.testing.assert_array_equal(frame(1), [0, 0, 0, 0, 1, -1])
    np.testing.assert_array_equal(frame(2), [0, 0, 1, -1, 2, -2])
    np.testing.assert_array_equal(frame(3), [1, -1, 2, -2, 3, -3])
    np.testing.assert_array_equal(frame(4), [2, -2, 3, -3, 4, -4])
    builder.reset()
    np.testing.assert_array_equal(frame(5), [0, 0, 0, 0, 5, -5])
    assert builder.size == 6


def test_clipping_and_absolute_joint_positions():
    terms = [ObservationTerm('joint_pos', (2.0,), relative_to_default=False), ObservationTerm('joint_vel')]
    builder = ObservationBuilder(_config(terms, clip_observations=18.0))
    obs = builder.build(0.0, (0, 0, 0, 1), (0, 0, 0), np.array([0.5, 12.0]), np.array([-30.0, 5.0]),
                        (0, 0, 0), np.zeros(2))
    np.testing.assert_array_equal(obs, [1.0, 18.0, -18.0, 5.0])


def test_wrong_sizes_are_said():
    builder = ObservationBuilder(_config([ObservationTerm('joint_pos'), ObservationTerm('projected_gravity')]))
    with pytest.raises(ValueError, match=r'expected q, dq and last_action of 2 values.*got 3, 2, 2, 3, 4, 3'):
        builder.build(0.0, (0, 0, 0, 1), (0, 0, 0), np.zeros(3), np.zeros(2), (0, 0, 0), np.zeros(2))
    with pytest.raises(ValueError, match='not a rotation'):
        builder.build(0.0, (0, 0, 0, 0), (0, 0, 0), np.zeros(2), np.zeros(2), (0, 0, 0), np.zeros(2))


MAKERS = Path(__file__).resolve().parent / 'fixtures' / 'policies' / 'makers'


def _readings(steps: int, standing: range, seed: int):
    """Per policy step: time [s], the attitude (its matrix and quaternion), gyro, q, dq, command
    (zero over ``standing``), last action."""
    rng = np.random.default_rng(seed)
    for k in range(steps):
        roll, pitch, yaw = rng.uniform(-0.3, 0.3, 3)
        matrix = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
        command = np.zeros(3) if k in standing else rng.uniform(-0.5, 0.5, 3)
        yield (0.02 * k, matrix, (roll, pitch, yaw), from_matrix(matrix), rng.normal(0, 1, 3),
               rng.normal(0, 0.3, 12), rng.normal(0, 60, 12), command, rng.normal(0, 2, 12))


def test_a_booster_style_nested_config_with_a_cos_sin_clock_term_by_term():
    """common: / policy: sections and the maker's names; the observation as its deploy script
    makes it: gravity, gyro, command, (cos, sin) of the phase (zero, the phase held, while told
    to stand), q - default, dq x 0.1, last action; computed here from the formulas."""
    config = read_policy_config(MAKERS / 'booster_style_t1.yaml')
    assert config.kp[:6] == (200.0, 200.0, 200.0, 200.0, 50.0, 50.0) and config.clip_actions == 1.0
    assert config.default_angles_rad[3] == 0.4 and config.tau_limit_nm[5] == 15.0
    assert (config.physics_dt_s, config.decimation, config.obs_size) == (0.002, 10, 47)
    builder = ObservationBuilder(config)
    default = np.array(config.default_angles_rad)
    walked_s = 0.0                      # the clock's own time: it stops while standing
    for k, (t, matrix, _, quat, gyro, q, dq, command, last) in enumerate(
            _readings(40, range(12, 25), seed=11)):
        obs = builder.build(t, quat, gyro, q, dq, command, last)
        standing = not np.any(command)
        if k and not standing:
            walked_s += 0.02
        phase = 2 * math.pi * 1.5 * walked_s
        clock = [0.0, 0.0] if standing else [math.cos(phase), math.sin(phase)]
        want = np.concatenate([matrix.T @ [0.0, 0.0, -1.0], gyro, command, clock, q - default,
                               dq * 0.1, last])
        np.testing.assert_allclose(obs, want, rtol=1e-6, atol=1e-6, err_msg=f'step {k}')
    # Standing to walking: the clock goes on from where it stopped, not from the wall clock.
    assert walked_s == pytest.approx(0.02 * (40 - 1 - 13))


def test_a_legged_gym_style_config_with_sections_parts_of_names_and_a_restarting_clock():
    """Gains by part of the joint name, default angles by joint, a field under the team's name,
    three stacked frames; a (sin, cos) clock a quarter cycle ahead that restarts at 0 while the
    command is below 0.05; per-term clips; computed here from the formulas."""
    config = read_policy_config(MAKERS / 'legged_gym_style.yaml')
    assert config.kp == (150.0, 150.0, 100.0, 200.0, 40.0, 40.0) * 2
    assert config.kd == (4.0, 4.0, 4.0, 5.0, 2.0, 2.0) * 2
    assert config.policy_path.name == 'tiny_mlp.pt' and config.single_obs_size == 47
    assert (config.frame_stack, config.period_s, config.clip_observations) == (3, 0.02, 18.0)
    builder = ObservationBuilder(config)
    default = np.array(config.default_angles_rad)
    frames, walked_s = [np.zeros(47)] * 3, 0.0
    for k, (t, _, euler, quat, gyro, q, dq, command, last) in enumerate(
            _readings(30, range(8, 15), seed=12)):
        command = command * (0.05 if k == 20 else 1.0)          # a small command walks on
        obs = builder.build(t, quat, gyro, q, dq, command, last)
        standing = np.linalg.norm(command) <= 0.05
        walked_s = 0.0 if standing else walked_s + (0.02 if k else 0.0)
        phase = 2 * math.pi * ((walked_s / 0.7 + 0.25) % 1.0)
        frame = np.concatenate([[math.sin(phase), math.cos(phase)], command * [2.0, 2.0, 0.25],
                                q - default, np.clip(dq * 0.05, -5, 5), np.clip(last, -3, 3),
                                gyro * 0.25, euler])
        frames = frames[1:] + [np.clip(frame, -18, 18)]
        np.testing.assert_allclose(obs, np.concatenate(frames), rtol=1e-6, atol=1e-6,
                                   err_msg=f'step {k}')
    builder.reset()                                               # a new run: the clock restarts
    obs = builder.build(5.0, (0.0, 0.0, 0.0, 1.0), np.zeros(3), default, np.zeros(12), (0.3, 0, 0),
                        np.zeros(12))
    assert obs[-47:-45] == pytest.approx([1.0, 0.0], abs=1e-7)   # a quarter cycle: sin 1, cos 0
