"""Tests of the plausibility bounds and the continuity check (monitor/plausibility.py).

The cases are the ones adversarial tests found: finite values that killed
the nodes with OverflowError, a single glitch sample that fired the CoM guard, and a huge
momentum that poisoned the rate window.
"""
import math

import numpy as np
import pytest

from fall_predictor.contract.topics import WireFormatError
from fall_predictor.contract.wire import pack_features, pack_measurement, unpack_features, unpack_measurement
from fall_predictor.monitor.features import FeatureExtractor
from fall_predictor.monitor.plausibility import (MAX_HORIZONTAL_OFFSET_M, MAX_SAMPLE_TIME_S,
                                                 ContinuityCheck, ImplausibleSample,
                                                 check_measurement, check_time)
from fall_predictor.monitor.records import Measurement

LEFT = [(0.1, 0.15), (-0.1, 0.15), (-0.1, 0.05), (0.1, 0.05)]
RIGHT = [(0.1, -0.05), (-0.1, -0.05), (-0.1, -0.15), (0.1, -0.15)]


def standing(t, com=(0.0, 0.0, 0.59), lin_mom=(0.0, 0.0, 0.0), cop=(0.0, 0.0, 0.0)):
    rows = lambda pts: np.array([[x, y, 120.0] for x, y in pts])  # noqa: E731
    return Measurement(t=t, com=np.array(com, float), lin_mom=np.array(lin_mom, float),
                       ang_mom=np.zeros(3), heading=0.0, cop=np.array(cop, float),
                       left_contacts=rows(LEFT), right_contacts=rows(RIGHT),
                       left_foot=np.array([0.0, 0.1, 0.0]), right_foot=np.array([0.0, -0.1, 0.0]),
                       non_foot_contact=False)


def wire_round_trip(m):
    return unpack_measurement(pack_measurement(m))


@pytest.mark.parametrize('field, value, match', [
    ('t', 9.3e9, 'sample time'),                        # overflowed the ns stamp conversion
    ('t', 2.0 ** 31 + 1.0, 'sample time'),              # wrapped header sec to negative
    ('com', (0.0, 0.0, -0.01), 'CoM height'),
    ('com', (0.0, 0.0, 2.5), 'CoM height'),
    ('com', (1e5, 0.0, 0.6), 'from the origin'),
    ('cop', (1.3e154, 0.0, 0.0), 'CoP is'),             # overflowed a squared distance
    ('lin_mom', (1e308, 0.0, 0.0), 'linear momentum'),  # poisoned the rate window
    ('ang_mom', (0.0, 600.0, 0.0), 'angular momentum'),
    ('heading', 1e9, 'heading'),
])
def test_each_bound_rejects_at_the_wire(field, value, match):
    m = standing(0.5)
    setattr(m, field, np.array(value, float) if isinstance(value, tuple) else value)
    data = np.empty(0)
    with pytest.raises(WireFormatError, match=match):
        data = pack_measurement(m)
    assert data.size == 0


@pytest.mark.parametrize('field, value, match', [
    ('com', (0.0, 0.0, -0.01), 'CoM height'),
    ('com', (0.0, 0.0, 2.0000001), 'CoM height'),
    ('com', (1e5, 0.0, 0.6), 'from the origin'),
    ('cop', (0.0, 2.01, 0.0), 'CoP is'),
    ('cop', (0.0, 0.0, -0.6), 'CoP z'),
    ('lin_mom', (1e308, 0.0, 0.0), 'linear momentum'),
    ('ang_mom', (0.0, 600.0, 0.0), 'angular momentum'),
    ('push_force', (0.0, 0.0, 2e5), 'push force'),
    ('left_foot', (2.01, 0.0, 0.0), 'left foot'),
    ('right_foot', (0.0, -2.01, 0.0), 'right foot'),
    ('heading', 1e9, 'heading'),
    ('com', (0.0, math.nan, 0.6), 'non-finite'),
    ('lin_mom', (0.0, 0.0, math.inf), 'non-finite'),
    ('left_foot', (0.0, 0.1, math.nan), 'non-finite'),      # a yaw no bound would catch
    ('heading', math.nan, 'non-finite'),
    ('cop', (math.nan, 0.0, 0.0), 'all finite or all NaN'),  # a NaN x would skip the CoP bounds
    ('torso_rotation', np.full((3, 3), math.nan), 'base orientation'),
])
def test_a_measurement_out_of_bounds_or_not_finite_is_named(field, value, match):
    """The check every estimate and every measurement taken in process passes names the field."""
    m = standing(0.5)
    setattr(m, field, np.array(value, float) if isinstance(value, tuple) else value)
    with pytest.raises(ImplausibleSample, match=match):
        check_measurement(m)


