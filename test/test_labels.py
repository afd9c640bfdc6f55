import numpy as np
import pytest

from fall_predictor.data.outcomes import first_fallen_time, height_drop_time, unsettled_at_horizon
from fall_predictor.learning.labels import label_states, training_mask_and_weights
from fall_predictor.monitor.records import BALANCED, FALLEN, FALLING, TrajectoryFeatures

DT = 0.001
T = np.arange(3000) * DT            # 0 .. 2.999 s


def rise_then_fall(t_peak=1.2, t_end=2.0):
    """CoM height: 0.55 m rising at 0.05 m/s until t_peak, then falling at 0.4 m/s (reaching
    0.33 m a little before t_end) and lying flat afterwards."""
    peak = 0.55 + 0.05 * t_peak
    z = np.where(T <= t_peak, 0.55 + 0.05 * T, peak - 0.4 * (T - t_peak))
    return np.maximum(z, peak - 0.4 * (t_end - t_peak))


class TestFirstFallenTime:
    def test_com_height(self):
        z = rise_then_fall()
        t_fallen = first_fallen_time(T, z, np.zeros(T.size, bool))
        assert t_fallen == T[np.argmax(z < 0.33)]
        assert 1.7 < t_fallen < 2.0

    def test_non_foot_contact_first(self):
        contact = T >= 1.5
        assert first_fallen_time(T, rise_then_fall(), contact) == T[1500]

    def test_never(self):
        assert first_fallen_time(T, np.full(T.size, 0.59), np.zeros(T.size, bool)) is None


class TestHeightDropTime:
    def test_peak_of_a_clean_curve(self):
        z = rise_then_fall(t_peak=1.2)
        t_fallen = first_fallen_time(T, z, np.zeros(T.size, bool))
        assert height_drop_time(T, z, t_fallen) == T[1200]
        assert height_drop_time(T, z, t_fallen, tolerance_m=0.0) == T[1200]

    @pytest.mark.parametrize('seed', range(5))
    def test_jitter_is_tolerated(self, seed):
        # A tipping-like descent: it starts from rest at 1.2 s, so its first samples fall by
        # less than the +-0.05 mm jitter superimposed on the whole curve.
        z = np.where(T <= 1.2, 0.54 + 0.05 * T, 0.6 - 0.3 * ((T - 1.2) / 0.8) ** 2)
        z += np.random.default_rng(seed).uniform(-5e-5, 5e-5, T.size)
        t_fallen = first_fallen_time(T, z, np.zeros(T.size, bool))
        assert height_drop_time(T, z, t_fallen) == pytest.approx(1.2, abs=0.01)
        # Without a tolerance the last jitter upturn on the slow start ends the descent.
        assert height_drop_time(T, z, t_fallen, tolerance_m=0.0) > 1.24

    def test_a_real_pause_in_the_descent_ends_it(self):
        # Descent from 1.2 s, interrupted by a 2 mm rise between 1.5 and 1.55 s.
        z = rise_then_fall(t_peak=1.2)
        bump = (T >= 1.5) & (T < 1.55)
        z[bump] = z[1500] + 0.04 * (T[bump] - 1.5)
        z[T >= 1.55] = z[1549] - 0.4 * (T[T >= 1.55] - 1.549)
        t_fallen = first_fallen_time(T, z, np.zeros(T.size, bool))
        assert height_drop_time(T, z, t_fallen) == T[1549]

    def test_slow_rise_is_not_absorbed(self):
        # High at 0.3 s, down to 0.55 m at 0.6 s, a slow rise (0.05 mm per sample, each step
        # below the tolerance) to 0.58 m at 1.2 s, then the fall. The rise is not a descent,
        # so the earlier, higher peak must not be picked.
        z = np.interp(T, [0.0, 0.3, 0.6, 1.2, 2.0], [0.59, 0.62, 0.55, 0.58, 0.2])
        t_fallen = first_fallen_time(T, z, np.zeros(T.size, bool))
        assert height_drop_time(T, z, t_fallen, tolerance_m=1e-4) == T[1200]

    def test_plateau_counts_as_part_of_the_descent(self):
        z = np.concatenate([np.linspace(0.5, 0.6, 1000), np.full(500, 0.6),
                            np.linspace(0.6, 0.2, 1500)])
        assert height_drop_time(T, z, T[2700]) == T[999]

    def test_monotone_from_the_start(self):
        z = np.linspace(0.6, 0.2, T.size)
        assert height_drop_time(T, z, T[2000]) == T[0]

    def test_t_fallen_is_matched_to_the_nearest_sample(self):
        z = rise_then_fall(t_peak=1.2)
        t_fallen = first_fallen_time(T, z, np.zeros(T.size, bool))
        assert height_drop_time(T, z, t_fallen + 1e-12) == T[1200]


