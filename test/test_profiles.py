"""Robot profiles: every shipped profile is consistent with its URDF, a user's profile loads from
any folder, a malformed one says what is wrong, and no robot constant lives outside profiles/."""
from __future__ import annotations

import ast
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from fall_predictor.monitor import records
from fall_predictor.profiles.profile import ProfileError, available_profiles, load_profile
from fall_predictor.profiles.profile import PROFILES_DIR

PACKAGE_DIR = Path(__file__).resolve().parents[1] / 'fall_predictor'


def test_the_shipped_robots():
    assert set(available_profiles()) >= {'asimo_like', 'g1'}


@pytest.mark.parametrize('name', available_profiles())
def test_a_profile_agrees_with_its_urdf(name):
    profile = load_profile(name)
    description = profile.sensor_layout().description(profile.urdf_xml())
    # The mass the profile states is the URDF's (fall direction and momentum use it).
    assert description.total_mass_kg == pytest.approx(profile.total_mass_kg, rel=1e-3)
    # Every joint of the URDF is in exactly one group and has servo gains.
    grouped = [j for joints in profile.joint_groups.values() for j in joints]
    assert sorted(grouped) == sorted(description.joint_names)
    for joint in description.joint_names:
        assert profile.gains_for(joint).kp_nm_per_rad > 0
    # Legs run hip to ankle: the last joint of each leg moves the foot the sole is fixed to.
    model = description.model
    for side in ('l', 'r'):
        foot = profile.feet[side]
        ankle = profile.leg_joints(side)[-1]
        assert model.frames[model.getFrameId(foot.foot_link)].parentJoint == model.getJointId(ankle)
    # The IMU frame is a frame of the URDF.
    assert model.existFrame(profile.imu_frame)
    assert 0 < profile.fallen_com_height_m < profile.guard_com_height_m


@pytest.mark.parametrize('name', available_profiles())
def test_the_soles_lie_under_the_ankles_and_apart(name):
    """Standing on the URDF's zero posture, both soles are the lowest points of the legs, level,
    and the feet lie left and right of the base."""
    profile = load_profile(name)
    d = profile.sensor_layout().description(profile.urdf_xml())
    q = pin.neutral(d.model)
    pin.framesForwardKinematics(d.model, d.data, q)
    soles = {s: d.data.oMf[d.sole_ids[s]] for s in ('l', 'r')}
    assert soles['l'].translation[1] > 0.02 > -0.02 > soles['r'].translation[1]
    assert soles['l'].translation[2] == pytest.approx(soles['r'].translation[2], abs=1e-6)
    for s in ('l', 'r'):
        ankle = d.data.oMi[d.model.getJointId(profile.leg_joints(s)[-1])].translation
        assert ankle[2] - soles[s].translation[2] > 0.02          # the ankle above its sole
        assert np.allclose(soles[s].rotation, np.eye(3), atol=1e-9)


def test_the_g1_sole_is_where_its_collision_spheres_touch_the_ground():
    """Independently of the profile: the 4 collision spheres of each G1 ankle roll link; the
    sole frame lies at the centre of their contact points, on the plane they touch, and the
    sole rectangle lies inside their hull."""
    profile = load_profile('g1')
    root = ET.fromstring(profile.urdf_xml())
    for side in ('l', 'r'):
        foot = profile.feet[side]
        link = next(lk for lk in root.iter('link') if lk.get('name') == foot.foot_link)
        points = []
        for collision in link.iter('collision'):
            radius = float(collision.find('geometry/sphere').get('radius'))
            x, y, z = (float(v) for v in collision.find('origin').get('xyz').split())
            points.append((x, y, z - radius))
        points = np.array(points)
        assert len(points) == 4
        ox, oy, oz = foot.sole_origin_in_foot_m
        assert oz == pytest.approx(points[:, 2].min(), abs=1e-9)
        assert ox == pytest.approx((points[:, 0].min() + points[:, 0].max()) / 2, abs=1e-9)
        assert foot.sole_length_m <= np.ptp(points[:, 0]) + 1e-9
        assert foot.sole_width_m <= 2 * np.abs(points[:, 1]).min() + 1e-9
        assert foot.force_torque_frame is None          # the G1 has no foot F/T sensors
    assert profile.sensor_layout().force_sensors == ()


def test_the_monitor_defaults_are_the_shipped_robots():
    """The learner's default heights (monitor.records) are those of the default profile."""
    profile = load_profile()
    assert records.FALLEN_COM_HEIGHT_M == profile.fallen_com_height_m
    assert records.GUARD_COM_HEIGHT_M == profile.guard_com_height_m


def test_a_user_profile_loads_from_its_own_folder(tmp_path):
    """A robot team's profile lives anywhere; its URDF path is relative to the profile file."""
    src = PROFILES_DIR / 'asimo_like'
    shutil.copy(src / 'asimo_like.urdf', tmp_path / 'robot.urdf')
    raw = yaml.safe_load((src / 'profile.yaml').read_text())
    raw.update(name='my_robot', urdf='robot.urdf')
    del raw['sim_urdf']
    raw['feet']['l']['sole_length_m'] = 0.2
    path = tmp_path / 'my_robot.yaml'
    path.write_text(yaml.safe_dump(raw))
    profile = load_profile(str(path))
    assert profile.name == 'my_robot'
    assert profile.urdf_path == profile.sim_urdf_path == (tmp_path / 'robot.urdf').resolve()
    assert profile.sensor_layout().soles['l'].length_m == 0.2