def test_the_measurement_bounds_are_inclusive():
    m = standing(0.5, com=(0.0, 0.0, 2.0), cop=(MAX_HORIZONTAL_OFFSET_M, 0.0, -0.5))
    m.left_foot = np.array([0.0, MAX_HORIZONTAL_OFFSET_M, 1e3])
    m.lin_mom = np.array([0.0, 0.0, 2000.0])
    m.torso_rotation = np.eye(3)
    check_measurement(m)
    m.cop = np.full(3, math.nan)        # no contact: no CoP
    check_measurement(m)
    m.left_contacts[0, 2] = math.inf
    with pytest.raises(ImplausibleSample, match='contacts are not finite'):
        check_measurement(m)


def test_contact_rows_far_away_or_negative_force_are_rejected():
    m = standing(0.5)
    m.left_contacts[0, 0] = 1.3e154
    with pytest.raises(WireFormatError, match='contact point'):
        pack_measurement(m)
    m = standing(0.5)
    m.right_contacts[1, 2] = -5.0
    with pytest.raises(WireFormatError, match='normal forces'):
        pack_measurement(m)


def test_bounds_are_inclusive_and_accept_real_extremes():
    m = standing(MAX_SAMPLE_TIME_S, com=(0.0, 0.0, 2.0))
    assert wire_round_trip(m).t == MAX_SAMPLE_TIME_S
    assert check_time(0.0) == 0.0
    with pytest.raises(ImplausibleSample):
        check_time(math.nan)


def test_features_bounds_at_the_wire():
    x = np.zeros(15)
    x[2] = 0.6
    assert unpack_features(pack_features(1.0, x, 0)).t == 1.0
    x[9] = 6e5              # rate of linear momentum beyond 5e5 N
    with pytest.raises(WireFormatError, match='rate of linear momentum'):
        pack_features(1.0, x, 0)


def test_a_com_glitch_to_the_origin_is_rejected_and_leaves_the_extractor_unchanged():
    extractor = FeatureExtractor()
    reference = FeatureExtractor()
    for k in range(20):
        extractor.update(standing(k * 0.001))
        reference.update(standing(k * 0.001))
    glitch = standing(0.020, com=(0.0, 0.0, 0.0))       # passes the bounds (height 0 m) ...
    assert wire_round_trip(glitch).com[2] == 0.0
    with pytest.raises(ImplausibleSample, match='CoM moved 0.59 m'):   # ... not continuity
        extractor.update(glitch)
    for k in range(21, 40):
        x, mode = extractor.update(standing(k * 0.001))
        x_ref, mode_ref = reference.update(standing(k * 0.001))
        assert np.array_equal(x, x_ref) and mode == mode_ref


def test_momentum_jump_is_rejected_but_the_next_valid_sample_is_not_blamed():
    extractor = FeatureExtractor()
    for k in range(20):
        extractor.update(standing(k * 0.001, lin_mom=(1.0, 0.0, 0.0)))
    with pytest.raises(ImplausibleSample, match='linear momentum changed'):
        extractor.update(standing(0.020, lin_mom=(1000.0, 0.0, 0.0)))   # 1e6 N for 1 ms
    x, _ = extractor.update(standing(0.030, lin_mom=(1.0, 0.0, 0.0)))
    # The rate window holds only valid samples: constant momentum, zero rate.
    assert np.all(x[9:12] == 0.0)


def test_continuity_follows_real_fast_motion_and_resyncs_after_a_real_jump():
    check = ContinuityCheck(resync_samples=5)
    # 3 m/s, the fastest CoM motion seen in the simulated dataset, is accepted.
    for k in range(10):
        check.check(k * 0.001, (0.003 * k, 0.0, 0.6), (0, 0, 0), (0, 0, 0))
    # The robot is lifted 1 m sideways: 4 rejections, then the 5th is accepted as a resync.
    for k in range(10, 14):
        with pytest.raises(ImplausibleSample):
            check.check(k * 0.001, (0.0, 1.0, 0.6), (0, 0, 0), (0, 0, 0))
    assert check.check(0.014, (0.0, 1.0, 0.6), (0, 0, 0), (0, 0, 0)) is True
    assert check.resyncs == 1
    assert check.check(0.015, (0.0, 1.0, 0.6), (0, 0, 0), (0, 0, 0)) is False
    with pytest.raises(ValueError):
        ContinuityCheck(resync_samples=0)


def test_joint_states_and_pushes_have_bounds_too():
    from fall_predictor.contract.wire import JointStateSample, PushEvent
    assert JointStateSample(0.1, ('a',), [1.0], [2.0], [3.0]).effort[0] == 3.0
    for values, match in ((([200.0], [], []), 'position beyond 100'),
                          (([0.0], [2e3], []), 'velocity beyond 1000'),
                          (([0.0], [], [1e6]), 'effort beyond 100000')):
        with pytest.raises(WireFormatError, match=match):
            JointStateSample(0.1, ('a',), *values)
    assert PushEvent(1.0, np.array([500.0, 0.0, 0.0])).force[0] == 500.0
    with pytest.raises(WireFormatError, match='push force beyond'):
        PushEvent(1.0, np.array([1e6, 0.0, 0.0]))


