"""Measurements checked against physics."""
import numpy as np
import pybullet as pb
import pytest

from fall_predictor.robot.balance_controller import BalanceController
from fall_predictor.monitor.records import PushSpec
from fall_predictor.sim.pybullet_world import GRAVITY, PybulletWorld, PybulletConfig
from fall_predictor.sim.trajectory import run_trajectory


def _stand(sim, seconds):
    q0, torso = BalanceController().initial_posture()
    ms = [sim.reset(q0, torso)]
    for _ in range(int(seconds / sim.config.dt_s)):
        ms.append(sim.step())
    return ms


def test_standing_still_normal_force_carries_the_weight_and_cop_is_under_the_com(sim):
    ms = _stand(sim, 1.5)[-200:]
    weight = sim.total_mass * GRAVITY
    normal = np.array([m.left_contacts[:, 2].sum() + m.right_contacts[:, 2].sum() for m in ms])
    assert normal.mean() == pytest.approx(weight, rel=0.01)
    cop = np.array([m.cop[:2] for m in ms]).mean(axis=0)
    com = np.array([m.com[:2] for m in ms]).mean(axis=0)
    assert np.linalg.norm(cop - com) < 0.005
    assert np.abs(np.array([m.lin_mom for m in ms])).max() < 0.05
    assert not any(m.fallen for m in ms)
    # Both flat soles touch: the CoP lies between the feet.
    assert all(len(m.left_contacts) >= 3 and len(m.right_contacts) >= 3 for m in ms)


def _free_fall(sim, angular_velocity=(0.0, 0.0, 0.0)):
    q0, _ = BalanceController().initial_posture()
    sim.reset(q0, [0.0, 0.0, 5.0])
    pb.resetBaseVelocity(sim.robot, [0, 0, 0], list(angular_velocity), physicsClientId=sim.client)
    return sim.measure()


def test_free_fall_momentum_rate_is_the_weight(sim):
    first = _free_fall(sim)
    ms = [sim.step() for _ in range(200)]
    rate = (ms[-1].lin_mom - first.lin_mom) / (ms[-1].t - first.t)
    assert rate == pytest.approx([0.0, 0.0, -sim.total_mass * GRAVITY], abs=0.05)
    assert all(len(m.left_contacts) == 0 and len(m.right_contacts) == 0 and np.isnan(m.cop).all() for m in ms)


def test_free_fall_conserves_angular_momentum_about_the_com(sim):
    # Also checks the method's zero link damping, which PyBullet cannot report back: damping would
    # bleed the spin away.
    first = _free_fall(sim, angular_velocity=(0.8, -0.5, 1.2))
    assert np.linalg.norm(first.ang_mom) > 1.0          # a real spin, not a trivial zero
    ms = [sim.step() for _ in range(300)]
    for m in ms[::50]:
        assert np.allclose(m.ang_mom, first.ang_mom, rtol=0.02, atol=0.02)


def test_a_known_push_force_shows_up_in_the_momentum_rate(sim):
    _free_fall(sim)
    sim.schedule_push(PushSpec(force_n=120.0, angle_deg=90.0, height_m=0.1, t_push=0.02))
    ms = [sim.step() for _ in range(200)]
    by_t = {round(m.t, 3): m for m in ms}
    during = (by_t[0.1].lin_mom - by_t[0.03].lin_mom) / 0.07
    # Heading 0: 90 deg pushes along +y (to the robot's left).
    assert during == pytest.approx([0.0, 120.0, -sim.total_mass * GRAVITY], abs=0.2)
    after = (by_t[0.19].lin_mom - by_t[0.13].lin_mom) / 0.06
    assert after == pytest.approx([0.0, 0.0, -sim.total_mass * GRAVITY], abs=0.2)
    assert by_t[0.05].push_force == pytest.approx([0.0, 120.0, 0.0], abs=1e-9)
    assert not by_t[0.15].push_force.any()
    # The push is applied above the CoM: it also spins the robot (a moment about the CoM).
    assert abs(by_t[0.1].ang_mom[0]) > 0.5


def test_same_push_gives_an_identical_trajectory():
    push = PushSpec(force_n=180.0, angle_deg=40.0, height_m=0.12, t_push=1.3)
    a = run_trajectory(push, 2.5)
    b = run_trajectory(push, 2.5)
    assert np.array_equal(a.com, b.com)
    assert np.array_equal(a.joint_positions, b.joint_positions)


def test_an_unsupported_robot_ends_fallen():
    q0, torso = BalanceController().initial_posture()
    # Servo gains scaled to nothing: only the drives' friction resists, and the robot collapses.
    with PybulletWorld(config=PybulletConfig(actuation='pd_torque', servo_gain_scale=1e-9)) as limp:
        limp.reset(q0, torso)
        fallen_at = None
        for _ in range(3000):
            m = limp.step()
            if m.fallen:
                fallen_at = m.t
                break
    assert fallen_at is not None
    assert m.com[2] < 0.33 or m.non_foot_contact


def test_a_trajectory_from_a_walk_prefix_equals_one_from_a_fresh_world(sim):
    from fall_predictor.sim.trajectory import WalkPrefix
    prefix = WalkPrefix(sim, until_s=1.6, walk_duration_s=10.0)
    for push in (PushSpec(160.0, 120.0, 0.05, 1.234), PushSpec(90.0, -60.0, 0.2, 1.55)):
        warm = run_trajectory(push, 3.0, prefix=prefix)
        fresh = run_trajectory(push, 3.0)
        assert len(warm.measurements) == len(fresh.measurements)
        assert np.array_equal(warm.com, fresh.com)
        assert np.array_equal(warm.joint_positions, fresh.joint_positions)
        assert warm.t_reflex == fresh.t_reflex and warm.fallen == fresh.fallen


