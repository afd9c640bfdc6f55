import math

import numpy as np
import pytest

from fall_predictor.monitor.contact_modes import ContactMode
from fall_predictor.monitor.features import (FeatureExtractor, FeatureSettings, FeatureSettingsMismatch,
                                             extract_features)
from fall_predictor.monitor.records import FEATURE_NAMES, Measurement
from test_contact_modes import LEFT_FOOT, RIGHT_FOOT, corners, rotated

DT = 0.001
COL = {name: i for i, name in enumerate(FEATURE_NAMES)}
L_FLAT, R_FLAT = corners(LEFT_FOOT), corners(RIGHT_FOOT)


def meas(t=0.0, com=(0.02, 0.0, 0.59), lin_mom=(0.0, 0.0, 0.0), ang_mom=(0.0, 0.0, 0.0),
         heading=0.0, cop=(0.0, 0.0), left=L_FLAT, right=R_FLAT):
    def rows(points):
        return np.array([[x, y, 150.0] for x, y in points]) if points else np.zeros((0, 3))

    return Measurement(
        t=t, com=np.array(com, dtype=float), lin_mom=np.array(lin_mom, dtype=float),
        ang_mom=np.array(ang_mom, dtype=float), heading=heading,
        cop=np.array([cop[0], cop[1], 0.0]), left_contacts=rows(left), right_contacts=rows(right),
        left_foot=np.array(LEFT_FOOT), right_foot=np.array(RIGHT_FOOT), non_foot_contact=False)


