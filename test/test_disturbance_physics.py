"""Each disturbance beyond pushes does in both engines what physics says (sim/disturbances.py): the
G1 under Unitree's policy walks into a box, onto a slippery patch, off a step, with a failing
joint, and through changing commands."""
import math

import numpy as np
import pytest

from fall_predictor.profiles.profile import load_profile
from fall_predictor.sim.disturbances import (STUCK_PLAY_RAD, CommandSchedule, Disturbance, JointFault,
                                             slip_patch, step_terrain, trip_box)
from fall_predictor.sim.policy_runs import load_learned_policy, policy_run
from fall_predictor.sim.trajectory import run_trajectory
from fall_predictor.sim.world import make_world

ROBOT = 'g1_12dof'
ENGINES = ('mujoco', 'pybullet')
_POLICY = {}


def _run(simulator, disturbance, duration_s, command=(0.5, 0.0, 0.0), stop_when_fallen=True):
    """A run of the G1 under its policy with ``disturbance``; per step: (t, measurement, terrain
    contacts, joint torques, joint positions, the policy's command)."""
    profile = load_profile(ROBOT)
    policy = profile.controller_profile()
    if 'learned' not in _POLICY:
        _POLICY['learned'] = load_learned_policy(policy)
    learned = _POLICY['learned']
    world = make_world(profile, simulator, learned.physics_dt_s)
    args = policy_run(profile, policy, learned, command, 1.0, 0, world)
    steps = []

    def record(w, m):
        q, _, tau = w.joint_states()
        steps.append((m.t, m, w.terrain_contacts(), tau, q, args['controller'].velocity_command))
    result = run_trajectory(None, duration_s, disturbance=disturbance, on_step=record,
                            stop_when_fallen=stop_when_fallen, **args)
    world.close()
    return result, steps


@pytest.mark.parametrize('simulator', ENGINES)
def test_a_trips_onset_is_the_first_contact_with_the_box_and_the_foot_is_stopped(simulator):
    box = trip_box(0.7, 0.08, 0.06)
    result, steps = _run(simulator, Disturbance('trip', terrain=(box,)), 4.0)
    onset = result.extras['t_onset']
    touching = [(t, contacts) for t, _, contacts, *_ in steps if contacts]
    assert onset is not None and touching[0][0] == onset
    t_first, contacts = touching[0]
    side = contacts[0].side
    assert side in ('l', 'r')                       # a foot caught it
    # On the box's near face or its top edge.
    point = contacts[0].point_m
    assert 0.69 <= point[0] <= 0.7 + 0.06 + 0.01 and point[2] <= 0.08 + 0.01
    t = np.array([s[0] for s in steps])
    foot = np.array([(s[1].left_foot if side == 'l' else s[1].right_foot)[:2] for s in steps])
    k = int(np.searchsorted(t, onset))
    window = max(3, int(round(0.03 / (t[1] - t[0]))))
    before = np.linalg.norm(foot[k] - foot[k - window]) / (t[k] - t[k - window])
    after = np.linalg.norm(foot[k + window] - foot[k]) / (t[k + window] - t[k])
    assert before > 0.3 and after < 0.5 * before
    # A link other than a foot resting on the box (a shin over it) is no fall: only the ground's are.
    fallen_m = load_profile(ROBOT).fallen_com_height_m
    assert not any(m.non_foot_contact for _, m, *_ in steps if m.com[2] > fallen_m + 0.1)


@pytest.mark.parametrize('simulator', ENGINES)
def test_on_a_slip_patch_the_contact_friction_is_the_patchs(simulator):
    mu = 0.1
    patch = slip_patch(0.3, mu)
    result, steps = _run(simulator, Disturbance('slip', terrain=(patch,)), 3.5, command=(0.6, 0.0, 0.0))
    assert result.extras['t_onset'] is not None
    ratios = np.array([np.linalg.norm(c.friction_force_n) / np.linalg.norm(c.normal_force_n)
                       for step in steps for c in step[2] if np.linalg.norm(c.normal_force_n) > 20.0])
    assert ratios.size > 50
    # Coulomb's law with the patch's friction (both engines' pyramidal cones: up to sqrt(2) mu
    # along a diagonal), and sliding feet reach it: not the feet's own friction of 1.
    assert ratios.max() <= math.sqrt(2) * mu * 1.02
    assert ratios.max() >= 0.7 * mu


