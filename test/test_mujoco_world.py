"""sim/mujoco_world.py: the MuJoCo engine behind the simulator seam, checked against physics: the
weight on the feet, a free fall, a push's impulse, the IMU at rest, exact snapshots, determinism;
and the URDF path (a robot without an MJCF)."""
from __future__ import annotations

import numpy as np
import pytest

from fall_predictor.monitor.records import STANDARD_GRAVITY_M_S2, PushSpec
from fall_predictor.profiles.profile import load_profile
from fall_predictor.robot.control import JointCommand, Posture, make_controller
from fall_predictor.sim.mujoco_world import MujocoWorld
from fall_predictor.sim.sensors import SensorParams, SensorSuite
from fall_predictor.sim.trajectory import run_trajectory

G1 = load_profile('g1_12dof')
DT_S = 0.002


def hold(world: MujocoWorld, posture: Posture) -> JointCommand:
    """The policy's PD gains holding ``posture`` (the deploy config's drives)."""
    policy = G1.controller_profile()
    from fall_predictor.robot.policy_config import load_policy_config
    config = load_policy_config(policy.policy_path, check_network=False)
    names = config.joint_names
    return JointCommand(names, np.array([posture.joint_angles[n] for n in names]),
                        np.array(config.kp, float), np.array(config.kd, float))


def free_base(world: MujocoWorld) -> MujocoWorld:
    """``world`` without the joint defaults Unitree's MJCF also gives the free base (armature 0.01,
    damping 0.001, friction loss 0.1: on the base they act as a small outside friction and mass,
    0.1 N, 0.3 N s over 3 s of walking), so that nothing but gravity, the ground and a push acts
    on the robot as a whole."""
    base = world.base_dofs
    world.model.dof_frictionloss[base] = world.model.dof_damping[base] = 0.0
    world.model.dof_armature[base] = 0.0
    return world


def test_the_contact_forces_are_those_that_move_the_robot() -> None:
    """The policy walking 3 s: the ground forces the world reports (the feet's contacts), summed
    over the steps with gravity, equal the change of the robot's linear momentum (Newton: nothing
    else acts on it), to 10 mN s of 12; both feet take turns, the CoP stays under the feet,
    no other link touches the ground."""
    world = free_base(MujocoWorld(G1, dt_s=DT_S))
    weight_n = world.total_mass * STANDARD_GRAVITY_M_S2
    assert world.total_mass == pytest.approx(G1.total_mass_kg, abs=1e-4)
    forces, cops = [], []

    def on_step(w, m) -> None:
        f = sum((f for _, f in w._last_contacts['l'] + w._last_contacts['r']), np.zeros(3))
        forces.append(f)
        cops.append(m.cop)
    result = run_trajectory(None, 3.0, world=world, controller=make_controller(G1, command=(
        0.4, 0.0, 0.0)), on_step=on_step)
    p0, p1 = result.measurements[0].lin_mom, result.measurements[-1].lin_mom
    impulse = (np.sum(forces, axis=0) - [0.0, 0.0, weight_n * len(forces)]) * DT_S
    np.testing.assert_allclose(impulse, p1 - p0, atol=0.01)    # of 12 N s (a stale-state read: 0.3)
    assert not any(m.non_foot_contact for m in result.measurements) and not result.fallen
    singles = [m for m in result.measurements if len(m.left_contacts) != len(m.right_contacts)]
    assert {len(m.left_contacts) > 0 for m in singles} == {True, False}     # both feet step
    for m in result.measurements[250:]:
        feet = np.array([m.left_foot[:2], m.right_foot[:2]])
        assert np.linalg.norm(m.cop[:2] - feet, axis=1).min() < 0.15


def test_the_imu_in_free_fall_reads_no_specific_force_and_no_rotation() -> None:
    world = MujocoWorld(G1, dt_s=DT_S)
    posture = make_controller(G1).initial_posture()
    world.start(Posture(posture.joint_angles, 0.0, (0.0, 0.0, 2.0)))
    world.apply(hold(world, posture))
    truths = []
    for _ in range(50):
        world.step()
        truths.append(world.sensor_truth())
    readings = SensorSuite(SensorParams(noise_scale=0.0), dt_s=DT_S, profile=G1).read_many(truths)
    # The first reading has no earlier velocity (its specific force is gravity's alone).
    np.testing.assert_allclose([r.accel_m_s2 for r in readings[1:]], 0.0, atol=0.01)
    # The joints settle in the air: the base turns by micro-radians a second (angular momentum 0).
    np.testing.assert_allclose([t.gyro_rad_s for t in truths], 0.0, atol=1e-4)
    assert truths[-1].left_wrench is None and truths[-1].right_wrench is None    # no foot F/T
    # The IMU frame is the URDF's imu_in_pelvis: 4.5 cm ahead of and 8.3 cm below the pelvis.
    assert world._imu_offset.tolist() == [0.04525, 0.0, -0.08339]