def _g1_bounds():
    """The shipped G1 (12 joints) description's joint bounds, from its URDF."""
    from fall_predictor.profiles.profile import load_profile
    profile = load_profile('g1_12dof')
    return profile.sensor_layout().description(profile.urdf_xml()).joint_bounds


def test_a_joint_past_its_urdf_limit_by_a_realistic_margin_is_flagged_not_refused():
    """The G1 under its policy takes its left ankle pitch to 0.78 rad against a URDF limit of
    0.524 rad as it hits the ground (MuJoCo), and measured speeds beyond the rated 37 rad/s:
    flagged, kept."""
    bounds = _g1_bounds()
    i = bounds.names.index('left_ankle_pitch_joint')
    assert bounds.upper[i] == pytest.approx(0.5236, abs=1e-4)
    q, dq = np.zeros(len(bounds.names)), np.zeros(len(bounds.names))
    q[i] = bounds.upper[i] + 0.26
    assert bounds.violations(q, dq) == []
    [flag] = bounds.exceedances(q, dq)
    assert flag.startswith('joint left_ankle_pitch_joint at 0.7836 rad, outside its limits')
    q[i], dq[i] = 0.0, 1.3 * bounds.velocity[i]          # 48 rad/s on a 37 rad/s motor
    assert bounds.violations(q, dq) == [] and 'moving at 48.1 rad/s' in bounds.exceedances(q, dq)[0]
    dq[i] = 0.9 * bounds.velocity[i]
    assert bounds.exceedances(q, dq) == []                # within: nothing to say


@pytest.mark.parametrize('position_rad, speed_rad_s, words', [
    (0.524 + 0.6, 0.0, 'impossible: joint left_ankle_pitch_joint at 1.124 rad'),   # degrees? order?
    (30.0, 0.0, 'impossible: joint left_ankle_pitch_joint at 30 rad'),        # 30 "rad": degrees
    (math.nan, 0.0, 'impossible: joint left_ankle_pitch_joint at nan rad'),
    (0.0, 6 * 37.0, 'impossible: joint left_ankle_pitch_joint moving at 222 rad/s'),
    (0.0, math.inf, 'impossible: joint left_ankle_pitch_joint moving at inf rad/s'),
])
def test_an_impossible_joint_reading_is_refused(position_rad, speed_rad_s, words):
    bounds = _g1_bounds()
    i = bounds.names.index('left_ankle_pitch_joint')
    q, dq = np.zeros(len(bounds.names)), np.zeros(len(bounds.names))
    q[i], dq[i] = position_rad, speed_rad_s
    [why] = bounds.violations(q, dq)
    assert why.startswith(words), why


def test_a_profiles_own_joint_limits_replace_the_urdfs(tmp_path):
    """``monitor.joint_limits`` in a profile: the limits the monitor judges the encoders by."""
    import shutil

    from fall_predictor.profiles.profile import ProfileError, load_profile
    from fall_predictor.profiles.profile import profile_path
    folder = tmp_path / 'g1_12dof'
    shutil.copytree(profile_path('g1_12dof').parent, folder)
    text = (folder / 'profile.yaml').read_text()
    assert '\nmonitor:\n' in text
    limits = ('\nmonitor:\n  joint_limits:\n    left_ankle_pitch_joint: {upper_rad: 0.9, '
              'velocity_rad_s: 50.0}\n')
    (folder / 'profile.yaml').write_text(text.replace('\nmonitor:\n', limits, 1))
    profile = load_profile(folder / 'profile.yaml')
    bounds = profile.sensor_layout().description(profile.urdf_xml()).joint_bounds
    i = bounds.names.index('left_ankle_pitch_joint')
    assert (bounds.lower[i], bounds.upper[i], bounds.velocity[i]) == pytest.approx((-0.8727, 0.9, 50.0),
                                                                                  abs=1e-4)
    q, dq = np.zeros(len(bounds.names)), np.zeros(len(bounds.names))
    q[i] = 0.78
    assert bounds.exceedances(q, dq) == []                # within the robot's own limit
    (folder / 'typo.yaml').write_text(text.replace('\nmonitor:\n', limits.replace(
        'upper_rad', 'uper_rad'), 1))
    with pytest.raises(ProfileError, match=r"typo\.yaml: monitor\.joint_limits\.left_ankle_pitch_joint: "
                                           r"unknown keys \['uper_rad'\]"):
        load_profile(folder / 'typo.yaml')


def test_joint_limits_naming_a_joint_the_urdf_lacks_or_out_of_order_are_said():
    bounds = _g1_bounds()
    with pytest.raises(ValueError, match=r"joint_limits names joint 'left_ankle_pich_joint', which the "
                                         r"robot description lacks"):
        bounds.with_limits({'left_ankle_pich_joint': {'upper_rad': 0.9}})
    with pytest.raises(ValueError, match=r'joint_limits\.left_ankle_pitch_joint: lower_rad must be <= '
                                         r'upper_rad'):
        bounds.with_limits({'left_ankle_pitch_joint': {'lower_rad': 1.0}})   # above the URDF's upper
