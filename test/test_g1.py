"""The Unitree G1 in the simulator under the balance controller (robot profile 'g1'): it stands,
it walks, it survives small pushes while walking and falls from a large one; and its simulated
sensors (efforts, pelvis IMU, no foot F/T) give the estimator its state."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from fall_predictor.monitor.estimator import StateEstimator
from fall_predictor.monitor.records import PushSpec
from fall_predictor.profiles.profile import load_profile
from fall_predictor.robot.balance_controller import BalanceController, controller_configs
from fall_predictor.sim.sensors import SensorParams, apply_sensors
from fall_predictor.sim.pybullet_world import GRAVITY, PybulletWorld
from fall_predictor.sim.trajectory import gait_run, run_trajectory
from fall_predictor.sim.world import make_world

G1 = load_profile('g1')


@pytest.fixture(scope='module')
def sim():
    with PybulletWorld(profile=G1) as simulator:
        yield simulator


def test_the_simulated_g1_is_the_urdf_robot(sim):
    """The PyBullet model weighs what the URDF says (no default 1 kg on its frame links) and
    moves the profile's joints in the URDF's order."""
    run_trajectory(None, 0.01, world=sim)
    assert sim.total_mass == pytest.approx(G1.total_mass_kg, abs=1e-5)
    assert sim.joint_names == G1.joint_names and len(sim.joint_names) == 29


def test_g1_stands_ten_seconds(sim):
    standing = replace(controller_configs(G1)[0], standing=True)
    run = run_trajectory(None, 10.0, **gait_run(sim, standing, 10.0))
    assert not run.fallen
    com = np.array([m.com for m in run.measurements[1000:]])
    # Still: the CoM moves less than 5 mm; the weight is on the soles; the feet stay put.
    assert np.ptp(com, axis=0).max() < 0.005
    last = run.measurements[-1]
    normal = last.left_contacts[:, 2].sum() + last.right_contacts[:, 2].sum()
    assert normal == pytest.approx(G1.total_mass_kg * GRAVITY, rel=0.02)
    first = run.measurements[1000]
    for a, b in ((first.left_foot, last.left_foot), (first.right_foot, last.right_foot)):
        assert np.linalg.norm(a[:2] - b[:2]) < 0.002


def test_g1_walks_ten_seconds(sim):
    """The profile's gait (0.08 m steps, 0.35 s single and 0.2 s double support): the CoM advances
    at the pattern's speed, keeps its height and heading, and every step lands near its plan."""
    gait = controller_configs(G1)[0]
    run = run_trajectory(None, 10.0, world=sim)
    assert not run.fallen and run.t_reflex is None
    ms = run.measurements
    com = np.array([m.com for m in ms])
    # Steps start after initial_stand_s + double_support_s; the first is half a step.
    steps = (10.0 - gait.initial_stand_s) / (gait.single_support_s + gait.double_support_s)
    planned_x = (steps - 1.5) * gait.step_length_m
    # Each swing lags its plan and lands its sole about 1 cm short (the plan then follows the
    # measured foothold): up to 1.2 cm a step behind the plan, never ahead by more than 0.1 m.
    assert planned_x - 0.012 * steps < com[-1, 0] - com[0, 0] < planned_x + 0.1
    assert np.ptp(com[1000:, 2]) < 0.01 and abs(com[-1, 1]) < 0.1
    assert max(abs(m.heading) for m in ms) < math.radians(2.0)
    # Feet that land and stay: the soles are never both off the ground, and a planted sole's
    # lateral offset stays the stance width within 2 cm.
    assert not any(len(m.left_contacts) == 0 and len(m.right_contacts) == 0 for m in ms[100:])
    assert all(abs(m.left_foot[1] - gait.stance_half_width_m) < 0.02
               and abs(m.right_foot[1] + gait.stance_half_width_m) < 0.02 for m in ms[::100])


@pytest.mark.parametrize('push, falls', [
    (PushSpec(40.0, 0.0, 0.1, 2.0), False),       # forward, while walking
    (PushSpec(60.0, 90.0, 0.1, 2.0), False),      # sideways
    (PushSpec(220.0, 0.0, 0.1, 2.0), True),       # forward, beyond any recovery
])
def test_g1_pushes(sim, push, falls):
    run = run_trajectory(push, 4.5, world=sim)
    assert run.fallen is falls
    if falls:
        assert push.t_push < run.t_fallen < push.t_push + 2.0
    else:
        # Recovered: no launch, the CoM back near its height (the reflex lowers it 2 cm).
        z = np.array([m.com[2] for m in run.measurements])
        assert z.max() < z[0] + 0.02 and abs(z[-1] - z[0]) < 0.03


def test_g1_sensors_give_the_estimator_its_state():
    """Efforts (0.5 N m noise), the pelvis IMU and no F/T, over 4 s of walking with a recovered
    sideways push: the estimated CoM and CoP against the simulator's."""
    run = run_trajectory(PushSpec(60.0, 90.0, 0.1, 2.0), 4.0, record_sensors=True, world=make_world(G1))
    readings = apply_sensors(run.sensor_truths, SensorParams(), seed=3, profile=G1)
    assert readings[0].left_wrench is None and readings[0].imu_frame == 'imu_in_pelvis'
    robot = G1.sensor_layout().description(G1.urdf_xml())
    estimates = StateEstimator(robot, imu_frame=G1.imu_frame, effort_feet=('l', 'r')).run(readings)
    pairs = [(a, b) for a, b in zip(estimates, run.measurements) if a is not None]
    assert len(pairs) >= len(readings) - 5
    com = np.array([np.linalg.norm(a.com - b.com) for a, b in pairs])
    cop = np.array([np.linalg.norm((a.cop - b.cop)[:2]) for a, b in pairs
                    if np.isfinite(a.cop).all() and np.isfinite(b.cop).all()])
    print(f'G1 CoM p99 {np.percentile(com, 99) * 1000:.1f} mm, CoP median {np.median(cop) * 1000:.1f} mm, '
          f'p90 {np.percentile(cop, 90) * 1000:.1f} mm')
    assert np.percentile(com, 99) <= 0.02 and np.median(cop) <= 0.01


