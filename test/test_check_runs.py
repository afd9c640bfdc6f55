"""``fall-predictor check``'s runs (sim/checks.py): every shipped robot stands and walks where it
is commanded under each of its controllers, never falling; a policy whose joints are given in the
wrong order falls, and the check names the likely causes."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from fall_predictor.cli.main import main
from fall_predictor.profiles.profile import available_profiles

PROFILES = Path(__file__).resolve().parents[1] / 'fall_predictor' / 'profiles'


@pytest.mark.parametrize('robot', available_profiles())
def test_every_shipped_robot_passes_every_check(robot, capsys) -> None:
    assert main(['check', '--robot', robot, '--json']) == 0
    payload = json.loads(capsys.readouterr().out)
    rows = {c['name']: c for c in payload['checks']}
    assert all(c['ok'] for c in rows.values()), [c for c in rows.values() if not c['ok']]
    runs = [name for name in rows if 'walks' in name or 'stands' in name or 'turns' in name]
    assert runs, rows
    if robot == 'g1_12dof':             # Unitree's policy: a stand, a walk and a turn, measured
        walk = rows['unitree_rl_gym: walks forward at 0.5 m/s']['found']
        forward = float(walk.split(' m forward')[0])
        assert 0.5 * 0.5 * 4.0 <= forward <= 1.5 * 0.5 * 4.0, walk


def test_a_policy_with_its_legs_swapped_fails_its_runs_naming_the_causes(tmp_path, capsys) -> None:
    shutil.copytree(PROFILES / 'g1_12dof', tmp_path / 'g1_12dof')
    policy = tmp_path / 'g1_12dof' / 'controllers' / 'unitree_rl_gym' / 'policy.yaml'
    data = yaml.safe_load(policy.read_text())
    data['joint_names'] = data['joint_names'][6:] + data['joint_names'][:6]
    policy.write_text(yaml.safe_dump(data))
    assert main(['check', '--robot', str(tmp_path / 'g1_12dof' / 'profile.yaml'),
                 '--controller', 'unitree_rl_gym', '--json']) == 1
    rows = json.loads(capsys.readouterr().out)['checks']
    failed = [c for c in rows if not c['ok'] and not c['warning']]
    assert failed and all(c['name'].startswith('unitree_rl_gym: ') for c in failed)
    assert any('fell' in c['found'] for c in failed)
    assert all('joint order of joint_names' in c['fix'] and c['file'] == str(policy) for c in failed)
    # the static part already warned: the MJCF's actuators are in another order
    warned = [c for c in rows if c['warning']]
    assert [c['name'] for c in warned] == ['unitree_rl_gym: joint order']
    assert warned[0]['field'] == 'joint_names' and 'right_hip_pitch_joint' in warned[0]['found']
