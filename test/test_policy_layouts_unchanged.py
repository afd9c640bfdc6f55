"""The three observation layouts the package knew before the deploy-config schema (unitree_rl_gym,
humanoid_gym, an explicit list) give bit-for-bit what they gave: ``layouts_before_schema.npz``
holds the shipped G1 policy's joint targets over Unitree's 60 reference steps, and the observation
frames of ``humanoid_gym_layout.yaml`` and ``explicit_layout.yaml`` over 25 fixed readings, all
recorded with the code of commit 4adf78c (before the schema)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fall_predictor.monitor.sensor_records import SensorSample
from fall_predictor.robot.learned_policy import LearnedPolicy
from fall_predictor.robot.observations import ObservationBuilder
from fall_predictor.robot.policy_config import read_policy_config

FIXTURES = Path(__file__).resolve().parent / 'fixtures' / 'policies'
SHIPPED = (Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles' / 'g1_12dof'
           / 'controllers' / 'unitree_rl_gym' / 'policy.yaml')
BEFORE = np.load(FIXTURES / 'layouts_before_schema.npz')
REFS = np.load(FIXTURES / 'references.npz')


def test_the_shipped_g1_policy_gives_the_same_targets_bit_for_bit():
    policy = LearnedPolicy.from_yaml(SHIPPED)
    names = policy.joint_names
    order = np.random.default_rng(2).permutation(12)
    policy.reset(start_s=0.0)
    targets = []
    for k in range(len(REFS['g1s_t'])):
        sample = SensorSample(t=float(REFS['g1s_t'][k]), joint_names=tuple(names[i] for i in order),
                              q=REFS['g1s_q'][k][order], dq=REFS['g1s_dq'][k][order],
                              imu_quat_xyzw=REFS['g1s_quat_xyzw'][k], gyro_rad_s=REFS['g1s_gyro'][k],
                              accel_m_s2=np.zeros(3))
        targets.append(policy.act(float(REFS['g1s_t'][k]), sample, REFS['g1s_command'][k]))
    np.testing.assert_array_equal(np.stack(targets), BEFORE['g1_targets'])


def test_humanoid_gym_and_explicit_layouts_give_the_same_frames_bit_for_bit():
    inputs = {k[3:]: BEFORE[k] for k in BEFORE.files if k.startswith('in_')}
    for name in ('humanoid_gym_layout', 'explicit_layout'):
        builder = ObservationBuilder(read_policy_config(FIXTURES / f'{name}.yaml'))
        frames = [builder.build(inputs['t'][k], inputs['quat'][k], inputs['gyro'][k], inputs['q'][k],
                                inputs['dq'][k], inputs['command'][k], inputs['action'][k])
                  for k in range(len(inputs['t']))]
        np.testing.assert_array_equal(np.stack(frames), BEFORE[name], err_msg=name)
