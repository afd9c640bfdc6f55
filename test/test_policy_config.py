"""Policy deploy configs: Unitree's and humanoid-gym's settings read as their teams write them,
checked against the network, and every mistake said in words naming the file and the field."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fall_predictor.robot.networks import load_network
from fall_predictor.robot.policy_config import (PolicyConfigError, load_policy_config,
                                                read_policy_config)

FIXTURES = Path(__file__).resolve().parent / 'fixtures' / 'policies'
SHIPPED = (Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles' / 'g1_12dof'
           / 'controllers' / 'unitree_rl_gym')
#: unitree_rl_gym's deploy/deploy_mujoco/configs/g1.yaml, as it is (commit 276801e).
UNITREE_G1_YAML = '''\
# 
policy_path: "{LEGGED_GYM_ROOT_DIR}/deploy/pre_train/g1/motion.pt"
xml_path: "{LEGGED_GYM_ROOT_DIR}/resources/robots/g1_description/scene.xml"

# Total simulation time
simulation_duration: 60.0
# Simulation time step
simulation_dt: 0.002
# Controller update frequency (meets the requirement of simulation_dt * controll_decimation=0.02; 50Hz)
control_decimation: 10

kps: [100, 100, 100, 150, 40, 40, 100, 100, 100, 150, 40, 40]
kds: [2, 2, 2, 4, 2, 2, 2, 2, 2, 4, 2, 2]

default_angles: [-0.1,  0.0,  0.0,  0.3, -0.2, 0.0, 
                  -0.1,  0.0,  0.0,  0.3, -0.2, 0.0]

ang_vel_scale: 0.25
dof_pos_scale: 1.0
dof_vel_scale: 0.05
action_scale: 0.25
cmd_scale: [2.0, 2.0, 0.25]
num_actions: 12
num_obs: 47

cmd_init: [0.5, 0, 0]'''
#: The G1 12-dof model's actuator order (unitree_rl_gym's g1_12dof.xml).
G1_JOINTS = ['left_hip_pitch_joint', 'left_hip_roll_joint', 'left_hip_yaw_joint', 'left_knee_joint',
             'left_ankle_pitch_joint', 'left_ankle_roll_joint', 'right_hip_pitch_joint',
             'right_hip_roll_joint', 'right_hip_yaw_joint', 'right_knee_joint',
             'right_ankle_pitch_joint', 'right_ankle_roll_joint']
JOINTS_LINE = f'\njoint_names: {G1_JOINTS}\n'.replace("'", '')


@pytest.fixture
def g1_dir(tmp_path) -> Path:
    """A folder with Unitree's policy, for YAML files that name it relative to themselves."""
    shutil.copy(SHIPPED / 'motion.pt', tmp_path / 'motion.pt')
    return tmp_path


def write(folder: Path, text: str, name: str = 'policy.yaml') -> Path:
    path = folder / name
    path.write_text(text)
    return path


def test_unitree_g1_yaml_as_it_is_plus_joint_names(g1_dir):
    """Unitree's file loads unchanged except for the one thing this package cannot expand (the
    placeholder, refused in words) and the joint names it adds."""
    as_is = write(g1_dir, UNITREE_G1_YAML + JOINTS_LINE)
    with pytest.raises(PolicyConfigError, match=r'policy\.yaml: policy_path: .*LEGGED_GYM_ROOT_DIR.*'
                                                r'placeholder.*relative to the YAML file'):
        read_policy_config(as_is)
    text = UNITREE_G1_YAML.replace('"{LEGGED_GYM_ROOT_DIR}/deploy/pre_train/g1/motion.pt"', 'motion.pt')
    config = load_policy_config(write(g1_dir, text + JOINTS_LINE))
    assert config.observation_layout == 'unitree_rl_gym'
    assert config.policy_path == g1_dir / 'motion.pt'
    assert (config.physics_dt_s, config.decimation) == (0.002, 10)
    assert config.period_s == pytest.approx(0.02)
    assert config.kp[3] == 150.0 and config.kd[3] == 4.0 and config.default_angles_rad[4] == -0.2
    assert config.action_scale == (0.25,) * 12 and config.command_init == (0.5, 0.0, 0.0)
    assert [(t.name, t.scale) for t in config.observation] == [
        ('base_ang_vel', (0.25,)), ('projected_gravity', (1.0,)), ('command', (2.0, 2.0, 0.25)),
        ('joint_pos', (1.0,)), ('joint_vel', (0.05,)), ('last_action', (1.0,)),
        ('gait_phase_sin_cos', (1.0,))]
    assert config.observation[-1].period_s == 0.8                   # deploy_mujoco.py's
    assert (config.single_obs_size, config.obs_size, config.frame_stack) == (47, 47, 1)
    assert config.clip_observations is None and config.clip_actions is None and config.tau_limit_nm is None