@pytest.mark.parametrize('simulator', ENGINES)
def test_the_g1_walking_onto_a_slip_patch_slides_its_stance_feet(simulator):
    """Walking at 0.5 m/s onto a patch of friction 0.1 (below what its gait asks of the ground), a
    foot carrying weight slides on the patch (MuJoCo ~0.47 m/s, PyBullet ~0.2-0.3 m/s median),
    where on the ground before it a stance foot stands still (< 5 mm/s)."""
    _, steps = _run(simulator, Disturbance('slip', terrain=(slip_patch(0.5, 0.1),)), 4.0)
    t = np.array([s[0] for s in steps])
    for side in ('left', 'right'):
        xy = np.array([getattr(m, f'{side}_foot')[:2] for _, m, *_ in steps])
        load = np.array([getattr(m, f'{side}_contacts')[:, 2].sum() for _, m, *_ in steps])
        speed = np.r_[0.0, np.linalg.norm(np.diff(xy, axis=0), axis=1) / np.diff(t)]
        stance = load > 150.0
        on_ground = stance & (xy[:, 0] < 0.4) & (t > 0.5)
        on_patch = stance & (xy[:, 0] > 0.6)
        assert on_ground.sum() > 100 and on_patch.sum() > 100
        assert np.median(speed[on_ground]) < 0.005
        assert np.median(speed[on_patch]) > 0.1


def _block_deceleration(simulator: str, mu: float, v0_m_s: float = 2.0) -> float:
    """A 10 kg block (0.2 x 0.2 x 0.1 m) sent at ``v0_m_s`` along +x on a slip patch of friction
    ``mu``, laid as the worlds lay it: its deceleration over the slide [m/s^2]."""
    patch = slip_patch(0.5, mu)
    samples = []
    if simulator == 'mujoco':
        import mujoco
        from fall_predictor.sim.mujoco_model import compile_with_terrain
        spec = mujoco.MjSpec()
        spec.worldbody.add_geom(name='floor', type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])
        block = spec.worldbody.add_body(pos=[1.0, 0.0, 0.05])
        block.add_freejoint()
        block.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.05], mass=10.0)
        m = compile_with_terrain(spec, (patch,))
        d = mujoco.MjData(m)
        for _ in range(100):
            mujoco.mj_step(m, d)
        d.qvel[0] = v0_m_s
        for _ in range(300):
            mujoco.mj_step(m, d)
            samples.append((d.time, d.qvel[0]))
    else:
        import pybullet as pb
        from fall_predictor.sim.pybullet_terrain import add_box, ground_of_boxes
        c = pb.connect(pb.DIRECT)
        pb.setGravity(0, 0, -9.81, physicsClientId=c)
        pb.setTimeStep(0.001, physicsClientId=c)
        ground_of_boxes(c, (patch,))
        add_box(c, patch)
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.1, 0.1, 0.05], physicsClientId=c)
        block = pb.createMultiBody(10.0, shape, -1, [1.0, 0.0, 0.05], physicsClientId=c)
        # The feet's friction (PybulletConfig.foot_friction; Bullet multiplies the two); no
        # velocity damping (Bullet's default on a free body: 0.04 (1 + |v|) v).
        pb.changeDynamics(block, -1, lateralFriction=1.0, linearDamping=0.0, angularDamping=0.0,
                          physicsClientId=c)
        for _ in range(100):
            pb.stepSimulation(physicsClientId=c)
        pb.resetBaseVelocity(block, [v0_m_s, 0.0, 0.0], physicsClientId=c)
        for k in range(300):
            pb.stepSimulation(physicsClientId=c)
            samples.append(((k + 1) * 0.001, pb.getBaseVelocity(block, physicsClientId=c)[0][0]))
        pb.disconnect(c)
    t, v = np.array(samples).T
    sliding = v > 0.2
    return -float(np.polyfit(t[sliding], v[sliding], 1)[0])


