"""Domain randomisation (sim/randomization.py): the draws, and in both engines the masses the feet
carry and the torques the drives give."""
import math

import numpy as np
import pytest

from fall_predictor.profiles.profile import load_profile
from fall_predictor.robot.control import JointCommand, make_controller
from fall_predictor.sim.randomization import RandomizationRanges, WorldRandomization, randomization_rng
from fall_predictor.sim.sensors import SensorParams
from fall_predictor.sim.world import make_world

ROBOT = 'g1_12dof'
WORLD = WorldRandomization(friction=0.3, added_base_mass_kg=2.0, link_mass_scale=1.1, motor_strength=0.9,
                           kp_scale=1.2, kd_scale=0.8, latency_s=0.012, imu_tilt_bias_deg=1.0)


def test_each_run_draws_its_world_within_the_training_ranges_from_its_own_stream():
    ranges = RandomizationRanges()
    draws = [WorldRandomization.sample(ranges, randomization_rng(3, i)) for i in range(200)]
    assert draws[7] == WorldRandomization.sample(ranges, randomization_rng(3, 7))
    for name, (low, high) in ranges.to_dict().items():
        values = [getattr(d, name) for d in draws]
        assert low <= min(values) and max(values) <= high and max(values) - min(values) > 0.8 * (high - low)
    params = WORLD.sensor_params(SensorParams())
    assert params.imu.latency_s == params.encoders.latency_s == 0.012
    assert params.imu.tilt_bias_rad == pytest.approx(math.radians(1.0))
    assert WORLD.drive_scales() == pytest.approx((1.08, 0.72, 0.9))


def _standing(simulator, randomization):
    profile = load_profile(ROBOT)
    controller = make_controller(profile)
    world = make_world(profile, simulator, 0.002)
    world.set_randomization(randomization)
    world.start(controller.initial_posture())
    return profile, controller, world


def _mean_foot_load_n(simulator, randomization):
    """The feet's mean load [N] over 2-4 s of the policy stepping in place (its momentum's change
    averages out: the load is the weight)."""
    from fall_predictor.sim.policy_runs import load_learned_policy, policy_run
    from fall_predictor.sim.trajectory import run_trajectory
    profile = load_profile(ROBOT)
    policy = profile.controller_profile()
    learned = load_learned_policy(policy)
    world = make_world(profile, simulator, learned.physics_dt_s)
    params = None if randomization is None else randomization.sensor_params(SensorParams())
    result = run_trajectory(None, 4.0, randomization=randomization,
                            **policy_run(profile, policy, learned, (0.0, 0.0, 0.0), 1.0, 0, world, params))
    world.close()
    assert not result.fallen
    return np.mean([m.left_contacts[:, 2].sum() + m.right_contacts[:, 2].sum()
                    for m in result.measurements if m.t >= 2.0])


@pytest.mark.parametrize('simulator', ['mujoco', 'pybullet'])
def test_the_feet_carry_the_randomised_mass(simulator):
    nominal_kg = load_profile(ROBOT).total_mass_kg
    assert _mean_foot_load_n(simulator, WORLD) == pytest.approx((nominal_kg * 1.1 + 2.0) * 9.80665, rel=0.03)
    # The nominal world carries the nominal mass.
    assert _mean_foot_load_n(simulator, None) == pytest.approx(nominal_kg * 9.80665, rel=0.03)


@pytest.mark.parametrize('simulator', ['mujoco', 'pybullet'])
def test_the_drives_gains_and_strength_are_the_randomised_ones(simulator):
    profile, controller, world = _standing(simulator, WORLD)
    names = world.joint_names
    q0, dq0, _ = world.joint_states()
    targets = q0 + 0.01
    kp, kd = np.full(len(names), 50.0), np.full(len(names), 2.0)
    world.apply(JointCommand(names, targets, kp, kd, np.full(len(names), 1000.0)))
    world.step()
    _, _, tau = world.joint_states()
    # The step's torque, from the state it started at: 0.9 x (1.2 kp e - 0.8 kd dq).
    assert tau == pytest.approx(0.9 * (1.2 * kp * (targets - q0) - 0.8 * kd * dq0), rel=1e-9, abs=1e-9)
    world.close()