class TestLabelStates:
    def test_never_fallen_is_balanced(self):
        assert np.all(label_states(T, 1.0, None) == BALANCED)

    def test_fallen_trajectory(self):
        y = label_states(T, T[1000], T[2500])
        assert y.dtype == np.int8
        assert np.all(y[:1000] == BALANCED)
        assert np.all(y[1000:2500] == FALLING)
        assert np.all(y[2500:] == FALLEN)

    def test_fall_before_push_is_an_error(self):
        with pytest.raises(ValueError, match='before the push'):
            label_states(T, 1.0, 0.5)


def trajectory(fallen, t_push=1.0, t_height_drop=1.5, t_fallen=2.5):
    return TrajectoryFeatures(
        trajectory_id='synthetic', t=T, X=np.zeros((T.size, 15)),
        mode=np.zeros(T.size, dtype=np.int64), fallen=fallen, t_push=t_push,
        t_force_end=t_push + 0.1, t_fallen=t_fallen if fallen else None,
        t_height_drop=t_height_drop if fallen else None)


class TestTrainingMaskAndWeights:
    def test_never_fallen_trains_on_everything_as_balanced(self):
        mask, y, w = training_mask_and_weights(trajectory(False), tau_plus_s=0.25)
        assert mask.all() and np.all(y == BALANCED) and np.all(w == 4.0)

    def test_positive_tau_plus_withholds_early_falling_states(self):
        mask, y, w = training_mask_and_weights(trajectory(True), tau_plus_s=0.25)
        i_push, i_window, i_fallen = 1000, 1750, 2500
        assert mask[:i_push].all() and np.all(w[:i_push] == 4.0)
        assert np.all(y[:i_push] == BALANCED)
        assert not mask[i_push:i_window].any() and np.all(w[i_push:i_window] == 0.0)
        assert mask[i_window:i_fallen].all() and np.all(w[i_window:i_fallen] == 1.0)
        assert np.all(y[i_window:i_fallen] == FALLING)
        assert not mask[i_fallen:].any() and np.all(w[i_fallen:] == 0.0)

    def test_negative_tau_plus_stops_at_the_push(self):
        mask, y, w = training_mask_and_weights(trajectory(True), tau_plus_s=-1.25)
        assert mask[:2500].all() and not mask[2500:].any()
        assert np.all(w[:1000] == 4.0) and np.all(w[1000:2500] == 1.0)

    def test_custom_weights(self):
        _, _, w = training_mask_and_weights(trajectory(True), 0.0, balanced_weight=2.0,
                                            falling_weight=0.5)
        assert w[0] == 2.0 and w[2000] == 0.5

    def test_fallen_without_height_drop_is_an_error(self):
        traj = trajectory(True)
        traj.t_height_drop = None
        with pytest.raises(ValueError, match='t_height_drop'):
            training_mask_and_weights(traj, 0.0)


# -- settled at the horizon (method §4) -----------------------------------------------------
def _walk_then(after_push: np.ndarray, walking_kg_mps: float = 10.0) -> tuple:
    """1 s of walking (momentum magnitude oscillating up to ``walking_kg_mps``), then
    ``after_push`` [kg m/s] per 1 ms sample along x."""
    before = walking_kg_mps * np.abs(np.sin(np.arange(1000) * 0.01))
    magnitude = np.concatenate([before, after_push])
    t = np.arange(magnitude.size) * 0.001
    return t, np.column_stack([magnitude, np.zeros_like(magnitude)]), 1.0


def test_a_recording_that_ends_mid_fall_is_unsettled_and_says_why():
    # Back to walking, then accelerating away in the last 0.3 s (CoM tipping over).
    after = np.concatenate([np.full(3700, 8.0), np.linspace(8.0, 40.0, 300)])
    why = unsettled_at_horizon(*_walk_then(after), mass_kg=33.0)
    assert why is not None and '40.0 kg m/s' in why and 'above 15.0' in why
    # The same robot back at its walking level: settled.
    assert unsettled_at_horizon(*_walk_then(np.full(4000, 9.0)), mass_kg=33.0) is None
    # Just under the bound (1.5 x the walking level, 10 x the 99th percentile of |sin|) and over it.
    assert unsettled_at_horizon(*_walk_then(np.full(4000, 14.9)), mass_kg=33.0) is None
    assert unsettled_at_horizon(*_walk_then(np.full(4000, 15.1)), mass_kg=33.0) is not None


def test_a_robot_that_stood_still_is_judged_against_the_mass_floor():
    # Walking level 0.2 kg m/s of sensor noise; a 2 kg m/s sway at the end is below 0.1 m/s x 42 kg.
    assert unsettled_at_horizon(*_walk_then(np.full(4000, 2.0), walking_kg_mps=0.2), mass_kg=42.0) is None
    assert unsettled_at_horizon(*_walk_then(np.full(4000, 5.0), walking_kg_mps=0.2), mass_kg=42.0) is not None
