"""The disturbances beyond pushes, engine-free: faults' torque profiles, long walks' command
schedules, each cause's terrain, the draws and the cause mix of a dataset (physics in both
engines: test_disturbance_physics.py)."""
import math

import numpy as np
import pytest

from fall_predictor.data.dataset import CAUSES as INDEX_CAUSES
from fall_predictor.data.disturbance_generation import parse_causes, run_cause
from fall_predictor.profiles.profile import load_profile
from fall_predictor.profiles.cause_ranges import parse_cause_ranges
from fall_predictor.sim.disturbance_runs import (DEFAULT_RANGES, cause_ranges, fault_joints,
                                                 sample_disturbance, walker_for)
from fall_predictor.sim.disturbances import (CAUSES, CommandSchedule, FaultProtocol, JointFault,
                                             TerrainBox, ground_around, slip_patch, start_height_m,
                                             step_terrain, trip_box)


def test_the_simulator_and_the_index_name_the_same_causes():
    assert CAUSES == INDEX_CAUSES


@pytest.mark.parametrize('mode, expected', [
    # before the start, at it, half-way through a 2 s fade, after it
    ('lost', [1.0, 0.25, 0.25, 0.25]),
    ('fade', [1.0, 1.0, 0.625, 0.25]),
    ('stuck', [1.0, 1.0, 1.0, 1.0]),
])
def test_a_faults_torque_share_follows_its_mode(mode, expected):
    fault = JointFault('knee', mode, 1.0, torque_scale=0.25, fade_s=2.0)
    assert [fault.torque_scale_at(t) for t in (0.5, 1.0, 2.0, 4.0)] == pytest.approx(expected)


def test_an_intermittent_fault_is_on_for_its_duty_of_every_period():
    fault = JointFault('knee', 'intermittent', 1.0, torque_scale=0.0, period_s=0.4, duty=0.25)
    t = np.arange(1.0, 3.0, 0.001)
    share = np.array([fault.torque_scale_at(x) for x in t])
    assert set(share) == {0.0, 1.0} and share.mean() == pytest.approx(0.75, abs=0.01)
    assert fault.torque_scale_at(1.05) == 0.0 and fault.torque_scale_at(1.15) == 1.0


def test_the_fault_protocol_scales_one_joint_and_locks_a_stuck_one_where_it_was():
    protocol = FaultProtocol()
    protocol.schedule(JointFault('b', 'lost', 1.0, torque_scale=0.0), ('a', 'b', 'c'))
    tau = np.array([1.0, 2.0, 3.0])
    assert protocol.torques(0.9, tau) is tau
    assert protocol.torques(1.0, tau).tolist() == [1.0, 0.0, 3.0]
    protocol.schedule(JointFault('c', 'stuck', 1.0), ('a', 'b', 'c'))
    assert protocol.stuck_joint(0.5, np.array([0, 0, 0.3])) is None
    assert protocol.stuck_joint(1.0, np.array([0, 0, 0.4])) == (2, 0.4)
    assert protocol.stuck_joint(1.5, np.array([0, 0, 0.9])) == (2, 0.4)     # where it stuck
    with pytest.raises(ValueError, match='does not have'):
        protocol.schedule(JointFault('z', 'lost', 1.0), ('a', 'b'))


