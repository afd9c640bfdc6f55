"""``fall-predictor check``'s static part (profiles/checks.py, robot/checks.py, sim/checks.py):
every shipped profile passes in well under a second; each check finds the mistake it is for, with
the answer an independent computation gives; the off-screen GL choice of ``render``."""
from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from fall_predictor.cli.main import main
from fall_predictor.profiles.profile import available_profiles
from fall_predictor.profiles.checks import nearest, unknown_keys
from fall_predictor.sim.checks import StaticCheckFailed, require_static_checks, static_checks

PROFILES = Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles'


@pytest.mark.parametrize('robot', available_profiles())
def test_every_shipped_profile_passes_the_static_checks_fast(robot) -> None:
    static_checks(robot)                                   # imports warmed
    start = time.perf_counter()
    checks, profile = static_checks(robot)
    elapsed = time.perf_counter() - start
    assert profile is not None and profile.name == robot
    assert [c.line() for c in checks if not c.ok] == []
    assert elapsed < 2.0, elapsed
    assert {'profile keys', 'URDF joint limits', 'total mass', 'feet sides', 'fall heights'} <= {
        c.name for c in checks}


def test_check_static_prints_a_table_and_json(capsys) -> None:
    assert main(['check', '--robot', 'g1_12dof', '--static']) == 0
    out = capsys.readouterr().out
    assert out.count('✓') >= 15 and '✗' not in out
    assert main(['check', '--robot', 'g1_12dof', '--static', '--json']) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload['ok'] and payload['failures'] == 0
    names = {c['name'] for c in payload['checks']}
    assert {'MJCF CoM', 'unitree_rl_gym: network sizes', 'unitree_rl_gym: actions at rest'} <= names


def _copy(tmp_path: Path, robot: str) -> Path:
    shutil.copytree(PROFILES / robot, tmp_path / robot)
    return tmp_path / robot / 'profile.yaml'


def _edit(path: Path, change) -> None:
    data = yaml.safe_load(path.read_text())
    change(data)
    path.write_text(yaml.safe_dump(data, sort_keys=False))


def test_an_unknown_key_is_named_with_the_nearest_known_one() -> None:
    found = unknown_keys(Path('p.yaml'), {'name': 'x', 'total_mas_kg': 3,
                                          'feet': {'l': {'sole_lenght_m': 0.2}},
                                          'controllers': {'rl': {'polcy': 'p.yaml'}}})
    assert found == ["total_mas_kg (did you mean 'total_mass_kg'?)",
                     "feet.l.sole_lenght_m (did you mean 'sole_length_m'?)",
                     "controllers.rl.polcy (did you mean 'policy'?)"]
    assert nearest('zzz', ['urdf']) == ''


def test_the_mass_check_gives_the_urdfs_mass(tmp_path) -> None:
    """The URDF's links' masses summed independently of Pinocchio (its <mass> elements)."""
    import xml.etree.ElementTree as ET
    profile = _copy(tmp_path, 'g1_12dof')
    _edit(profile, lambda d: d.update(total_mass_kg=60.0))
    urdf_mass = sum(float(m.get('value')) for m in
                    ET.parse(profile.parent / 'g1_12dof.urdf').getroot().iter('mass'))
    checks, _ = static_checks(profile)
    mass = next(c for c in checks if c.name == 'total mass')
    assert not mass.ok and mass.field == 'total_mass_kg'
    assert f'{urdf_mass:.3f}' in mass.fix


def test_fall_heights_are_measured_from_the_soles_at_the_default_posture(tmp_path) -> None:
    """The standing CoM height: the G1's CoM over its soles at Unitree's default angles, which the
    MuJoCo model of the same robot gives too (test_profiles: the two agree)."""
    profile = _copy(tmp_path, 'g1_12dof')
    _edit(profile, lambda d: d['monitor'].update(fallen_com_height_m=0.72, guard_com_height_m=0.8))
    checks, _ = static_checks(profile)
    heights = next(c for c in checks if c.name == 'fall heights')
    assert not heights.ok and heights.field == 'monitor.fallen_com_height_m'
    standing = float(heights.found.split('standing CoM (')[1].split(' m')[0])
    assert 0.66 < standing < 0.72