def test_the_shipped_g1_policy_config():
    config = load_policy_config(SHIPPED / 'policy.yaml')
    assert list(config.joint_names) == G1_JOINTS
    assert config.policy_path == SHIPPED / 'motion.pt'
    assert config.obs_size == 47 and config.num_actions == 12
    assert (SHIPPED / 'LICENSE').read_text().startswith('BSD 3-Clause License')


HUMANOID_GYM = '''
policy_path: tiny_mlp.pt
joint_names: [a, b]
dt: 0.001
decimation: 10
frame_stack: 15
num_single_obs: 17
num_observations: 255
obs_scales: {lin_vel: 2.0, ang_vel: 1.0, dof_pos: 1.0, dof_vel: 0.05, quat: 1.0}
cycle_time: 0.64
clip_observations: 18.0
clip_actions: 18.0
action_scale: 0.25
kps: [200, 350]
kds: [10, 10]
tau_limit: 200.0
'''


def test_humanoid_gym_names(tmp_path):
    """humanoid-gym's sim2sim settings under their own names (the XBot-L values, two joints)."""
    shutil.copy(FIXTURES / 'tiny_mlp.pt', tmp_path)
    config = read_policy_config(write(tmp_path, HUMANOID_GYM))
    assert config.observation_layout == 'humanoid_gym'
    assert (config.physics_dt_s, config.decimation, config.frame_stack) == (0.001, 10, 15)
    assert config.period_s == pytest.approx(0.01)
    assert [(t.name, t.scale) for t in config.observation] == [
        ('gait_phase_sin_cos', (1.0,)), ('command', (2.0, 2.0, 1.0)), ('joint_pos', (1.0,)),
        ('joint_vel', (0.05,)), ('last_action', (1.0,)), ('base_ang_vel', (1.0,)),
        ('base_euler_xyz', (1.0,))]
    assert config.observation[0].period_s == 0.64
    assert (config.single_obs_size, config.obs_size) == (2 + 3 + 3 * 2 + 3 + 3, 15 * 17)
    assert (config.clip_observations, config.clip_actions, config.tau_limit_nm) == (18.0, 18.0, (200.0, 200.0))
    assert config.default_angles_rad == (0.0, 0.0) and config.kp == (200.0, 350.0)
    with pytest.raises(PolicyConfigError, match=r'policy\.yaml: policy_path tiny_mlp\.pt: the network '
                                                r'takes 10 inputs, the observation has 255'):
        config.check_network(load_network(FIXTURES / 'tiny_mlp.pt'))


EXPLICIT = '''
policy_path: tiny_mlp.pt
joint_names: [j1, j2, j3, j4]
simulation_dt: 0.005
control_decimation: 4
kps: 50
kds: [1, 1, 2, 2]
default_angles: {j1: 0.1, j2: 0.2, j3: 0.3, j4: 0.4}
action_scale: [0.5, 0.5, 0.25, 0.25]
action_offset: zero
observation:
  - joint_pos: {scale: 2.0, relative_to_default: false}
  - joint_vel: [0.1, 0.1, 0.2, 0.2]
  - gait_phase_sin_cos: {period_s: 0.5}
'''


def test_an_explicit_observation_list(tmp_path):
    shutil.copy(FIXTURES / 'tiny_mlp.pt', tmp_path)
    config = load_policy_config(write(tmp_path, EXPLICIT))
    assert config.observation_layout == 'custom' and config.action_offset == 'zero'
    assert config.kp == (50.0,) * 4 and config.default_angles_rad == (0.1, 0.2, 0.3, 0.4)
    pos, vel, phase = config.observation
    assert (pos.scale, pos.relative_to_default) == ((2.0,), False)
    assert vel.scale == (0.1, 0.1, 0.2, 0.2) and phase.period_s == 0.5
    assert config.obs_size == 10 and config.period_s == pytest.approx(0.02)