def random_trajectory(n=300, seed=0):
    """A smooth wandering state with contact changes (double support, left, right, flight)."""
    rng = np.random.default_rng(seed)
    # Steps of a few mm per ms: fast, but within what physics allows (ContinuityCheck).
    walk = np.cumsum(rng.normal(size=(n, 9)), axis=0) * 0.002
    phases = [(L_FLAT, R_FLAT), (L_FLAT, ()), ((), ()), ((), R_FLAT)]
    out = []
    for k in range(n):
        left, right = phases[(k // 40) % len(phases)]
        cop = (walk[k, 0] * 0.1, 0.1 if left and not right else (-0.1 if right else 0.0))
        out.append(meas(t=k * DT, com=(walk[k, 0], walk[k, 1], 0.59 + walk[k, 2]),
                        lin_mom=walk[k, 3:6] * 50, ang_mom=walk[k, 6:9] * 5,
                        heading=0.3 + walk[k, 0], cop=cop, left=left, right=right))
    return out


def features_by_hand(traj, i, window_samples=10):
    """method §6 features of sample ``i`` computed directly, without the extractor: a rotation
    matrix into the heading frame, the CoP (or, with no contact, the CoM's ground projection)
    as origin, and momentum rates as differences to the sample ``window_samples`` back (or the
    first sample)."""
    m = traj[i]
    c, s = math.cos(m.heading), math.sin(m.heading)
    world_to_heading = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    in_contact = len(m.left_contacts) + len(m.right_contacts) > 0
    origin = np.array([m.cop[0], m.cop[1], 0.0] if in_contact else [m.com[0], m.com[1], 0.0])
    j = max(0, i - window_samples)
    span = m.t - traj[j].t
    force = (m.lin_mom - traj[j].lin_mom) / span if i else np.zeros(3)
    moment = (m.ang_mom - traj[j].ang_mom) / span if i else np.zeros(3)
    return np.concatenate([world_to_heading @ v for v in (m.com - origin, m.lin_mom, m.ang_mom,
                                                          force, moment)])


# Samples from every contact phase of random_trajectory: the first sample, samples within and
# past the first rate window, double support, left only, flight and right only.
CHECKED_SAMPLES = (0, 1, 5, 9, 10, 11, 39, 45, 85, 130, 199, 299)


def test_batch_and_streaming_features_match_a_direct_computation():
    traj = random_trajectory()
    X, mode = extract_features(traj)
    assert X.shape == (len(traj), len(FEATURE_NAMES)) and mode.shape == (len(traj),)
    extractor = FeatureExtractor()
    streamed = [extractor.update(m) for m in traj]
    for i in CHECKED_SAMPLES:
        expected = features_by_hand(traj, i)
        assert X[i] == pytest.approx(expected, rel=1e-12, abs=1e-12), f'batch, sample {i}'
        assert streamed[i][0] == pytest.approx(expected, rel=1e-12, abs=1e-12), f'stream, sample {i}'
        assert streamed[i][1] == mode[i]
    # Flight (samples 80-119) is OUTSIDE; a centred CoP between two flat feet is LR-INSIDE.
    assert mode[85] == ContactMode.OUTSIDE and mode[5] == ContactMode.LR_INSIDE


def test_empty_sequence():
    X, mode = extract_features([])
    assert X.shape == (0, 15) and mode.shape == (0,)


def test_reset_restarts_the_history():
    traj = random_trajectory(60)
    extractor = FeatureExtractor()
    first = [extractor.update(m)[0] for m in traj]
    extractor.reset()
    again = [extractor.update(m)[0] for m in traj]
    assert np.array_equal(np.array(first), np.array(again))


def test_origin_is_the_cop():
    x, mode = FeatureExtractor().update(meas(com=(0.1, 0.05, 0.58), cop=(0.03, -0.02)))
    assert mode == ContactMode.LR_INSIDE
    assert x[COL['com_x']] == pytest.approx(0.07)
    assert x[COL['com_y']] == pytest.approx(0.07)
    assert x[COL['com_z']] == 0.58


def test_outside_uses_the_com_ground_projection():
    x, mode = FeatureExtractor().update(
        meas(com=(0.3, -0.2, 0.5), cop=(math.nan, math.nan), left=(), right=()))
    assert mode == ContactMode.OUTSIDE
    assert x[COL['com_x']] == 0.0 and x[COL['com_y']] == 0.0 and x[COL['com_z']] == 0.5


def test_nan_cop_with_contacts_uses_the_contact_mean():
    x, _ = FeatureExtractor().update(meas(com=(0.05, 0.0, 0.59), cop=(math.nan, math.nan)))
    assert x[COL['com_x']] == pytest.approx(0.05) and x[COL['com_y']] == pytest.approx(0.0)


def test_axes_follow_the_heading():
    # Heading +90 deg: world +y is ahead (x), world +x is to the right (-y).
    x, _ = FeatureExtractor().update(meas(com=(0.0, 0.1, 0.59), lin_mom=(2.0, 5.0, -1.0),
                                          ang_mom=(0.5, 0.0, 0.2), heading=math.pi / 2))
    assert x[COL['com_x']] == pytest.approx(0.1)
    assert x[COL['com_y']] == pytest.approx(0.0, abs=1e-15)
    assert x[3:6] == pytest.approx([5.0, -2.0, -1.0])
    assert x[6:9] == pytest.approx([0.0, -0.5, 0.2], abs=1e-15)


@pytest.mark.parametrize('theta', [0.4, -1.9, math.pi])
def test_turning_world_and_heading_together_gives_identical_features(theta):
    traj = random_trajectory(200, seed=3)
    X, mode = extract_features(traj)
    X_rot, mode_rot = extract_features([rotated(m, theta) for m in traj])
    assert np.array_equal(mode, mode_rot)
    np.testing.assert_allclose(X_rot, X, rtol=0, atol=1e-11)


@pytest.mark.parametrize('heading', [0.0, 0.8, -2.2])
def test_constant_external_force_and_moment_are_recovered(heading):
    force, moment = np.array([12.0, -30.0, -412.0]), np.array([3.0, 1.5, -0.5])
    p0, l0 = np.array([1.0, 2.0, 0.0]), np.array([0.1, 0.0, -0.2])
    traj = [meas(t=1.0 + k * DT, lin_mom=p0 + force * k * DT, ang_mom=l0 + moment * k * DT,
                 heading=heading) for k in range(40)]
    X, _ = extract_features(traj)
    c, s = math.cos(heading), math.sin(heading)

    def to_heading(v):
        return [c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]]

    assert np.all(X[0, 9:15] == 0.0)
    np.testing.assert_allclose(X[1:, 9:12], np.tile(to_heading(force), (39, 1)), atol=1e-9)
    np.testing.assert_allclose(X[1:, 12:15], np.tile(to_heading(moment), (39, 1)), atol=1e-9)


def test_rate_window():
    # A momentum step of 1 kg m/s at sample 20 shows as 1 / window for exactly one window.
    traj = [meas(t=k * DT, lin_mom=(1.0 if k >= 20 else 0.0, 0.0, 0.0)) for k in range(60)]
    for window, n in [(0.01, 10), (0.005, 5), (0.001, 1)]:
        rate = extract_features(traj, rate_window_s=window)[0][:, COL['d_lin_mom_x']]
        expected = np.zeros(60)
        expected[20:20 + n] = 1.0 / (n * DT)
        np.testing.assert_allclose(rate, expected, rtol=1e-9)


def test_rate_uses_the_available_history_at_the_start():
    # p = t^2 from t = 0: a backward difference from the first sample gives (t_k^2 - 0) / t_k.
    traj = [meas(t=k * DT, lin_mom=((k * DT) ** 2, 0.0, 0.0)) for k in range(15)]
    rate = extract_features(traj)[0][:, COL['d_lin_mom_x']]
    t = np.arange(15) * DT
    expected = np.where(t <= 0.01, t, (t ** 2 - (t - 0.01) ** 2) / 0.01)
    np.testing.assert_allclose(rate, expected, rtol=1e-9, atol=1e-15)


def test_rate_divides_by_the_measured_time_span():
    # A dropped sample (t jumps 2 ms) still gives the true rate of a ramp.
    times = [0.0, 0.001, 0.003, 0.004]
    traj = [meas(t=t, lin_mom=(5.0 * t, 0.0, 0.0)) for t in times]
    rate = extract_features(traj, rate_window_s=0.001)[0][:, COL['d_lin_mom_x']]
    np.testing.assert_allclose(rate, [0.0, 5.0, 5.0, 5.0])


class TestValidation:
    @pytest.mark.parametrize('field, value, match', [
        ('com', np.array([0.0, math.nan, 0.5]), 'com'),
        ('lin_mom', np.array([math.inf, 0.0, 0.0]), 'lin_mom'),
        ('ang_mom', np.zeros(2), 'ang_mom'),
        ('com', np.zeros((3, 1)), 'com'),
        ('heading', math.nan, 'heading'),
        ('t', math.nan, 't='),
        ('left_contacts', np.zeros((2, 4)), 'left_contacts'),
    ])
    def test_bad_input_raises_and_leaves_the_state_unchanged(self, field, value, match):
        good = [meas(t=k * DT, lin_mom=(k * 0.1, 0.0, 0.0)) for k in range(5)]
        reference = extract_features(good)[0]
        extractor = FeatureExtractor()
        for m in good[:3]:
            extractor.update(m)
        bad = meas(t=0.0025)
        setattr(bad, field, value)
        with pytest.raises(ValueError, match=match):
            extractor.update(bad)
        assert np.array_equal(extractor.update(good[3])[0], reference[3])

    def test_time_must_increase(self):
        extractor = FeatureExtractor()
        extractor.update(meas(t=1.0))
        with pytest.raises(ValueError, match='reset'):
            extractor.update(meas(t=1.0))
        extractor.reset()
        extractor.update(meas(t=0.0))

    def test_accepts_plain_sequences(self):
        m = meas()
        m.com = [0.0, 0.0, 0.59]
        assert FeatureExtractor().update(m)[0][COL['com_z']] == 0.59

    def test_window_must_cover_a_sample(self):
        with pytest.raises(ValueError):
            FeatureExtractor(rate_window_s=0.0005, dt_s=0.001)


class TestFeatureSettings:
    def test_unset_values_adopt_the_models_and_equal_ones_pass(self):
        model = FeatureSettings(rate_window_s=0.02, edge_tolerance_m=0.0)
        assert model.resolve({'rate_window_s': None, 'edge_tolerance_m': 0.0}) == model
        assert model.resolve({}) == model

    def test_every_difference_is_named(self):
        with pytest.raises(FeatureSettingsMismatch) as error:
            FeatureSettings().resolve({'rate_window_s': 0.02, 'guard_com_height_m': 0.5,
                                       'sample_period_s': 0.001}, what='model m.json')
        message = str(error.value)
        assert 'rate_window_s = 0.02 but model m.json was trained with 0.01' in message
        assert 'guard_com_height_m = 0.5' in message and 'sample_period_s' not in message

    def test_unknown_names_and_impossible_settings_are_refused(self):
        with pytest.raises(KeyError):
            FeatureSettings().resolve({'window': 0.01})
        with pytest.raises(ValueError, match='sample_period_s <= rate_window_s'):
            FeatureSettings(rate_window_s=0.001, sample_period_s=0.002)
        with pytest.raises(ValueError, match='edge_tolerance_m'):
            FeatureSettings(edge_tolerance_m=float('nan'))

    def test_the_extractor_uses_the_settings(self):
        extractor = FeatureSettings(rate_window_s=0.02, sample_period_s=0.002,
                                    edge_tolerance_m=0.005).extractor()
        assert (extractor.rate_window_s, extractor.dt_s, extractor.edge_tolerance_m) == (0.02, 0.002, 0.005)


def _rotation(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Rz(yaw) Ry(pitch) Rx(roll), base to world."""
    cy, sy, cp, sp, cr, sr = (math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch),
                              math.cos(roll), math.sin(roll))
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def test_the_attitude_follows_the_features_heading_free_with_the_base_angular_velocity():
    """A base turning at a constant 0.5 rad/s about its own x axis (R = Rz Ry Rx(roll(t)): the
    body angular velocity is (0.5, 0, 0) exactly) while pitched 0.1 rad and facing 2 rad: the
    fused roll is asin(cos(pitch) sin(roll)) and the fused pitch stays 0.1, whatever the heading
    (the world z axis seen from the base); the angular velocity is 0.5 rad/s about x, 0 about y
    (0 at the first sample, with nothing to turn from); the 15 features are those of an
    extractor without the attitude."""
    traj = random_trajectory(60, seed=3)
    for k, m in enumerate(traj):
        m.torso_rotation = _rotation(2.0, 0.1, 0.05 + 0.5 * k * DT)
    with_attitude = FeatureExtractor(attitude=True)
    plain = FeatureExtractor()
    assert with_attitude.n_outputs == 19 and plain.n_outputs == 15
    for k, m in enumerate(traj):
        x, mode = with_attitude.update(m)
        x15, mode15 = plain.update(m)
        assert x.shape == (19,) and mode == mode15
        np.testing.assert_array_equal(x[:15], x15)
        # Rz Ry Rx: R[2, 1] = cos(pitch) sin(roll), R[2, 0] = -sin(pitch).
        roll = math.asin(math.cos(0.1) * math.sin(0.05 + 0.5 * k * DT))
        assert x[15] == pytest.approx(roll, abs=1e-12)
        assert x[16] == pytest.approx(0.1, abs=1e-12)
        expected = (0.0, 0.0) if k == 0 else (0.5, 0.0)
        assert x[17:] == pytest.approx(expected, abs=1e-9)


def test_the_angular_velocity_is_the_turn_in_the_base_frame_not_the_world_frame():
    """A base pitched down 0.6 rad turning about the world vertical at 1 rad/s (a yaw rate):
    seen from the base, that turn is about its own x and z axes, (-sin 0.6, 0, cos 0.6) rad/s;
    the fused angles do not change."""
    traj = random_trajectory(30, seed=6)
    for k, m in enumerate(traj):
        m.torso_rotation = _rotation(1.0 * k * DT, 0.6, 0.0)
    extractor = FeatureExtractor(attitude=True)
    out = np.array([extractor.update(m)[0] for m in traj])
    np.testing.assert_allclose(out[5:, 17], -math.sin(0.6), atol=1e-9)
    np.testing.assert_allclose(out[5:, 18], 0.0, atol=1e-9)
    np.testing.assert_allclose(out[:, 16], 0.6, atol=1e-12)


def test_without_a_base_orientation_the_attitude_is_nan_and_its_angular_velocity_waits():
    traj = random_trajectory(30, seed=4)
    for k, m in enumerate(traj):
        m.torso_rotation = None if k < 10 else _rotation(0.0, 0.0, 0.2)
    extractor = FeatureExtractor(attitude=True)
    out = np.array([extractor.update(m)[0] for m in traj])
    assert np.isnan(out[:10, 15:]).all()
    assert np.isfinite(out[:, :15]).all()
    # From sample 10 the angles are known; the angular velocity needs a reference with an
    # orientation (the window's oldest sample, 10 ms back), so it comes back once that has one.
    assert np.isfinite(out[10:, 15:17]).all()
    assert np.isnan(out[10:20, 17:]).all() and np.allclose(out[20:, 17:], 0.0)


def test_extract_features_with_the_attitude_is_the_streaming_extractor():
    traj = random_trajectory(50, seed=5)
    for k, m in enumerate(traj):
        m.torso_rotation = _rotation(0.3 * k * DT, -0.2, 0.01 * k)
    X, mode = extract_features(traj, attitude=True)
    extractor = FeatureSettings().extractor(attitude=True)
    for k, m in enumerate(traj):
        x, mk = extractor.update(m)
        np.testing.assert_array_equal(X[k], x)
        assert mode[k] == mk
    assert X.shape == (50, 19)