def test_a_free_fall_follows_gravity_exactly() -> None:
    """The robot released 1 m above the ground, joints held: its momentum grows by m g per second
    and its CoM falls g t^2 / 2 (MuJoCo's semi-implicit Euler: to the step's order), its angular
    momentum stays zero."""
    world = free_base(MujocoWorld(G1, dt_s=DT_S))
    posture = make_controller(G1).initial_posture()
    start = world.start(Posture(posture.joint_angles, 0.0, (0.0, 0.0, 2.0)))
    world.apply(hold(world, posture))
    steps = 200
    for _ in range(steps):
        m = world.step()
    t = steps * DT_S
    assert m.lin_mom[2] == pytest.approx(-world.total_mass * STANDARD_GRAVITY_M_S2 * t, rel=1e-9)
    assert m.com[2] == pytest.approx(start.com[2] - STANDARD_GRAVITY_M_S2 * t ** 2 / 2, abs=0.01)
    assert np.linalg.norm(m.ang_mom) < 1e-6 and not len(m.left_contacts)


def test_a_push_changes_the_momentum_by_its_impulse() -> None:
    """Without gravity, in the air: a 200 N push for 0.1 s along the heading's left changes the
    linear momentum by 20 N s to the left (the push protocol's onset direction), exactly."""
    world = free_base(MujocoWorld(G1, dt_s=DT_S))
    world.model.opt.gravity[:] = 0.0
    posture = make_controller(G1).initial_posture()
    world.start(Posture(posture.joint_angles, 0.3, (0.0, 0.0, 2.0)))
    world.apply(hold(world, posture))
    world.schedule_push(PushSpec(200.0, 90.0, 0.1, 0.1))
    heading = []
    for _ in range(int(0.4 / DT_S)):
        m = world.step()
        if abs(m.t - 0.1) < 1e-9:
            heading.append(m.heading)          # the heading at the onset fixes the direction
    assert heading[0] == pytest.approx(0.3, abs=0.01)
    left = np.array([np.cos(heading[0] + np.pi / 2), np.sin(heading[0] + np.pi / 2), 0.0])
    np.testing.assert_allclose(m.lin_mom, 20.0 * left, atol=0.02)    # 0.1 % of the impulse


def test_a_snapshot_continues_bit_for_bit_and_runs_are_deterministic() -> None:
    """The policy walking, pushed: a run restored from a snapshot taken mid-walk continues as the
    uninterrupted run, and two runs from the start are identical."""
    def run(seed: int):
        world = MujocoWorld(G1, dt_s=DT_S)
        control = make_controller(G1, command=(0.4, 0.0, 0.2))
        suite = SensorSuite(SensorParams(), seed=seed, dt_s=DT_S, profile=G1)
        return run_trajectory(PushSpec(300.0, 45.0, 0.1, 1.0), 1.5, world=world,
                              controller=control, sensors=suite, stop_when_fallen=False)
    a, b = run(3), run(3)
    assert [m.com.tolist() for m in a.measurements] == [m.com.tolist() for m in b.measurements]
    assert np.array_equal(a.sensor_readings[-1].q, b.sensor_readings[-1].q)
    world = MujocoWorld(G1, dt_s=DT_S)
    posture = make_controller(G1).initial_posture()
    world.start(posture)
    command = hold(world, posture)
    world.apply(command)
    for _ in range(100):
        world.step()
    state, tick, m = world.save_state(), world.tick, world.measure()
    straight = [world.step().com.tolist() for _ in range(50)]
    world.restore(state, tick, m)
    world.apply(command)
    assert [world.step().com.tolist() for _ in range(50)] == straight


