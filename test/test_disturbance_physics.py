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
def test_a_step_downs_onset_is_a_toe_crossing_the_edge_and_the_robot_comes_down_by_its_height(simulator):
    height = 0.05
    result, steps = _run(simulator, Disturbance('step', terrain=step_terrain('down', 0.5, height),
                                                edge_x_m=0.5), 5.0, command=(0.4, 0.0, 0.0))
    onset = result.extras['t_onset']
    half = load_profile(ROBOT).feet['l'].sole().length_m / 2
    crossed = next(t for t, m, *_ in steps
                   if max(f[0] + half * math.cos(f[2]) for f in (m.left_foot, m.right_foot)) > 0.5)
    assert onset == crossed
    assert not result.fallen
    # Against the same walk on flat ground: the robot starts on the platform, and ends its height
    # lower, walking as on the flat.
    flat, flat_steps = _run(simulator, None, 5.0, command=(0.4, 0.0, 0.0))
    com = np.array([m.com for _, m, *_ in steps])
    flat_com = np.array([m.com for _, m, *_ in flat_steps])
    assert com[0, 2] - flat_com[0, 2] == pytest.approx(height, abs=0.002)
    assert com[-250:, 2].mean() == pytest.approx(flat_com[-250:, 2].mean(), abs=0.01)


@pytest.mark.parametrize('simulator', ENGINES)
@pytest.mark.parametrize('mode', ['lost', 'fade', 'stuck'])
def test_a_faulty_joints_torque_is_lost_faded_or_it_is_stuck_from_the_onset(simulator, mode):
    profile = load_profile(ROBOT)
    joint = 'left_knee_joint' if mode != 'stuck' else 'left_hip_pitch_joint'
    j = profile.joint_names.index(joint)
    fault = JointFault(joint, mode, 2.0, torque_scale=0.0, fade_s=0.4)
    result, steps = _run(simulator, Disturbance('fault', fault=fault), 3.0, stop_when_fallen=False)
    onset = result.extras['t_onset']
    assert onset == pytest.approx(2.0, abs=0.003)
    t = np.array([s[0] for s in steps])
    tau = np.array([s[3][j] for s in steps])
    q = np.array([s[4][j] for s in steps])
    # The torque of step k acted from t[k-1]: the first step after the onset is the fault's.
    before, after = t <= onset - 0.01, t > onset + 0.005
    assert np.abs(tau[before]).max() > 1.0
    if mode == 'lost':
        assert np.all(tau[after] == 0.0)
    elif mode == 'fade':
        assert np.all(tau[t > onset + 0.4 + 0.005] == 0.0)
        assert np.abs(tau[(t > onset) & (t < onset + 0.1)]).max() > 0.5
    else:
        assert np.ptp(q[before & (t > 1.0)]) > 0.05              # it moved while sound
        stuck_at = q[int(np.searchsorted(t, onset))]
        assert np.abs(q[after] - stuck_at).max() <= STUCK_PLAY_RAD + 0.01


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
