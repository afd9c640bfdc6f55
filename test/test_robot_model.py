"""The URDF read back through PyBullet matches method §1."""
import pybullet as pb
import pytest

from fall_predictor.profiles import asimo_like_urdf as rm
from fall_predictor.robot.balance_controller import BalanceController


@pytest.fixture
def robot():
    client = pb.connect(pb.DIRECT)
    body = pb.loadURDF(str(rm.SIM_URDF_PATH), [0, 0, 1], flags=pb.URDF_USE_INERTIA_FROM_FILE,
                       physicsClientId=client)
    yield client, body
    pb.disconnect(client)


def test_urdf_file_is_generated_from_the_model_tables():
    assert rm.URDF_PATH.read_text() == rm.urdf_xml()
    assert rm.SIM_URDF_PATH.read_text() == rm.urdf_xml(sole_frames=False)


def test_the_description_has_massless_sole_frames_at_the_sole_centres():
    import xml.etree.ElementTree as ET
    root = ET.fromstring(rm.URDF_PATH.read_text())
    joints = {j.get('name'): j for j in root.findall('joint')}
    for side in rm.SIDES:
        j = joints[f'{side}_sole_fixed']
        assert j.get('type') == 'fixed' and j.find('parent').get('link') == f'{side}_foot'
        xyz = [float(v) for v in j.find('origin').get('xyz').split()]
        # The foot box's underside centre: its CoM half a sole thickness lower.
        foot = next(lk for lk in rm.all_links_and_joints()[0] if lk.name == f'{side}_foot')
        assert xyz == pytest.approx([foot.com_xyz[0], 0.0, foot.com_xyz[2] - foot.size_xyz[2] / 2])
    assert [lk.find('inertial/mass').get('value') for lk in root.findall('link')
            if lk.get('name') in rm.SOLE_FRAMES] == ['0', '0']


def test_26_revolute_joints_with_the_spec_names(robot):
    client, body = robot
    n = pb.getNumJoints(body, physicsClientId=client)
    assert n == 26
    infos = [pb.getJointInfo(body, i, physicsClientId=client) for i in range(n)]
    assert tuple(i[1].decode() for i in infos) == rm.JOINT_NAMES
    assert all(i[2] == pb.JOINT_REVOLUTE for i in infos)
    for info in infos:
        lower, upper, effort, velocity = info[8], info[9], info[10], info[11]
        assert lower < upper and effort > 0 and velocity > 0
    leg = [i for i in infos if i[1].decode().endswith(('knee_pitch', 'hip_pitch', 'hip_roll'))]
    assert min(i[10] for i in leg) >= 150.0   # leg joints carry a 42 kg robot


def test_total_mass_is_42_1_kg(robot):
    client, body = robot
    masses = [pb.getDynamicsInfo(body, i, physicsClientId=client)[0] for i in range(-1, 26)]
    assert sum(masses) == pytest.approx(42.1, rel=0.01)


def test_feet_are_boxes_of_the_spec_size(robot):
    client, body = robot
    names = [pb.getJointInfo(body, i, physicsClientId=client)[12].decode() for i in range(26)]
    for foot in rm.FOOT_LINKS:
        shapes = pb.getCollisionShapeData(body, names.index(foot), physicsClientId=client)
        assert len(shapes) == 1
        assert shapes[0][2] == pb.GEOM_BOX
        length, width, _ = shapes[0][3]
        assert length == pytest.approx(0.225, abs=1e-6)
        assert width == pytest.approx(0.157, abs=1e-6)


def test_com_height_in_the_walking_posture(sim):
    q0, torso = BalanceController().initial_posture()
    m = sim.reset(q0, torso)
    assert m.com[2] == pytest.approx(0.59, abs=0.02)
    # The soles start flat on the ground: no gap to fall through.
    for foot in ('l_foot', 'r_foot'):
        aabb_min, _ = pb.getAABB(sim.robot, sim.link_names.index(foot), physicsClientId=sim.client)
        assert abs(aabb_min[2]) < 0.003