def test_a_robot_without_an_mjcf_is_loaded_from_its_urdf() -> None:
    """The ASIMO-like robot (URDF only) in MuJoCo: a free base, the URDF's mass, its feet on the
    ground carrying its weight with C_bal's servos holding its starting posture."""
    profile = load_profile('asimo_like')
    world = MujocoWorld(profile, dt_s=0.001)
    assert world.total_mass == pytest.approx(profile.total_mass_kg, rel=1e-6)
    control = make_controller(profile, 'c_bal')
    posture = control.initial_posture()
    world.start(Posture(posture.joint_angles))
    names = control.joint_names
    world.apply(JointCommand(names, np.array([posture.joint_angles[n] for n in names])))
    for _ in range(500):
        m = world.step()
    load = m.left_contacts[:, 2].sum() + m.right_contacts[:, 2].sum()
    assert load == pytest.approx(world.total_mass * STANDARD_GRAVITY_M_S2, rel=0.01)
    # Each foot's F/T truth (in its sole frame) carries that foot's contact forces.
    truth = world.sensor_truth()
    for side, wrench in (('l', truth.left_wrench), ('r', truth.right_wrench)):
        forces = sum((f for _, f in world._last_contacts[side]), np.zeros(3))
        assert np.linalg.norm(wrench[:3]) == pytest.approx(np.linalg.norm(forces), rel=1e-9)


def test_a_sole_frame_turned_from_its_foot_link(tmp_path) -> None:
    """A foot link whose axes are not x forward, z up (as some robots' URDFs have them): the sole
    frame turned by the profile's ``sole_rpy_in_foot`` (URDF roll, pitch, yaw) has the same axes in
    the monitor's robot description (Pinocchio) as in the simulator's measurement, and a yaw of
    90 degrees turns the foot's heading by 90 degrees."""
    import math
    import shutil

    import pinocchio as pin
    import yaml

    from fall_predictor.monitor.rotations import rpy_matrix
    folder = tmp_path / 'g1'
    shutil.copytree(G1.source.parent, folder)
    raw = yaml.safe_load((folder / 'profile.yaml').read_text())
    for side in ('l', 'r'):
        raw['feet'][side]['sole_rpy_in_foot'] = [0.0, 0.0, math.pi / 2]
    (folder / 'profile.yaml').write_text(yaml.safe_dump(raw))
    turned = load_profile(folder / 'profile.yaml')
    robot = turned.sensor_layout().description(turned.urdf_xml())
    pin.framesForwardKinematics(robot.model, robot.data, pin.neutral(robot.model))
    sole = robot.data.oMf[robot.model.getFrameId('left_sole')].rotation
    link = robot.data.oMf[robot.model.getFrameId('left_ankle_roll_link')].rotation
    np.testing.assert_allclose(sole, link @ rpy_matrix(0.0, 0.0, math.pi / 2), atol=1e-12)
    straight, rotated = MujocoWorld(G1, dt_s=DT_S), MujocoWorld(turned, dt_s=DT_S)
    posture = make_controller(G1).initial_posture()
    a, b = straight.start(posture), rotated.start(posture)
    assert b.left_foot[2] == pytest.approx(a.left_foot[2] + math.pi / 2, abs=1e-9)
    np.testing.assert_allclose(b.left_foot[:2], a.left_foot[:2], atol=1e-12)


def test_a_base_on_slide_and_ball_joints_is_a_floating_base(tmp_path) -> None:
    """Some teams' MJCFs (humanoid-gym's) free the base with three slide joints and a ball joint
    instead of a free joint: the same robot then starts at the same pose and falls the same."""
    import re
    import shutil
    import yaml

    folder = tmp_path / 'g1'
    shutil.copytree(G1.source.parent, folder)
    xml = (folder / 'g1_12dof.xml').read_text()
    slides = ('<joint name="base_x" type="slide" axis="1 0 0" limited="false"/>'
              '<joint name="base_y" type="slide" axis="0 1 0" limited="false"/>'
              '<joint name="base_z" type="slide" axis="0 0 1" limited="false"/>'
              '<joint name="base_ball" type="ball" limited="false"/>')
    xml = re.sub(r'<joint name="floating_base_joint" type="free"[^>]*/>', slides, xml)
    (folder / 'g1_12dof.xml').write_text(xml)
    raw = yaml.safe_load((folder / 'profile.yaml').read_text())
    (folder / 'profile.yaml').write_text(yaml.safe_dump(raw))
    sliding = load_profile(folder / 'profile.yaml')
    posture = make_controller(G1).initial_posture()
    free, slid = MujocoWorld(G1, dt_s=DT_S), MujocoWorld(sliding, dt_s=DT_S)
    assert len(slid.base_dofs) == 6 and slid.total_mass == pytest.approx(free.total_mass)
    a, b = free.start(Posture(posture.joint_angles, 0.4)), slid.start(Posture(posture.joint_angles, 0.4))
    np.testing.assert_allclose(b.com, a.com, atol=1e-9)
    assert b.heading == pytest.approx(0.4)
    for world in (free, slid):
        world.apply(hold(world, posture))
    for _ in range(100):
        a, b = free.step(), slid.step()
    np.testing.assert_allclose(b.com, a.com, atol=2e-3)       # the same fall, other coordinates
