"""Mistakes a robotics team makes in its own files, each made by mutating a copy of a shipped
profile folder, with the command that meets it and what its one line must name.

Used by ``test_team_mistakes.py``. Run as a script (``python test/team_mistakes.py``) it runs
every mistake as a subprocess of the command line and counts the outcomes: a clear line (exit 2,
one line on stderr naming the file and the field), a traceback, or a run that ends without a word
(exit 0, nothing on stderr), or anything else.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

import numpy as np
import yaml

PROFILES = Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles'
POLICY = 'controllers/unitree_rl_gym/policy.yaml'
NETWORK = 'controllers/unitree_rl_gym/motion.pt'
G1_12_URDF, G1_12_MJCF = 'g1_12dof.urdf', 'g1_12dof.xml'


@dataclass(frozen=True)
class Mistake:
    """One mistake: the shipped profile it starts from, how the copy is changed, the command
    (``{robot}``: the copy's profile file, ``{dir}``: its folder, ``{out}``: a scratch folder),
    the file its line must name and the field (any of several, '|'-separated)."""

    name: str
    base: str
    mutate: Callable[[Path], None]
    argv: tuple[str, ...]
    file: str
    field: str
    #: The exit code wanted (2: a mistake in a team's file; 1: ``check`` found a failing check,
    #: or ``import-bags`` imported nothing; 0: a run that only a simulation shows wrong, warned).
    exit_code: int = 2
    slow: bool = False

    @property
    def is_check(self) -> bool:
        """A ``check`` command: its answer is the table on stdout (exit 1 on a failure)."""
        return self.argv[0] == 'check'

    def make(self, root: Path) -> tuple[Path, list[str]]:
        folder = root / self.base
        shutil.copytree(PROFILES / self.base, folder)
        out = root / 'out'
        out.mkdir(exist_ok=True)
        self.mutate(folder)
        profile = folder / 'profile.yaml'
        return profile, [a.format(robot=profile, dir=folder, out=out) for a in self.argv]


# -- mutations -------------------------------------------------------------------------------

def edit_yaml(rel: str, change: Callable[[dict], None]) -> Callable[[Path], None]:
    def apply(folder: Path) -> None:
        path = folder / rel
        data = yaml.safe_load(path.read_text())
        change(data)
        path.write_text(yaml.safe_dump(data, sort_keys=False))
    return apply


def replace(rel: str, old: str, new: str, count: int = 1) -> Callable[[Path], None]:
    def apply(folder: Path) -> None:
        path = folder / rel
        text = path.read_text()
        assert old in text, (rel, old)
        path.write_text(text.replace(old, new, count))
    return apply


def write(rel: str, content: bytes) -> Callable[[Path], None]:
    def apply(folder: Path) -> None:
        (folder / rel).write_bytes(content)
    return apply


def truncate(rel: str, fraction: float = 0.5) -> Callable[[Path], None]:
    def apply(folder: Path) -> None:
        path = folder / rel
        data = path.read_bytes()
        path.write_bytes(data[:int(len(data) * fraction)])
    return apply


def delete(rel: str) -> Callable[[Path], None]:
    def apply(folder: Path) -> None:
        (folder / rel).unlink()
    return apply


def scale_weights(factor: float) -> Callable[[Path], None]:
    """Every tensor of the TorchScript archive multiplied by ``factor`` (nan: set to NaN)."""
    def apply(folder: Path) -> None:
        path = folder / NETWORK
        with zipfile.ZipFile(path) as source:
            entries = [(info, source.read(info)) for info in source.infolist()]
        with zipfile.ZipFile(path, 'w', zipfile.ZIP_STORED) as target:
            for info, data in entries:
                if '/data/' in info.filename and not info.filename.endswith('.pkl'):
                    values = np.frombuffer(data, np.float32).copy()
                    values[:] = np.nan if np.isnan(factor) else values * np.float32(factor)
                    data = values.tobytes()
                target.writestr(info, data)
    return apply


def both(*changes: Callable[[Path], None]) -> Callable[[Path], None]:
    def apply(folder: Path) -> None:
        for change in changes:
            change(folder)
    return apply


def _swap_policy_sides(d: dict) -> None:
    names = d['joint_names']
    d['joint_names'] = names[6:] + names[:6]


def _degrees(d: dict) -> None:
    d['default_angles'] = [round(float(np.degrees(a)), 2) for a in d['default_angles']]


def _drop_c_bal(d: dict) -> None:
    d.pop('servo_gains')
    d.pop('controller')


def _swap_feet(d: dict) -> None:
    d['feet']['l'], d['feet']['r'] = d['feet']['r'], d['feet']['l']


def _eleven(d: dict) -> None:
    for key in ('joint_names', 'kps', 'kds', 'default_angles'):
        d[key] = d[key][:11]
    d['num_actions'] = 11


def _typo_joint(d: dict) -> None:
    d['joint_names'][3] = 'left_knee_jiont'


SIM = ('simulate', '--robot', '{robot}', '--duration', '1.5')
SIM2 = ('simulate', '--robot', '{robot}', '--duration', '2.5')
GEN = ('generate', '--robot', '{robot}', '--trajectories', '2', '--horizon', '1', '--out', '{out}/ds')
RENDER = ('render', '--robot', '{robot}', '--frames', '2', '--onset', '0.5', '--after', '0.3',
          '--out', '{out}/strip.png')
CHECK = ('check', '--robot', '{robot}', '--static')
NO_CHANGE: Callable[[Path], None] = lambda folder: None

MISTAKES: tuple[Mistake, ...] = (
    # -- the profile ----------------------------------------------------------------------------
    Mistake('profile_not_yaml', 'g1_12dof', replace('profile.yaml', 'name: g1_12dof', 'name: [g1_12dof'),
            SIM, 'profile.yaml', 'YAML'),
    Mistake('profile_misspelt_top_key', 'g1_12dof', replace('profile.yaml', 'simulator: mujoco',
                                                            'simulater: mujoco'),
            SIM, 'profile.yaml', 'simulater'),
    Mistake('profile_misspelt_foot_key', 'g1_12dof',
            edit_yaml('profile.yaml', lambda d: d['feet']['l'].update(sole_rpy_in_foot_rad=[0, 0, 0])),
            SIM, 'profile.yaml', 'sole_rpy_in_foot_rad'),
    Mistake('profile_mass_string', 'g1_12dof', edit_yaml('profile.yaml',
                                                        lambda d: d.update(total_mass_kg='32 kg')),
            SIM, 'profile.yaml', 'total_mass_kg'),
    Mistake('profile_mass_60kg', 'g1_12dof', edit_yaml('profile.yaml', lambda d: d.update(total_mass_kg=60.0)),
            SIM, 'profile.yaml', 'total_mass_kg'),
    Mistake('profile_mass_60kg_generate', 'g1_12dof',
            edit_yaml('profile.yaml', lambda d: d.update(total_mass_kg=60.0)),
            GEN, 'profile.yaml', 'total_mass_kg'),
    Mistake('profile_fallen_above_com', 'g1_12dof', edit_yaml('profile.yaml', lambda d: d['monitor'].update(
        fallen_com_height_m=0.9, guard_com_height_m=0.95)), SIM, 'profile.yaml', 'fallen_com_height_m'),
    Mistake('profile_guard_above_com', 'asimo_like', edit_yaml('profile.yaml', lambda d: d['monitor'].update(
        guard_com_height_m=0.9)), SIM, 'profile.yaml', 'guard_com_height_m'),
    Mistake('profile_unknown_imu', 'g1_12dof', edit_yaml('profile.yaml', lambda d: d.update(imu_frame='imu_link')),
            SIM, 'profile.yaml', 'imu_frame'),
    Mistake('profile_unknown_imu_generate', 'g1_12dof',
            edit_yaml('profile.yaml', lambda d: d.update(imu_frame='imu_link')),
            GEN, 'profile.yaml', 'imu_frame'),
    Mistake('profile_unknown_foot_link', 'g1_12dof',
            edit_yaml('profile.yaml', lambda d: d['feet']['l'].update(foot_link='left_ankle_link')),
            SIM, 'profile.yaml', 'foot_link'),
    Mistake('profile_unknown_ft_frame', 'asimo_like',
            edit_yaml('profile.yaml', lambda d: d['feet']['r'].update(force_torque_frame='r_ft_sensor')),
            SIM, 'profile.yaml', 'force_torque_frame'),
    Mistake('profile_feet_swapped', 'g1_12dof', edit_yaml('profile.yaml', _swap_feet),
            SIM, 'profile.yaml', 'feet'),
    Mistake('profile_joint_group_typo', 'g1_12dof',
            edit_yaml('profile.yaml', lambda d: d['joint_groups']['l_leg'].__setitem__(0, 'left_hip_pich_joint')),
            SIM, 'profile.yaml', 'joint_groups'),
    Mistake('profile_urdf_missing', 'g1_12dof', delete(G1_12_URDF), SIM, 'profile.yaml', 'urdf'),
    Mistake('profile_policy_missing', 'g1_12dof', delete(POLICY), SIM, 'profile.yaml', 'policy'),
    Mistake('profile_c_bal_without_gains', 'g1_12dof', edit_yaml('profile.yaml', _drop_c_bal),
            SIM + ('--controller', 'c_bal'), 'profile.yaml', 'servo_gains'),
    Mistake('profile_sole_length_string', 'asimo_like',
            edit_yaml('profile.yaml', lambda d: d['feet']['l'].update(sole_length_m='0.2')),
            SIM, 'profile.yaml', 'sole_length_m'),
    # -- the URDF ---------------------------------------------------------------------------------
    Mistake('urdf_truncated', 'g1_12dof', truncate(G1_12_URDF), SIM, G1_12_URDF, 'XML|line'),
    Mistake('urdf_empty', 'g1_12dof', write(G1_12_URDF, b''), SIM, G1_12_URDF, 'XML|empty'),
    Mistake('urdf_inverted_limit', 'g1_12dof', replace(
        G1_12_URDF, '<limit lower="-0.2618" upper="0.2618"', '<limit lower="0.2618" upper="-0.2618"'),
            SIM, G1_12_URDF, 'left_ankle_roll_joint'),
    Mistake('urdf_inverted_limit_generate', 'g1_12dof', replace(
        G1_12_URDF, '<limit lower="-0.2618" upper="0.2618"', '<limit lower="0.2618" upper="-0.2618"'),
            GEN, G1_12_URDF, 'left_ankle_roll_joint'),
    Mistake('urdf_negative_mass', 'g1_12dof', replace(G1_12_URDF, '<mass value="0.608"/>',
                                                      '<mass value="-0.608"/>'),
            SIM, G1_12_URDF, 'left_ankle_roll_link'),
    Mistake('urdf_joint_renamed', 'g1_12dof', replace(G1_12_URDF, 'joint name="left_knee_joint"',
                                                      'joint name="left_knee"'),
            SIM, G1_12_URDF, 'left_knee'),
    Mistake('urdf_mesh_missing', 'g1', replace(
        'g1_29dof_rev_1_0.urdf', 'package://example-robot-data/robots/g1_description/meshes/pelvis.STL',
        'meshes/pelvis.STL'), SIM, 'g1_29dof_rev_1_0.urdf', 'pelvis.STL'),
    Mistake('urdf_duplicate_link', 'g1_12dof', replace(G1_12_URDF, '<link name="left_hip_roll_link">',
                                                       '<link name="left_hip_pitch_link">'),
            SIM, G1_12_URDF, 'not unique'),
    Mistake('profile_urdf_is_the_mjcf', 'g1_12dof', edit_yaml('profile.yaml', lambda d: d.update(urdf=G1_12_MJCF)),
            SIM, G1_12_MJCF, 'urdf'),
    Mistake('asimo_urdf_truncated', 'asimo_like', truncate('asimo_like.urdf', 0.3), SIM,
            'asimo_like.urdf', 'XML|line'),
    # -- the MJCF -------------------------------------------------------------------------------
    Mistake('mjcf_missing_mesh', 'g1_12dof', delete('meshes/left_knee_link.STL'), SIM,
            'left_knee_link.STL', 'mesh'),
    Mistake('mjcf_truncated', 'g1_12dof', truncate(G1_12_MJCF), SIM, G1_12_MJCF, 'XML|line'),
    Mistake('mjcf_inverted_range', 'g1_12dof', replace(
        G1_12_MJCF, 'range="-0.087267 2.8798"', 'range="2.8798 -0.087267"'), SIM, G1_12_MJCF,
            'left_knee_joint'),
    Mistake('mjcf_mass_differs', 'g1_12dof', replace(G1_12_MJCF, 'mass="17.7349"', 'mass="27.7349"'),
            SIM, G1_12_MJCF, 'mass'),
    Mistake('mjcf_joint_renamed', 'g1_12dof', replace(G1_12_MJCF, 'joint name="left_knee_joint"',
                                                      'joint name="left_knee"'),
            SIM, G1_12_MJCF, 'left_knee'),
    Mistake('mjcf_foot_body_renamed', 'g1_12dof', replace(G1_12_MJCF, 'body name="left_ankle_roll_link"',
                                                          'body name="left_foot"'),
            SIM, 'profile.yaml', 'feet.l.foot_link'),
    Mistake('mjcf_imu_body_renamed', 'g1_12dof', replace(G1_12_MJCF, '<body name="pelvis"',
                                                         '<body name="base_link"'),
            SIM, 'profile.yaml', 'imu_frame'),
    # -- the deploy config ----------------------------------------------------------------------
    Mistake('policy_missing_kps', 'g1_12dof', edit_yaml(POLICY, lambda d: d.pop('kps')), SIM,
            'policy.yaml', 'kps'),
    Mistake('policy_num_obs_48', 'g1_12dof', edit_yaml(POLICY, lambda d: d.update(num_obs=48)), SIM,
            'policy.yaml', 'num_obs'),
    Mistake('policy_11_actions', 'g1_12dof', edit_yaml(POLICY, _eleven), SIM, 'policy.yaml',
            '11 joints|11 actions'),
    Mistake('policy_joint_typo', 'g1_12dof', edit_yaml(POLICY, _typo_joint), SIM, 'policy.yaml',
            'left_knee_jiont'),
    Mistake('policy_kds_zero', 'g1_12dof', edit_yaml(POLICY, lambda d: d.update(kds=0)), SIM,
            'policy.yaml', 'kds'),
    Mistake('policy_degrees', 'g1_12dof', edit_yaml(POLICY, _degrees), SIM2, 'policy.yaml',
            'default_angles'),
    Mistake('policy_degrees_generate', 'g1_12dof', edit_yaml(POLICY, _degrees), GEN, 'policy.yaml',
            'default_angles'),
    Mistake('policy_negative_action_scale', 'g1_12dof', edit_yaml(POLICY, lambda d: d.update(action_scale=-0.25)),
            SIM2, 'policy.yaml', 'action_scale'),
    # Sizes, names and values all plausible: only a run shows it (simulate warns, check fails).
    Mistake('policy_sides_swapped', 'g1_12dof', edit_yaml(POLICY, _swap_policy_sides), SIM2,
            'policy.yaml', 'joint_names', exit_code=0),
    Mistake('policy_sides_swapped_generate', 'g1_12dof', edit_yaml(POLICY, _swap_policy_sides), GEN,
            'policy.yaml', 'joint_names', exit_code=0),
    # The gait clock at half its period: the robot walks, not as commanded.
    Mistake('policy_gait_clock_simulate', 'g1_12dof', edit_yaml(POLICY, lambda d: d.update(gait_period_s=0.4)),
            ('simulate', '--robot', '{robot}', '--duration', '5', '--command', '0.5', '0', '0'),
            'policy.yaml', 'gait_period_s', exit_code=0),
    Mistake('check_gait_clock', 'g1_12dof', edit_yaml(POLICY, lambda d: d.update(gait_period_s=0.4)),
            ('check', '--robot', '{robot}', '--controller', 'unitree_rl_gym'), 'policy.yaml',
            'gait_period_s', exit_code=1, slow=True),
    Mistake('check_sides_swapped', 'g1_12dof', edit_yaml(POLICY, _swap_policy_sides),
            ('check', '--robot', '{robot}', '--controller', 'unitree_rl_gym'), 'policy.yaml',
            'joint_names', exit_code=1, slow=True),
    Mistake('policy_unknown_field', 'g1_12dof', edit_yaml(POLICY, lambda d: d.update(action_scal=0.25)),
            SIM, 'policy.yaml', 'action_scal'),
    Mistake('policy_placeholder_path', 'g1_12dof', edit_yaml(POLICY, lambda d: d.update(
        policy_path='{LEGGED_GYM_ROOT_DIR}/deploy/pre_train/g1/motion.pt')), SIM, 'policy.yaml',
            'policy_path'),
    Mistake('policy_not_yaml', 'g1_12dof', write(POLICY, b'kps: [100, 100\n joint_names: ]\n'), SIM,
            'policy.yaml', 'YAML'),
    Mistake('policy_action_scale_x100', 'g1_12dof', edit_yaml(POLICY, lambda d: d.update(action_scale=25.0)),
            SIM, 'policy.yaml', 'action_scale'),
    # -- the network ----------------------------------------------------------------------------
    Mistake('network_truncated', 'g1_12dof', truncate(NETWORK), SIM, 'motion.pt', 'policy_path'),
    Mistake('network_empty', 'g1_12dof', write(NETWORK, b''), SIM, 'motion.pt', 'policy_path'),
    Mistake('network_random_bytes', 'g1_12dof', write(NETWORK, bytes(np.random.default_rng(0).integers(
        0, 256, 4096, dtype=np.uint8))), SIM, 'motion.pt', 'policy_path'),
    Mistake('network_onnx_garbage', 'g1_12dof', both(
        write('controllers/unitree_rl_gym/motion.onnx', b'not a protobuf'),
        edit_yaml(POLICY, lambda d: d.update(policy_path='motion.onnx'))), SIM, 'motion.onnx',
            'policy_path'),
    Mistake('network_weights_1e30', 'g1_12dof', scale_weights(1e30), SIM, 'motion.pt',
            'policy_path|NaN|inf'),
    Mistake('network_weights_nan', 'g1_12dof', scale_weights(float('nan')), SIM, 'motion.pt',
            'policy_path|NaN|inf'),
    Mistake('network_weights_nan_render', 'g1_12dof', scale_weights(float('nan')), RENDER, 'motion.pt',
            'policy_path|NaN|inf'),
    # -- render, check, train, evaluate, import-bags --------------------------------------------
    Mistake('render_policy_degrees', 'g1_12dof', edit_yaml(POLICY, _degrees), RENDER, 'policy.yaml',
            'default_angles'),
    Mistake('check_inverted_limit', 'g1_12dof', replace(
        G1_12_URDF, '<limit lower="-0.2618" upper="0.2618"', '<limit lower="0.2618" upper="-0.2618"'),
            CHECK, G1_12_URDF, 'left_ankle_roll_joint', exit_code=1),
    Mistake('check_profile_not_yaml', 'g1_12dof',
            replace('profile.yaml', 'name: g1_12dof', 'name: [g1_12dof'), CHECK, 'profile.yaml', 'YAML',
            exit_code=1),
    Mistake('train_not_a_dataset', 'g1_12dof', NO_CHANGE,
            ('train', '--data', '{dir}', '--out', '{out}/m.json', '--tau-plus', '0.2'), 'g1_12dof', 'dataset'),
    Mistake('evaluate_model_truncated', 'g1_12dof',
            lambda f: (f / 'm.json').write_text('{"format": "fall_predictor'),
            ('evaluate', '--model', '{dir}/m.json', '--data', '{dir}'), 'm.json', 'JSON'),
    Mistake('evaluate_model_is_yaml', 'g1_12dof', NO_CHANGE,
            ('evaluate', '--model', '{robot}', '--data', '{dir}'), 'profile.yaml', 'JSON'),
    Mistake('evaluate_model_missing', 'g1_12dof', NO_CHANGE,
            ('evaluate', '--model', '{dir}/nothing.json', '--data', '{dir}'), 'nothing.json', 'model|no such'),
    Mistake('import_bags_not_bags', 'g1_12dof', NO_CHANGE,
            ('import-bags', '{dir}/meshes', '--out', '{out}/imported', '--robot', '{robot}'),
            'meshes', 'bag', exit_code=1),
    Mistake('import_bags_broken_urdf', 'g1_12dof', truncate(G1_12_URDF),
            ('import-bags', '{dir}/meshes', '--out', '{out}/imported', '--urdf', '{dir}/' + G1_12_URDF),
            G1_12_URDF, 'XML|line|bag'),
)


# -- running them through the command line ------------------------------------------------------

def run(mistake: Mistake, root: Path, extra_env: Optional[dict] = None) -> subprocess.CompletedProcess:
    _, argv = mistake.make(root)
    env = dict(os.environ)
    env.update(extra_env or {})
    return subprocess.run([sys.executable, '-m', 'fall_predictor', *argv], capture_output=True,
                          text=True, env=env, timeout=600, cwd=root)


def stderr_lines(text: str) -> list[str]:
    """The lines a person reads on stderr: without PyBullet's build banner and progress bars
    (neither says anything of the mistake; both are counted as no word for the counts)."""
    return [line for line in text.splitlines() if line.strip()
            and not line.startswith('pybullet build time') and '%|' not in line]


def classify(mistake: Mistake, result: subprocess.CompletedProcess) -> str:
    """'clear' (the exit code wanted, one line naming the file and the field), 'traceback',
    'silent' (exit 0 and not a word on stderr), or 'unclear' (anything else)."""
    err = stderr_lines(result.stderr)
    if any('Traceback' in line for line in err):
        return 'traceback'
    if result.returncode == 0 and not err:
        return 'silent'
    if result.returncode == mistake.exit_code and len(err) == 1 and named(mistake, err[0]):
        return 'clear'
    if mistake.is_check and result.returncode == 1 and named(mistake, result.stdout):
        return 'clear'
    return 'unclear'


def named(mistake: Mistake, text: str) -> bool:
    return mistake.file in text and any(f in text for f in mistake.field.split('|'))


if __name__ == '__main__':
    import tempfile
    only = set(sys.argv[1:])
    counts: dict[str, int] = {}
    raw = {}
    for mistake in MISTAKES:
        if only and mistake.name not in only:
            continue
        with tempfile.TemporaryDirectory() as tmp:
            result = run(mistake, Path(tmp))
        kind = classify(mistake, result)
        counts[kind] = counts.get(kind, 0) + 1
        err = stderr_lines(result.stderr)
        raw[mistake.name] = {'kind': kind, 'exit': result.returncode, 'stderr': result.stderr}
        print(f'{kind:9s} {mistake.name:32s} exit {result.returncode} '
              f'{(err[-1] if err else "")[:150]}', flush=True)
    print(json.dumps(counts))
    if os.environ.get('MISTAKES_RAW'):
        Path(os.environ['MISTAKES_RAW']).write_text(json.dumps(raw, indent=1))
