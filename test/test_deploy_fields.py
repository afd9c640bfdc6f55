"""A team's deploy config in its own shape (robot/deploy_fields.py): sections, its own field names,
per-joint mappings; every mistake said naming the file and the field as the team wrote it."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fall_predictor.robot.deploy_fields import PolicyConfigError, flatten, per_joint
from fall_predictor.robot.policy_config import load_policy_config, read_policy_config

FIXTURES = Path(__file__).resolve().parent / 'fixtures' / 'policies'
MAKERS = FIXTURES / 'makers'


def test_sections_open_and_synonyms_map_saying_where_each_field_was():
    flat, where = flatten('f.yaml', {'common': {'dt': 0.002, 'stiffness': [1, 2]},
                                     'policy': {'control': {'decimation': 4}, 'obs_scales': {'a': 1}},
                                     'field_names': {'policy.net': 'policy_path'},
                                     'default_qpos': {'j1': 0.1}})
    assert flat == {'dt': 0.002, 'kps': [1, 2], 'decimation': 4, 'obs_scales': {'a': 1},
                    'field_names': {'policy.net': 'policy_path'}, 'default_angles': {'j1': 0.1}}
    assert where['kps'] == 'common.stiffness' and where['decimation'] == 'policy.control.decimation'
    flat, where = flatten('f.yaml', {'policy': {'net': 'a.pt'}, 'field_names': {'policy.net': 'policy_path'}})
    assert flat['policy_path'] == 'a.pt' and where['policy_path'] == 'policy.net'


def test_the_same_field_twice_must_agree():
    with pytest.raises(PolicyConfigError, match=r'f\.yaml: policy\.kp: 3 disagrees with common\.kps '
                                                r'\[1, 2\] \(both give kps\)'):
        flatten('f.yaml', {'common': {'kps': [1, 2]}, 'policy': {'kp': 3}})
    flat, _ = flatten('f.yaml', {'common': {'dt': 0.002}, 'policy': {'dt': 0.002}})
    assert flat == {'dt': 0.002}


def test_per_joint_mappings_by_name_or_part_of_it():
    joints = ('left_hip_yaw', 'left_knee', 'right_hip_yaw', 'right_knee')
    assert per_joint({'hip_yaw': 100, 'knee': 150}, joints) == ([100, 150, 100, 150], [], [])
    assert per_joint({'hip': 1, 'left_knee': 2, 'knee': 3}, joints) == ([1, 2, 1, 3], [], [])
    # A joint two keys give different values, a joint no key gives, a key no joint has.
    values, bad, extra = per_joint({'left': 1, 'knee': 2, 'arm': 3}, joints)
    assert bad == ['left_knee', 'right_hip_yaw'] and extra == ['arm']


@pytest.mark.parametrize('edit, field, words', [
    (lambda t: t.replace('  stiffness: [200, 200, 200, 200, 50, 50, 200, 200, 200, 200, 50, 50]',
                         '  stiffness: [200, 200]'), 'common.stiffness', 'list of 12 numbers'),
    (lambda t: t.replace('    decimation: 10', '    decimation: ten'), 'policy.control.decimation',
     'integer >= 1'),
    (lambda t: t.replace('  gait_frequency: 1.5', '  gait_frequency: 1.5\n  walk_height: 0.6'),
     'policy.walk_height', 'unknown field'),
    (lambda t: t.replace('{order: cos_sin,', '{order: cos_tan,'), 'observation[3].order', 'cos_sin'),
    (lambda t: t.replace('when_standing: zero', 'when_standing: stop'), 'observation[3].when_standing',
     "one of ('run', 'zero', 'hold', 'reset')"),
    (lambda t: t.replace('- commands: 1.0', '- commands: {scale: 1.0, clip: -1}'),
     'observation[2].clip', 'number > 0'),
    (lambda t: t.replace('- commands: 1.0', '- velocity: 1.0'), 'observation[2]', "unknown term 'velocity'"),
    (lambda t: t.replace('frequency_hz: policy.gait_frequency', 'frequency_hz: policy.gait_frequency, '
                                                                 'period_s: 0.6'),
     'observation[3]', 'period_s or frequency_hz, not both'),
    (lambda t: t.replace('- dof_vel: policy.normalization.dof_vel', '- dof_vel: policy.normalization.dof_v'),
     'observation[5].scale', "'policy.normalization.dof_v' names no number of the file"),
    (lambda t: t.replace('  gait_frequency: 1.5', '  gait_frequency: fast'), 'observation[3].frequency_hz',
     "'policy.gait_frequency' names no number"),
    (lambda t: t.replace('  num_observations: 47', '  num_observations: 45'), 'policy.num_observations',
     'make 47'),
])
def test_mistakes_in_a_nested_config_name_the_field_as_the_team_wrote_it(tmp_path, edit, field, words):
    shutil.copy(FIXTURES / 'tiny_mlp.pt', tmp_path)
    (tmp_path / 'makers').mkdir()
    path = tmp_path / 'makers' / 't1.yaml'
    path.write_text(edit((MAKERS / 'booster_style_t1.yaml').read_text()))
    with pytest.raises(PolicyConfigError) as caught:
        read_policy_config(path)
    message = str(caught.value)
    assert message.startswith(f'{path}: {field}'), message
    assert words in message and '\n' not in message, message


def test_an_unknown_field_says_how_to_map_or_ignore_it(tmp_path):
    shutil.copy(FIXTURES / 'tiny_mlp.pt', tmp_path)
    (tmp_path / 'makers').mkdir()
    path = tmp_path / 'makers' / 't1.yaml'
    path.write_text((MAKERS / 'booster_style_t1.yaml').read_text().replace(
        '  gait_frequency: 1.5', '  gait_frequency: 1.5\n  walk_height: 0.6'))
    with pytest.raises(PolicyConfigError) as caught:
        read_policy_config(path)
    assert ('field_names: {policy.walk_height: KNOWN}' in str(caught.value)
            and 'ignored_fields: [policy.walk_height]' in str(caught.value))


def test_a_config_of_another_layout_is_told_how_to_describe_it_in_one_line(tmp_path):
    shutil.copy(FIXTURES / 'tiny_mlp.pt', tmp_path)
    text = (MAKERS / 'booster_style_t1.yaml').read_text().replace('../tiny_mlp.pt', 'tiny_mlp.pt')
    path = tmp_path / 't1.yaml'
    path.write_text(text[:text.index('observation:')].replace(
        'ignored_fields: [policy.normalization.lin_vel]', 'ignored_fields: [policy.normalization, '
        'policy.gait_frequency]'))
    with pytest.raises(PolicyConfigError) as caught:
        read_policy_config(path)
    message = str(caught.value)
    assert message.startswith(f'{path}: observation_layout: missing: name one of')
    assert 'describe the network\'s input as an observation: list of terms' in message
    assert 'docs/method.md §13' in message and '\n' not in message


def test_a_nested_config_is_checked_against_its_network(tmp_path):
    """The fixture's 47 inputs against a network of 10: said, with the terms."""
    shutil.copy(FIXTURES / 'tiny_mlp.pt', tmp_path)
    (tmp_path / 'makers').mkdir()
    path = tmp_path / 'makers' / 't1.yaml'
    shutil.copy(MAKERS / 'booster_style_t1.yaml', path)
    with pytest.raises(PolicyConfigError, match=r'the network takes 10 inputs, the observation has 47 '
                                                r'\(47 per frame x frame_stack 1: projected_gravity 3, '
                                                r'base_ang_vel 3, command 3, gait_clock 2'):
        load_policy_config(path)