@pytest.mark.parametrize('edit, field, words', [
    (lambda t: t.replace('joint_names: [j1, j2, j3, j4]', ''), 'joint_names', 'missing'),
    (lambda t: t.replace('kds: [1, 1, 2, 2]', 'kds: [1, 1, 2]'), 'kds', 'list of 4 numbers'),
    (lambda t: t + 'kp_gain: 3\n', 'kp_gain', 'unknown field'),
    (lambda t: t + 'kp: 3\n', 'kp', 'disagrees with kps 50'),       # a maker's name of kps
    (lambda t: t + 'num_actions: 5\n', 'num_actions', "joint_names names 4 joints"),
    (lambda t: t.replace('tiny_mlp.pt', 'nowhere.pt'), 'policy_path', "'nowhere.pt' is not a file"),
    (lambda t: t + 'decimation: 5\n', 'control_decimation', 'disagrees with decimation 5'),
    (lambda t: t + 'ang_vel_scale: 0.25\n', 'ang_vel_scale', 'not used by the observation layout custom'),
    (lambda t: t.replace('period_s: 0.5', 'scale: 1.0'), 'observation[2]', 'needs a period'),
    (lambda t: t.replace('- joint_vel:', '- joint_speed:'), 'observation[1]', "unknown term 'joint_speed'"),
    (lambda t: t + 'observation_layout: unitree_rl_gym\n', 'observation', 'not both'),
    (lambda t: t.replace('action_offset: zero', 'action_offset: default'), 'action_offset', 'one of'),
    (lambda t: t.replace('j4: 0.4', 'j5: 0.4'), 'default_angles', "missing ['j4'], extra ['j5']"),
    (lambda t: t.replace('simulation_dt: 0.005', 'simulation_dt: -1'), 'simulation_dt', 'number > 0'),
    (lambda t: t + 'clip_actions: 0\n', 'clip_actions', 'number > 0'),
    (lambda t: t + 'num_obs: 12\n', 'num_obs', 'makes 10 values per frame'),
    (lambda t: t + 'num_observations: 11\n', 'num_observations', 'x frame_stack 1 make 10'),
    (lambda t: t + 'frame_stack: 0\n', 'frame_stack', 'integer >= 1'),
])
def test_mistakes_are_said_naming_the_file_and_field(tmp_path, edit, field, words):
    shutil.copy(FIXTURES / 'tiny_mlp.pt', tmp_path)
    path = write(tmp_path, edit(EXPLICIT), 'team.yaml')
    with pytest.raises(PolicyConfigError) as caught:
        load_policy_config(path)
    message = str(caught.value)
    assert message.startswith(f'{path}: {field}'), message
    assert words in message, message


def test_mismatches_with_the_network_are_said(tmp_path):
    shutil.copy(FIXTURES / 'tiny_mlp.pt', tmp_path)
    more = EXPLICIT.replace('  - gait_phase_sin_cos', '  - base_ang_vel: 0.25\n  - gait_phase_sin_cos')
    with pytest.raises(PolicyConfigError, match=r'the network takes 10 inputs, the observation has 13 '
                                                r'\(13 per frame x frame_stack 1: joint_pos 4, joint_vel 4, '
                                                r'base_ang_vel 3, gait_phase_sin_cos 2\)'):
        load_policy_config(write(tmp_path, more))
    two = '''
policy_path: tiny_mlp.pt
joint_names: [j1, j2]
simulation_dt: 0.005
control_decimation: 4
kps: 50
kds: 1
action_scale: 0.5
observation: [base_ang_vel: 1, command: 1, joint_pos: 1, gait_phase_sin_cos: {period_s: 1.0}]
'''
    with pytest.raises(PolicyConfigError, match=r'the network gives 4 actions for 2 joint_names'):
        load_policy_config(write(tmp_path, two))
    assert read_policy_config(tmp_path / 'policy.yaml').obs_size == 10     # without the network: fine


def test_unreadable_files_are_said(tmp_path):
    with pytest.raises(PolicyConfigError, match='no such policy config file'):
        read_policy_config(tmp_path / 'missing.yaml')
    with pytest.raises(PolicyConfigError, match='not valid YAML'):
        read_policy_config(write(tmp_path, 'kps: [1, 2\n'))
    with pytest.raises(PolicyConfigError, match='must be a mapping'):
        read_policy_config(write(tmp_path, '- 1\n- 2\n'))
    with pytest.raises(PolicyConfigError, match=r'observation_layout: missing: name one of'):
        read_policy_config(write(tmp_path, 'policy_path: x.pt\njoint_names: [a]\n'))