def test_a_reflex_step_held_on_a_just_landed_foot_is_balanced_where_that_foot_stands(sim):
    """A 10 N s push forward and to the left (30 deg) as the left foot touches down: the reflex
    steps with that foot, which must first unload; while it waits, the stabilizer's support polygon
    has the foot where it landed, more than 10 cm from its previous foothold (it had kept the old
    foothold, pinning the desired ZMP to the other toe), and the walk recovers."""
    gait, reflex, stabilizer = controller_configs(G1)
    controller = BalanceController(gait, reflex, stabilizer=stabilizer, profile=G1)
    q0, torso = controller.initial_posture()
    m = sim.reset(q0, torso)
    sim.schedule_push(PushSpec(100.0, 30.0, 0.1, 3.21))
    previous, held_ticks, lift = None, [], None
    while m.t < 5.7 and not m.fallen:
        feet_before = {side: controller.feet[side].copy() for side in controller.feet}
        sim.set_joint_targets(controller.update(m))
        event = controller.reflex_event
        if event is not None:
            previous = feet_before[event.side] if previous is None else previous
            step = controller._reflex_step
            if lift is not None and step.t_lift > lift + 1e-9:        # held down this tick
                stands = (m.left_foot if event.side == 'l' else m.right_foot)[:2]
                held_ticks.append((controller.feet[event.side].copy(), np.array(step.start), stands))
            lift = step.t_lift
        m = sim.step()
    assert event is not None and event.side == 'l'
    assert len(held_ticks) > 100                             # waited > 0.1 s for the foot to unload
    for believed, start, stands in held_ticks:
        assert np.linalg.norm(start - previous) > 0.1        # the foot had stepped on
        np.testing.assert_array_equal(believed, start)
        assert np.linalg.norm(believed - stands) < 0.025
    assert not m.fallen


def test_a_trajectory_from_a_walk_prefix_does_not_depend_on_the_ones_run_before_it():
    """The G1's soles collide through several spheres each, whose contacts PyBullet's restoreState
    hands back by body pair: a pushed trajectory started from a walk prefix came out differently
    after another trajectory had run on that prefix (generation's workers each run many, so a
    dataset depended on their scheduling). Run alone, again, and after a fall, it is the same bit
    for bit, and it starts from the walk's own samples."""
    from fall_predictor.sim.trajectory import WalkPrefix
    prefix = WalkPrefix(PybulletWorld(profile=G1), until_s=2.8, walk_duration_s=10.0)
    try:
        push = PushSpec(100.0, 100.0, 0.1, 2.75)
        alone = run_trajectory(push, 3.4, prefix=prefix)
        again = run_trajectory(push, 3.4, prefix=prefix)
        fall = run_trajectory(PushSpec(180.0, 0.0, 0.1, 2.5), 4.0, prefix=prefix)
        after_a_fall = run_trajectory(push, 3.4, prefix=prefix)
    finally:
        prefix.sim.close()
    assert fall.fallen
    for other in (again, after_a_fall):
        assert len(other.measurements) == len(alone.measurements)
        np.testing.assert_array_equal(other.com, alone.com)
        np.testing.assert_array_equal(other.joint_positions, alone.joint_positions)
    walk = prefix.run.measurements
    np.testing.assert_array_equal(alone.com[:2701], np.array([m.com for m in walk[:2701]]))


def test_a_backward_push_that_fells_the_g1_does_not_launch_it(sim):
    """A 19 N s push backwards: the reflex steps back and the G1 falls over its stance foot. The
    swing leg, solved both upright and for the measured tilt each tick, once took its warm start
    from the other solve; the solver ended on another branch (hip at its limits, targets 3 rad
    away in one tick) and the flailing leg threw the robot 4 cm up, both feet off the ground,
    into a somersault. Now the CoM never rises, and the feet never leave the ground while the
    body moves up (they do for a few tens of milliseconds as it drops, the stance foot sliding
    out in the fall)."""
    gait, reflex, stabilizer = controller_configs(G1)
    controller = BalanceController(gait, reflex, stabilizer=stabilizer, profile=G1)
    q0, torso = controller.initial_posture()
    m = sim.reset(q0, torso)
    push = PushSpec(force_n=186.0, angle_deg=-161.0, height_m=0.01, t_push=2.7)
    sim.schedule_push(push)
    z_push, rise, airborne_rising = None, 0.0, 0
    while m.t < push.t_push + 1.2 and not m.fallen:
        sim.set_joint_targets(controller.update(m))
        m = sim.step()
        if m.t >= push.t_push:
            z_push = m.com[2] if z_push is None else z_push
            rise = max(rise, m.com[2] - z_push)
            airborne_rising += (len(m.left_contacts) + len(m.right_contacts) == 0
                                and m.lin_mom[2] > 0.0)
    assert controller.reflex_event is not None and m.fallen
    assert rise < 0.005 and airborne_rising == 0