def test_a_refusal_is_one_line_with_the_first_failure_and_the_count(tmp_path) -> None:
    profile = _copy(tmp_path, 'g1_12dof')
    _edit(profile, lambda d: d.update(total_mass_kg=60.0, simulater='mujoco'))
    with pytest.raises(StaticCheckFailed) as refused:
        require_static_checks(profile)
    text = str(refused.value)
    assert '\n' not in text and 'simulater' in text and '(1 more)' in text
    assert 'fall-predictor check --robot' in text


def test_a_check_of_a_profile_that_does_not_load_is_a_failed_row(tmp_path, capsys) -> None:
    profile = _copy(tmp_path, 'asimo_like')
    profile.write_text(profile.read_text().replace('name: asimo_like', 'name: [asimo'))
    assert main(['check', '--robot', str(profile)]) == 1
    out = capsys.readouterr().out
    assert '✗ profile loads' in out and 'line' in out


def test_degrees_and_a_negative_action_scale_are_named(tmp_path) -> None:
    profile = _copy(tmp_path, 'g1_12dof')
    policy = profile.parent / 'controllers' / 'unitree_rl_gym' / 'policy.yaml'
    _edit(policy, lambda d: d.update(default_angles=[round(float(np.degrees(a)), 1)
                                                     for a in d['default_angles']],
                                     action_scale=-0.25))
    checks, _ = static_checks(profile)
    failed = {c.name: c for c in checks if not c.ok}
    assert failed['unitree_rl_gym: default angles'].field == 'default_angles'
    assert '-0.099' in failed['unitree_rl_gym: default angles'].fix   # -5.7 deg in radians
    assert failed['unitree_rl_gym: action scale'].field == 'action_scale'


def test_nan_actions_name_the_network_file() -> None:
    from fall_predictor.monitor.sensor_records import SensorSample
    from fall_predictor.robot.learned_policy import LearnedPolicy, NonFiniteActions
    from fall_predictor.robot.policy_config import load_policy_config

    config = load_policy_config(PROFILES / 'g1_12dof' / 'controllers' / 'unitree_rl_gym' / 'policy.yaml')

    class NanNetwork:
        input_size, output_size, recurrent = config.obs_size, config.num_actions, False

        def reset(self) -> None:
            pass

        def __call__(self, obs):
            return np.full(12, np.nan, np.float32)

        def describe(self) -> str:
            return 'nan'
    policy = LearnedPolicy(config, NanNetwork())
    sample = SensorSample(0.0, config.joint_names, np.zeros(12), np.zeros(12),
                          np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(3))
    with pytest.raises(NonFiniteActions) as error:
        policy.act(0.0, sample, (0.0, 0.0, 0.0))
    assert error.value.file == str(config.policy_path) and error.value.field == 'policy_path'


def test_render_keeps_a_users_gl_choice_and_tries_egl_then_osmesa(monkeypatch) -> None:
    import sys

    from fall_predictor.sim import gl_backend
    monkeypatch.setenv('MUJOCO_GL', 'glfw')
    assert gl_backend.choose_mujoco_gl(probe=lambda name: False) == 'glfw'
    monkeypatch.delenv('MUJOCO_GL')
    monkeypatch.delitem(sys.modules, 'mujoco', raising=False)
    tried = []
    assert gl_backend.choose_mujoco_gl(probe=lambda name: tried.append(name) or name == 'osmesa') == 'osmesa'
    assert tried == ['egl', 'osmesa']
    monkeypatch.delenv('MUJOCO_GL')
    with pytest.raises(gl_backend.NoOffscreenGL, match='libosmesa6'):
        gl_backend.choose_mujoco_gl(probe=lambda name: False)


def test_every_failure_is_listed_not_only_the_first(tmp_path) -> None:
    """Mistakes in the profile, the URDF and the deploy config at once: a row for each."""
    profile = _copy(tmp_path, 'g1_12dof')
    _edit(profile, lambda d: d['monitor'].update(guard_com_height_m=0.9))
    urdf = profile.parent / 'g1_12dof.urdf'
    urdf.write_text(urdf.read_text().replace('<mass value="0.608"/>', '<mass value="-0.608"/>', 1))
    _edit(profile.parent / 'controllers' / 'unitree_rl_gym' / 'policy.yaml', lambda d: d.update(kds=0))
    checks, _ = static_checks(profile)
    failed = {c.name for c in checks if not c.ok}
    assert {'fall heights', 'URDF masses', 'unitree_rl_gym: PD gains'} <= failed, failed