def test_lists_in_the_motors_order_and_an_observation_as_a_mapping(tmp_path):
    """Unitree's IsaacLab-trained configs list the policy's joints (lab_joint) apart from the
    motors' (motor_joint), the gains and angles in the motors' order; the observation may be a
    mapping of terms, in the file's order."""
    shutil.copy(FIXTURES / 'tiny_mlp.pt', tmp_path)
    path = tmp_path / 'nav.yaml'
    path.write_text('''
policy_path: tiny_mlp.pt
lab_joint: [left_hip, right_hip, left_knee, right_knee]
motor_joint: [left_hip, left_knee, right_hip, right_knee, waist]
simulation_dt: 0.002
control_decimation: 10
kps: [100, 150, 101, 151, 300]
kds: [2, 4, 3, 5, 6]
default_angles: [-0.2, 0.42, -0.21, 0.43, 0.0]
action_scale: 0.25
observation:
  gravity: 1.0
  dof_pos: 1.0
''')
    config = read_policy_config(path)
    assert config.joint_names == ('left_hip', 'right_hip', 'left_knee', 'right_knee')
    assert config.kp == (100.0, 101.0, 150.0, 151.0) and config.kd == (2.0, 3.0, 4.0, 5.0)
    assert config.default_angles_rad == (-0.2, -0.21, 0.42, 0.43)
    assert [t.name for t in config.observation] == ['projected_gravity', 'joint_pos']
    path.write_text(path.read_text().replace('kds: [2, 4, 3, 5, 6]', 'kds: [2, 4, 3, 5]'))
    with pytest.raises(PolicyConfigError, match=r'nav\.yaml: kds: must be a list of 5 numbers, one per '
                                                r'motor_joint_names entry'):
        read_policy_config(path)