@pytest.mark.parametrize('simulator', ENGINES)
@pytest.mark.parametrize('mu', [0.05, 0.3])
def test_a_block_sliding_on_a_slip_patch_decelerates_at_its_friction_times_g(simulator, mu):
    assert _block_deceleration(simulator, mu) == pytest.approx(mu * 9.81, rel=0.03)


def _ground_contacts(world) -> list[tuple[str, float, float]]:
    """Every loaded contact of the robot with anything not the robot, whatever the engine:
    (what it touches, normal force [N], tangential force [N])."""
    out = []
    if simulator_of(world) == 'mujoco':
        import mujoco
        m, d, force6 = world.model, world.data, np.zeros(6)
        for i in range(d.ncon):
            g1, g2 = int(d.contact[i].geom1), int(d.contact[i].geom2)
            if (m.geom_bodyid[g1] == 0) == (m.geom_bodyid[g2] == 0):
                continue
            mujoco.mj_contactForce(m, d, i, force6)
            ground = g1 if m.geom_bodyid[g1] == 0 else g2
            out.append((mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, ground), force6[0],
                        math.hypot(force6[1], force6[2])))
    else:
        import pybullet as pb
        for cp in pb.getContactPoints(bodyA=world.robot, physicsClientId=world.client):
            if cp[2] != world.robot:
                name = 'patch' if cp[2] in world.terrain_bodies else 'ground'
                out.append((name, cp[9], math.hypot(cp[10], cp[12])))
    return [c for c in out if c[1] > 1.0]


def simulator_of(world) -> str:
    return 'mujoco' if hasattr(world, 'data') else 'pybullet'


@pytest.mark.parametrize('simulator', ENGINES)
def test_a_foot_on_a_slip_patch_touches_nothing_but_the_patch(simulator):
    """The patch is flush with the ground and nothing lies under it: the feet of the G1 marching
    in place on it (its policy at a zero command) touch the patch alone, every contact within
    its Coulomb cone (the ground beneath a sheet, which Bullet's contact margin and MuJoCo's
    sphere soles still felt at a friction of 1, is gone)."""
    mu = 0.05
    contacts = []
    profile = load_profile(ROBOT)
    policy = profile.controller_profile()
    learned = _POLICY.setdefault('learned', load_learned_policy(policy))
    world = make_world(profile, simulator, learned.physics_dt_s)
    args = policy_run(profile, policy, learned, (0.0, 0.0, 0.0), 1.0, 0, world)
    run_trajectory(None, 1.5, disturbance=Disturbance('slip', terrain=(slip_patch(-1.0, mu),)),
                   on_step=lambda w, m: contacts.extend(_ground_contacts(w)), **args)
    world.close()
    loaded = [(name, t / n) for name, n, t in contacts if n > 20.0]
    assert len(loaded) > 500
    assert {name for name, *_ in contacts} == {'terrain_0' if simulator == 'mujoco' else 'patch'}
    # MuJoCo's pyramid lies inside the cone; Bullet's two friction directions reach sqrt(2) mu.
    bound = mu * (1.02 if simulator == 'mujoco' else math.sqrt(2) * 1.02)
    assert max(r for _, r in loaded) <= bound