@pytest.mark.parametrize('change, message', [
    (lambda r: r.pop('imu_frame'), "missing key 'imu_frame'"),
    (lambda r: r['feet']['l'].update(sole_length_m=-1), 'feet.l.sole_length_m must be a number'),
    (lambda r: r['feet']['r'].update(sole_origin_in_foot_m=[0, 0]), 'list of 3 numbers'),
    (lambda r: r.update(urdf='nowhere.urdf'), "urdf names 'nowhere.urdf', which is not a file"),
    (lambda r: r['joint_groups'].pop('r_leg'), 'joint_groups needs r_leg'),
    (lambda r: r['monitor'].update(guard_com_height_m=0.1), 'guard_com_height_m must be'),
    (lambda r: r['servo_gains'].update(knee_pitch=[1, 2]), 'servo_gains.knee_pitch'),
    (lambda r: r['posture'].update(tail=0.3), r"posture names joints in no joint group: \['tail'\]"),
    (lambda r: r.update(gait_variety='yes'), 'gait_variety must be true or false'),
    (lambda r: r.update(sim_ground='sand'), "sim_ground must be 'plane' or 'slab'"),
])
def test_a_malformed_profile_says_which_key(tmp_path, change, message):
    src = PROFILES_DIR / 'asimo_like'
    for f in src.glob('*.urdf'):
        shutil.copy(f, tmp_path / f.name)
    raw = yaml.safe_load((src / 'profile.yaml').read_text())
    change(raw)
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(ProfileError, match=message) as info:
        load_profile(str(path))
    assert str(path) in str(info.value)


def test_an_unknown_robot_names_the_shipped_ones():
    with pytest.raises(ProfileError, match='unknown robot .atlas.: the shipped profiles are asimo_like, g1'):
        load_profile('atlas')
    with pytest.raises(ProfileError, match='no such file'):
        load_profile('/nowhere/robot.yaml')


# -- no robot constant outside the profiles ------------------------------------------------------

def _robot_constants() -> tuple[set[float], set[str]]:
    """Numbers and names that belong to one robot: masses, sole sizes, frame, link and file names."""
    numbers, names = set(), set()
    for name in available_profiles():
        p = load_profile(name)
        numbers.add(p.total_mass_kg)
        for foot in p.feet.values():
            numbers.update({foot.sole_length_m, foot.sole_width_m})
            names.update({foot.sole_frame, foot.foot_link})
            if foot.force_torque_frame:
                names.add(foot.force_torque_frame)
        names.update({p.urdf_path.name, p.sim_urdf_path.name})
        names.update(j for joints in p.joint_groups.values() for j in joints)
        if p.imu_frame not in {'torso', 'base_link', 'pelvis'}:     # generic words stay usable
            names.add(p.imu_frame)
    # Round numbers (0.05, 0.17) are everywhere for other reasons: only the telling ones count.
    numbers = {n for n in numbers if len(f'{n:g}'.replace('.', '').strip('0')) >= 3}
    return numbers, names


def _constants_in(path: Path, numbers: set[float], names: set[str], root: Path) -> list[str]:
    """'file:line: value' for every robot constant in ``path``'s code (docstrings aside)."""
    tree = ast.parse(path.read_text(), str(path))
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr)
                  and isinstance(node.body[0].value, ast.Constant)}
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Constant) or id(node) in docstrings:
            continue
        value = node.value
        if (isinstance(value, float) and value in numbers) or (isinstance(value, str) and value in names):
            found.append(f'{path.relative_to(root)}:{node.lineno}: {value!r}')
    return found


def test_no_robot_constant_outside_the_profiles():
    numbers, names = _robot_constants()
    offending = []
    for path in sorted(PACKAGE_DIR.rglob('*.py')):
        if path.relative_to(PACKAGE_DIR).parts[0] in {'profiles', 'msg'}:
            continue
        offending += _constants_in(path, numbers, names, PACKAGE_DIR.parent)
    assert not offending, ('robot-specific constants outside fall_predictor/profiles/ (move them '
                           'into the robot profile):\n' + '\n'.join(offending))


def test_the_constant_check_sees_one(tmp_path):
    module = tmp_path / 'fake.py'
    module.write_text('"""42.1 kg in a docstring is fine."""\nMASS = 42.1\nSOLE = "l_sole"\n'
                      'def f():\n    """l_sole"""\n    return 0.2\n')
    numbers, names = _robot_constants()
    assert _constants_in(module, numbers, names, tmp_path) == ["fake.py:2: 42.1", "fake.py:3: 'l_sole'"]


@pytest.mark.parametrize('name', ['asimo_like', 'g1'])
def test_legs_and_upper_body_split_every_joint_once(name):
    profile = load_profile(name)
    legs, upper = profile.legs_and_upper_body()
    assert legs == profile.leg_joints('l') + profile.leg_joints('r') and len(legs) == 12
    assert sorted(legs + upper) == sorted(profile.joint_names) and not set(legs) & set(upper)
    assert list(upper) == [n for n in profile.joint_names if n in upper]   # in the joint order