def test_a_run_goes_on_in_steps_while_asked_and_stops_at_its_cap():
    asked = []

    def twice(measurements):
        asked.append(measurements[-1].t)
        return len(asked) <= 2
    plain = run_trajectory(None, 0.5)
    extended = run_trajectory(None, 0.5, go_on_while=twice, max_extension_s=3.0)
    # Asked at the horizon and after each 0.5 s step; the third answer (no) ends the run.
    assert asked == pytest.approx([0.5, 1.0, 1.5])
    assert extended.measurements[-1].t == pytest.approx(1.5)
    # Going on changes nothing before the horizon (the walk planned for longer is the same walk).
    n = len(plain.measurements)
    assert np.array_equal(extended.joint_positions[:n], plain.joint_positions)
    capped = run_trajectory(None, 0.5, go_on_while=lambda measurements: True, max_extension_s=0.7)
    assert capped.measurements[-1].t == pytest.approx(1.2)


def test_quaternions_to_matrices_matches_pybullet():
    """The measurement's quaternion conversion against PyBullet's own, and orthonormal."""
    import pybullet

    from fall_predictor.sim.pybullet_state import quaternions_to_matrices
    q = np.random.default_rng(13).normal(size=(500, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    rots = quaternions_to_matrices(q)
    for quaternion, rot in zip(q[:50], rots[:50]):
        assert np.allclose(np.array(pybullet.getMatrixFromQuaternion(quaternion)).reshape(3, 3), rot, atol=1e-12)
    assert np.allclose(rots @ rots.transpose(0, 2, 1), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(rots), 1.0, atol=1e-12)


def test_quaternions_to_matrices_is_the_written_out_formula_bit_for_bit():
    """The vectorised conversion computes each entry as the written-out expression does (signed
    zeros too), into a C-ordered array: the measurement's sums, and so every trajectory, depend
    on both."""
    from fall_predictor.sim.pybullet_state import quaternions_to_matrices
    q = np.random.default_rng(14).normal(size=(2000, 13))[:, 3:7]     # a strided view, as measured
    q[:4] = [[0.0, 0.0, 0.0, 1.0], [-0.0, 0.0, -0.0, 1.0], [0.5, -0.5, 0.5, -0.5], [1.0, 0.0, 0.0, 0.0]]
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    written = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
                        2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                        2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
                       axis=1).reshape(-1, 3, 3)
    rots = quaternions_to_matrices(q)
    assert rots.flags['C_CONTIGUOUS']
    assert np.array_equal(rots.view(np.int64), written.view(np.int64))


def test_a_slab_ground_carries_a_standing_robot_as_the_plane_does():
    """The G1 stands on a slab ground (its profile's): the soles touch its top face at z = 0, the
    weight is carried, and the CoM stands within a millimetre of where it stands on a plane."""
    from dataclasses import replace
    from fall_predictor.profiles.profile import load_profile
    from fall_predictor.robot.balance_controller import controller_configs
    g1 = load_profile('g1')
    assert g1.sim_ground == 'slab'
    standing = replace(controller_configs(g1)[0], standing=True)
    com = {}
    for ground in ('slab', 'plane'):
        profile = replace(g1, sim_ground=ground)
        controller = BalanceController(profile=profile, gait=standing)
        with PybulletWorld(profile=profile) as sim:
            m = sim.reset(*controller.initial_posture())
            while m.t < 1.0:
                sim.set_joint_targets(controller.update(m))
                m = sim.step()
            heights = [cp[6][2] for cp in sim.ground_contacts()]
        assert not m.fallen and len(heights) == 8          # four spheres a sole
        assert max(abs(z) for z in heights) < 1e-3
        normal = m.left_contacts[:, 2].sum() + m.right_contacts[:, 2].sum()
        assert normal == pytest.approx(g1.total_mass_kg * GRAVITY, rel=0.02)
        com[ground] = m.com
    assert np.abs(com['slab'] - com['plane']).max() < 1e-3


def test_a_policy_posture_stands_on_the_ground_and_relative_meshes_load_from_the_copy():
    """A learned policy's posture gives no base position: PyBullet lowers the robot until its
    lowest geometry touches the ground (as MuJoCo does); the 12-joint G1's URDF names its meshes
    relative to its folder, and the rewritten copy PyBullet loads must still find them."""
    from fall_predictor.profiles.profile import load_profile
    from fall_predictor.robot.control import make_controller
    from fall_predictor.sim.urdf_loading import pybullet_urdf
    profile = load_profile('g1_12dof')
    copy = pybullet_urdf(profile.sim_urdf_path).read_text()
    mesh_dir = profile.sim_urdf_path.resolve().parent / 'meshes'
    assert f'filename="{mesh_dir}/' in copy and 'filename="meshes/' not in copy
    controller = make_controller(profile, 'unitree_rl_gym')
    sim = PybulletWorld(profile, dt_s=controller.policy.config.physics_dt_s)
    try:
        m = sim.start(controller.initial_posture())
        gaps = [p[8] for p in pb.getClosestPoints(sim.robot, sim.plane, 1.0, physicsClientId=sim.client)]
        assert min(gaps) == pytest.approx(0.001, abs=2e-4)
        for _ in range(int(round(1.0 / sim.dt_s))):   # 1 s in its posture, the drives holding it
            m = sim.step()
        # It settles onto its feet: the weight is carried, the CoM neither sinks nor jumps.
        assert m.left_contacts[:, 2].sum() + m.right_contacts[:, 2].sum() == pytest.approx(
            sim.total_mass * GRAVITY, rel=0.1)
        assert 0.6 < m.com[2] < 0.8
    finally:
        sim.close()