def test_a_command_schedule_holds_each_command_until_the_next():
    schedule = CommandSchedule((0.0, 2.5, 6.0), ((0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (0.2, 0.0, 0.4)))
    assert [schedule.at(t) for t in (0.0, 2.49, 2.5, 5.9, 60.0)] == [
        (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (0.5, 0.0, 0.0), (0.2, 0.0, 0.4)]
    with pytest.raises(ValueError):
        CommandSchedule((1.0,), ((0.0, 0.0, 0.0),))


def test_terrain_lies_across_the_path_where_its_parameters_say():
    box = trip_box(0.8, 0.05, 0.1)
    assert box.top_at((0.85, 1.5)) == pytest.approx(0.05) and box.top_at((0.75, 0.0)) is None
    patch = slip_patch(1.0, 0.1)
    # Flush with the ground: its top at z = 0, no edge to catch a sole.
    assert patch.friction == 0.1 and patch.top_at((12.0, 0.0)) == pytest.approx(0.0) and patch.flush
    assert patch.top_at((0.99, 0.0)) is None and not box.flush
    down, = step_terrain('down', 0.6, 0.1)
    # The robot starts on the platform; its edge is 0.6 m ahead.
    assert start_height_m((down,)) == pytest.approx(0.1)
    assert down.top_at((0.59, 0.0)) == pytest.approx(0.1) and down.top_at((0.61, 0.0)) is None
    up, = step_terrain('up', 0.6, 0.1)
    assert start_height_m((up,)) == 0.0 and up.top_at((0.61, 0.0)) == pytest.approx(0.1)
    ramp, = step_terrain('slope', 0.5, slope_deg=10.0)
    # The ramp's top face starts on the ground at 0.5 m and rises at 10 degrees.
    rot = ramp.rotation()
    top_normal = rot[:, 2]
    assert math.degrees(math.acos(top_normal[2])) == pytest.approx(10.0)
    near_edge = np.asarray(ramp.centre_m) + rot @ np.array([-ramp.half_extents_m[0], 0.0, ramp.half_extents_m[2]])
    assert near_edge[[0, 2]] == pytest.approx([0.5, 0.0], abs=1e-9)
    with pytest.raises(ValueError):
        TerrainBox((0, 0, 0), (0.1, 0.1, 0.0))


def test_the_causes_option_reads_weights_and_each_run_draws_its_cause_from_its_own_stream():
    assert parse_causes('push,trip') == (('push', 0.5), ('trip', 0.5))
    mix = parse_causes('push:0.4,trip:0.15,slip:0.15,step:0.1,fault:0.1,walk:0.1')
    assert sum(w for _, w in mix) == pytest.approx(1.0)
    for bad in ('push,jump', 'push:-1', 'push,push', ''):
        with pytest.raises(ValueError):
            parse_causes(bad)
    assert run_cause(None, 7, 3) == 'push'
    drawn = [run_cause(mix, 7, i) for i in range(2000)]
    assert drawn == [run_cause(mix, 7, i) for i in range(2000)]
    assert drawn.count('push') / 2000 == pytest.approx(0.4, abs=0.04)


def test_profile_cause_ranges_are_checked_and_override_the_defaults():
    assert parse_cause_ranges('p', {'trip': {'height_m': [0.02, 0.05]}}) == {'trip': {'height_m': (0.02, 0.05)}}
    for bad in ({'jump': {}}, {'trip': {'width_m': [0, 1]}}, {'slip': {'friction': [0.3, 0.1]}}):
        with pytest.raises(ValueError):
            parse_cause_ranges('p', bad)
    profile = load_profile('g1_12dof')
    ranges = cause_ranges(profile, None, 'trip')
    assert set(ranges) == set(DEFAULT_RANGES['trip'])


@pytest.mark.parametrize('cause', ['trip', 'slip', 'step', 'fault', 'walk'])
@pytest.mark.parametrize('robot, controller', [('g1_12dof', None), ('g1', 'c_bal')])
def test_each_cause_draws_the_same_disturbance_from_the_same_seed(cause, robot, controller):
    profile = load_profile(robot)
    walker = walker_for(profile, controller)
    ranges = cause_ranges(profile, controller, cause)
    joints = fault_joints(profile)
    a = sample_disturbance(cause, np.random.default_rng(5), walker, ranges, joints, walk_s=30.0)
    b = sample_disturbance(cause, np.random.default_rng(5), walker, ranges, joints, walk_s=30.0)
    assert a == b and a[0].cause == cause
    disturbance, gait, expected_s = a
    if cause in ('trip', 'slip', 'step'):
        # Laid ahead of the start, reached about when the walk is expected there.
        assert disturbance.params["distance_m"] > 0.12 and disturbance.terrain
        assert (gait is None) == (walker.policy is not None)
    if cause == 'fault':
        assert disturbance.fault.joint in joints and 'leg' not in disturbance.fault.joint
        assert expected_s == disturbance.fault.t_start_s
    if cause == 'walk' and walker.policy is not None:
        times = disturbance.schedule.times_s
        assert times[0] == 0.0 and times[-1] < 30.0
        assert all(2.0 - 1e-6 <= b - a <= 6.0 + 1e-3 for a, b in zip(times, times[1:]))


@pytest.mark.parametrize('cause, probe, fells', [
    ('trip', (0.0, 1.0), lambda s: s > 0.5),               # higher boxes fell
    ('slip', (0.2, 1.0), lambda s: s < 0.6),               # lower friction fells
])
def test_a_causes_range_starts_at_its_mild_end_and_reaches_the_wanted_fall_fraction(cause, probe, fells):
    from fall_predictor.sim.cause_calibration import suggest_cause_range
    severities = np.linspace(probe[0], probe[1], 121)[:-1] + (probe[1] - probe[0]) / 240
    rows = [{'severity': float(s), 'fallen': bool(fells(s)), 't_onset': 1.0, 'fell_before_onset': False,
             'onset_to_fall_s': 0.5 if fells(s) else None} for s in severities]
    summary = suggest_cause_range(cause, rows, probe, target_fall_fraction=0.4)
    key = summary['parameter']
    # Six bands, the severer half falling: five bands from the mild end fell 2 in 5.
    expected = [0.0, 0.8333] if cause == 'trip' else [0.3333, 1.0]
    assert summary['suggested'][key] == pytest.approx(expected, abs=1e-4)
    assert summary['predicted_fall_fraction'] == pytest.approx(0.4) and summary['can_fell']
    never = suggest_cause_range(cause, [{**r, 'fallen': False} for r in rows], probe)
    assert not never['can_fell']


def test_the_ground_around_a_flush_patch_covers_the_rest_and_nothing_under_it():
    patch = slip_patch(1.0, 0.1)
    assert ground_around((trip_box(0.8, 0.05, 0.1),)) == ()
    around = ground_around((patch, trip_box(0.8, 0.05, 0.1)), half_extent_m=50.0)
    # Areas: the square less the patch's 20 m x 4 m, every box's top at z = 0.
    area = sum(4 * h[0] * h[1] for _, h in around)
    assert area == pytest.approx(100.0 ** 2 - 20.0 * 4.0)
    assert all(c[2] + h[2] == pytest.approx(0.0) for c, h in around)
    grounds = [TerrainBox(c, h) for c, h in around]
    for xy in ((0.0, 0.0), (0.99, 0.0), (21.01, 0.0), (5.0, 2.01), (5.0, -2.01)):
        assert sum(b.top_at(xy) is not None for b in grounds) == 1
    for xy in ((1.01, 0.0), (12.0, 1.9), (20.99, -1.9)):
        assert not any(b.top_at(xy) is not None for b in grounds)