@pytest.mark.parametrize('simulator', ENGINES)
def test_a_robot_standing_on_a_slip_patch_slides_only_when_pushed(simulator):
    """The G1 held stiffly in its standing posture on a patch of friction 0.05 stays put
    (standing asks no friction of the ground); pushed forward with 60 N for 0.1 s (more than
    mu m g = 17 N) its feet slide, where on the ground the same push moves them by nothing."""
    from fall_predictor.monitor.records import PushSpec
    from fall_predictor.robot.control import HoldControl, JointCommand, PolicyControl
    profile = load_profile(ROBOT)
    learned = _POLICY.setdefault('learned', load_learned_policy(profile.controller_profile()))
    held = PolicyControl(learned, (0.0, 0.0, 0.0)).hold_command()
    n = len(held.joint_names)
    # Stiff enough to stand as a rigid body (the policy's own gains let it tip over).
    stiff = JointCommand(held.joint_names, held.targets_rad, np.full(n, 400.0), np.full(n, 10.0))
    patch = Disturbance('slip', terrain=(slip_patch(-1.0, 0.05),))
    push = PushSpec(60.0, 0.0, 0.0, 1.0, 0.1)
    moved = []
    for disturbance, pushed in ((patch, None), (patch, push), (None, push)):
        world = make_world(profile, simulator, learned.physics_dt_s)
        feet = []
        run_trajectory(pushed, 2.0, world=world, controller=HoldControl(stiff, 0.02),
                       disturbance=disturbance, stop_when_fallen=False,
                       on_step=lambda w, m: feet.append(np.r_[m.left_foot[:2], m.right_foot[:2]]))
        world.close()
        feet = np.array(feet)
        moved.append(np.abs(feet[-1] - feet[len(feet) // 4]).max())     # from 0.5 s (settled) on
    still, pushed_on_patch, pushed_on_ground = moved
    assert still < 0.002 and pushed_on_ground < 0.002
    assert pushed_on_patch > 0.005


@pytest.mark.parametrize('simulator', ENGINES)
def test_a_long_walks_commands_change_at_the_drawn_times(simulator):
    schedule = CommandSchedule((0.0, 1.0, 2.2), ((0.0, 0.0, 0.0), (0.4, 0.0, 0.0), (0.2, 0.0, 0.5)))
    result, steps = _run(simulator, Disturbance('walk', schedule=schedule), 4.0, command=(0.0, 0.0, 0.0))
    assert not result.fallen and result.extras['t_onset'] is None
    changes = [(t, cmd) for (t, _, _, _, _, cmd), (_, _, _, _, _, prev) in zip(steps[1:], steps)
               if cmd != prev]
    period = 0.02                                  # the policy's control period
    assert [c for _, c in changes] == [(0.4, 0.0, 0.0), (0.2, 0.0, 0.5)]
    for (t, _), drawn in zip(changes, (1.0, 2.2)):
        assert drawn <= t <= drawn + period + 0.01
    heading = np.unwrap([m.heading for _, m, *_ in steps])
    t = np.array([s[0] for s in steps])
    # Turning at 0.5 rad/s for the last second and more.
    assert heading[-1] - heading[t >= 3.0][0] > 0.2


def test_a_world_reused_across_causes_is_nominal_again_for_each_run():
    """A stuck joint, then a terrain run, then a flat one in one MuJoCo world (as a dataset's
    worker runs them): the flat run's model is the pristine one (no joint left stuck)."""
    from fall_predictor.sim.randomization import WorldRandomization
    profile = load_profile(ROBOT)
    policy = profile.controller_profile()
    learned = load_learned_policy(policy)
    world = make_world(profile, 'mujoco', learned.physics_dt_s)
    pristine = (world.model.jnt_range.copy(), world.model.jnt_limited.copy(), world.model.body_mass.copy(),
                world.model.geom_friction.copy())
    stuck = Disturbance('fault', fault=JointFault('left_knee_joint', 'stuck', 0.5))
    for disturbance, randomization in ((stuck, WorldRandomization(friction=0.4, link_mass_scale=1.1)),
                                       (Disturbance('trip', terrain=(trip_box(0.5, 0.03, 0.05),)), None)):
        run_trajectory(None, 1.0, disturbance=disturbance, randomization=randomization,
                       **policy_run(profile, policy, learned, (0.3, 0.0, 0.0), 1.0, 0, world))
    run_trajectory(None, 0.1, **policy_run(profile, policy, learned, (0.3, 0.0, 0.0), 1.0, 0, world))
    now = (world.model.jnt_range, world.model.jnt_limited, world.model.body_mass, world.model.geom_friction)
    assert all(np.array_equal(a, b) for a, b in zip(pristine, now))
    world.close()