def test_the_shipped_g1_policy_rewritten_nested_with_a_gait_clock_gives_the_same_targets(tmp_path):
    """Unitree's G1 config written as another maker would (sections, its names, gains per part of
    the joint name, an explicit observation with a gait_clock): the same joint targets over
    Unitree's 60 reference steps as the shipped unitree_rl_gym layout (to float rounding: the
    clock's phase is computed as a fraction first)."""
    import numpy as np

    from fall_predictor.monitor.sensor_records import SensorSample
    from fall_predictor.robot.learned_policy import LearnedPolicy
    shipped = (Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles' / 'g1_12dof'
               / 'controllers' / 'unitree_rl_gym')
    shutil.copy(shipped / 'motion.pt', tmp_path)
    joints = read_policy_config(shipped / 'policy.yaml').joint_names
    (tmp_path / 'nested.yaml').write_text(f'''
common:
  sim_dt: 0.002
  stiffness: {{hip: 100, knee: 150, ankle: 40}}
  damping: {{hip: 2, knee: 4, ankle: 2}}
  default_dof_pos: {{hip_pitch: -0.1, hip_roll: 0.0, hip_yaw: 0.0, knee: 0.3, ankle_pitch: -0.2,
                    ankle_roll: 0.0}}
policy:
  model_path: motion.pt
  control: {{decimation: 10, action_scale: 0.25}}
  scales: {{ang_vel: 0.25, dof_vel: 0.05}}
dof_names: [{", ".join(joints)}]
observation:
  ang_vel: policy.scales.ang_vel
  gravity: 1.0
  commands: [2.0, 2.0, 0.25]
  dof_pos: 1.0
  dof_vel: policy.scales.dof_vel
  actions: 1.0
  clock: {{order: sin_cos, period_s: 0.8}}
''')
    refs = np.load(FIXTURES / 'references.npz')
    targets = {}
    for name, path in (('shipped', shipped / 'policy.yaml'), ('nested', tmp_path / 'nested.yaml')):
        policy = LearnedPolicy.from_yaml(path)
        policy.reset(start_s=0.0)
        targets[name] = np.stack([policy.act(float(t), SensorSample(
            t=float(t), joint_names=joints, q=refs['g1s_q'][k], dq=refs['g1s_dq'][k],
            imu_quat_xyzw=refs['g1s_quat_xyzw'][k], gyro_rad_s=refs['g1s_gyro'][k],
            accel_m_s2=np.zeros(3)), refs['g1s_command'][k]) for k, t in enumerate(refs['g1s_t'])])
    np.testing.assert_allclose(targets['nested'], targets['shipped'], rtol=0, atol=1e-6)
