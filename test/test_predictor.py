import dataclasses
import math

import numpy as np
import pytest

from fall_predictor.monitor.decision_list import Condition, DecisionList, PerModeDecisionLists, Rule
from fall_predictor.learning.boosting import BoostedTreesLearner
from fall_predictor.learning.learners import TreeListLearner
from fall_predictor.monitor.predictor import OnlinePredictor, predict_trajectory
from fall_predictor.monitor.records import FALLING, FEATURE_NAMES, N_CONTACT_MODES, N_FEATURES

COM_Z = FEATURE_NAMES.index('com_z')
LIN_MOM_X = FEATURE_NAMES.index('lin_mom_x')


def momentum_lists() -> PerModeDecisionLists:
    """Every mode: falling iff lin_mom_x > 1."""
    dl = DecisionList((Rule((Condition(LIN_MOM_X, '>', 1.0),), FALLING),))
    return PerModeDecisionLists(tuple(dl for _ in range(N_CONTACT_MODES)))


def features(lin_mom_x: float, com_z: float = 0.59) -> list[float]:
    x = [0.0] * N_FEATURES
    x[LIN_MOM_X] = lin_mom_x
    x[COM_Z] = com_z
    return x


def run(predictor: OnlinePredictor, t: np.ndarray, momentum: list[float]) -> list[bool]:
    return [predictor.step(ti, features(p), 0).falling for ti, p in zip(t, momentum)]


def test_single_sample_spike_is_suppressed_by_2ms_window_and_passes_with_0():
    t = np.arange(10) * 0.001
    spike = [0, 0, 0, 5, 0, 0, 0, 0, 0, 0]
    assert run(OnlinePredictor(momentum_lists(), tau_his_s=0.0), t, spike) == [
        False, False, False, True, False, False, False, False, False, False]
    assert not any(run(OnlinePredictor(momentum_lists(), tau_his_s=0.002), t, spike))


def test_window_needs_every_sample_in_it_to_be_falling():
    # At 1 kHz, tau_his = 2 ms needs the samples at t - 2 ms, t - 1 ms and t: falling from
    # the third sample of a run; 0.003 - 0.001 < 0.002 in floats must not matter.
    t = np.arange(10) * 0.001
    run_of_three = [0, 0, 5, 5, 5, 0, 5, 5, 5, 5]
    out = run(OnlinePredictor(momentum_lists(), tau_his_s=0.002), t, run_of_three)
    assert out == [False, False, False, False, True, False, False, False, True, True]


def test_window_uses_times_not_sample_counts():
    # Irregular spacing: the run starts at 0.010 s; with tau_his = 5 ms it is output from the
    # first sample at or after 0.015 s, however many samples came in between.
    t = [0.000, 0.010, 0.011, 0.0149, 0.020, 0.021]
    out = run(OnlinePredictor(momentum_lists(), tau_his_s=0.005), np.array(t), [0, 5, 5, 5, 5, 5])
    assert out == [False, False, False, False, True, True]


def test_history_before_reset_counts_as_not_falling():
    predictor = OnlinePredictor(momentum_lists(), tau_his_s=0.002)
    assert run(predictor, np.arange(3) * 0.001, [5, 5, 5]) == [False, False, True]
    predictor.reset()
    assert run(predictor, np.arange(3) * 0.001, [5, 5, 5]) == [False, False, True]


def test_guard_fires_without_a_window_and_is_reported_separately():
    predictor = OnlinePredictor(momentum_lists(), tau_his_s=0.0)
    out = predictor.step(0.0, features(0.0, com_z=0.47), 0)
    assert (out.atomic, out.guard, out.falling, out.latched) == (False, True, True, True)
    out = predictor.step(0.001, features(0.0, com_z=0.48), 0)
    assert (out.atomic, out.guard, out.falling, out.latched) == (False, False, False, True)


def test_a_single_guard_glitch_does_not_latch_but_a_held_low_com_does():
    predictor = OnlinePredictor(momentum_lists(), tau_his_s=0.005)
    out = predictor.step(0.0, features(0.0, com_z=0.0), 0)         # one glitch sample
    assert (out.guard, out.falling, out.latched) == (True, False, False)
    assert not predictor.step(0.001, features(0.0), 0).falling     # back to normal
    assert not predictor.latched
    # A CoM that stays low from 0.002 s fires once it has held for tau_his (at 0.007 s).
    outs = [predictor.step(0.001 * k, features(0.0, com_z=0.45), 0) for k in range(2, 10)]
    assert [o.falling for o in outs] == [False] * 5 + [True] * 3
    assert outs[5].t == pytest.approx(0.007)


def test_guard_and_list_samples_form_one_run():
    predictor = OnlinePredictor(momentum_lists(), tau_his_s=0.003)
    # atomic (momentum 5), then guard only (low CoM, momentum 0), alternating: one run.
    xs = [features(5.0), features(0.0, com_z=0.4), features(5.0), features(0.0, com_z=0.4)]
    outs = [predictor.step(0.001 * k, x, 0) for k, x in enumerate(xs)]
    assert [o.falling for o in outs] == [False, False, False, True]


def test_latch_is_one_way_until_reset():
    predictor = OnlinePredictor(momentum_lists(), tau_his_s=0.0)
    outputs = [predictor.step(i * 0.001, features(p), 0) for i, p in enumerate([0, 5, 0, 0])]
    assert [o.falling for o in outputs] == [False, True, False, False]
    assert [o.latched for o in outputs] == [False, True, True, True]
    assert [o.t for o in outputs] == [0.0, 0.001, 0.002, 0.003]
    predictor.reset()
    assert not predictor.latched
    assert not predictor.step(0.0, features(0.0), 0).latched


def test_tau_his_is_validated_and_takes_effect_immediately():
    predictor = OnlinePredictor(momentum_lists(), tau_his_s=1.0)
    assert not any(run(predictor, np.arange(20) * 0.001, [5] * 20))
    predictor.tau_his_s = 0.010
    assert predictor.step(0.020, features(5.0), 0).falling    # the run began at 0.000
    for bad in (-0.001, math.nan, math.inf):
        with pytest.raises(ValueError):
            predictor.tau_his_s = bad
    with pytest.raises(ValueError):
        OnlinePredictor(momentum_lists(), tau_his_s=-1.0)
    assert predictor.tau_his_s == 0.010


def test_step_rejects_time_going_backwards_and_bad_modes():
    predictor = OnlinePredictor(momentum_lists(), tau_his_s=0.0)
    predictor.step(1.0, features(0.0), 0)
    predictor.step(1.0, features(0.0), 0)          # equal times are allowed
    with pytest.raises(ValueError, match='backwards'):
        predictor.step(0.999, features(0.0), 0)
    for mode in (-1, N_CONTACT_MODES):
        with pytest.raises(ValueError, match='mode'):
            predictor.step(2.0, features(0.0), mode)


def test_numpy_and_list_inputs_agree():
    predictor_a = OnlinePredictor(momentum_lists(), tau_his_s=0.0)
    predictor_b = OnlinePredictor(momentum_lists(), tau_his_s=0.0)
    x = features(5.0)
    assert predictor_a.step(0.0, np.array(x), np.int64(3)) == predictor_b.step(0.0, x, 3)


@pytest.fixture(scope='module', params=['lists', 'boosted trees'])
def noisy_lists(request) -> PerModeDecisionLists:
    """A different learned classifier per mode (decision lists, or boosted trees) whose outputs
    flip often on smooth random input."""
    rng = np.random.default_rng(21)
    if request.param == 'boosted trees':
        # One fit (a boosting fit costs seconds on a loaded machine); each mode its own threshold.
        X = rng.normal(size=(2000, N_FEATURES))
        y = (X[:, 0] + X[:, 1] + rng.normal(size=2000) > 1.0).astype(np.int8)
        trees = BoostedTreesLearner(max_iter=10).fit(X, y).classifier_
        return PerModeDecisionLists(tuple(dataclasses.replace(trees, decision_threshold=-1.5 + 0.1 * m)
                                          for m in range(N_CONTACT_MODES)))
    lists = []
    for _ in range(N_CONTACT_MODES):
        X = rng.normal(size=(2000, N_FEATURES))
        y = (X[:, 0] + X[:, 1] + rng.normal(size=2000) > 1.0).astype(np.int8)
        lists.append(TreeListLearner(max_depth=5, min_samples_leaf=1).fit(X, y).classifier_)
    return PerModeDecisionLists(tuple(lists))


@pytest.mark.parametrize('tau_his_s', [0.0, 0.001, 0.002, 0.0025, 0.010, 0.050])
def test_vectorised_prediction_equals_streaming(noisy_lists, tau_his_s):
    lists = noisy_lists
    rng = np.random.default_rng(22)
    n = 3000
    for _ in range(3):
        # Slowly varying features (so runs of falling have all lengths), modes that stay a
        # while, irregular sample spacing, and a CoM that dips below the guard height.
        X = np.cumsum(rng.normal(scale=0.1, size=(n, N_FEATURES)), axis=0) % 4.0 - 2.0
        X[:, COM_Z] = 0.50 + 0.05 * np.sin(np.arange(n) / 200.0)
        mode = np.repeat(rng.integers(0, N_CONTACT_MODES, n // 100), 100)
        t = np.cumsum(rng.choice([0.0005, 0.001, 0.001, 0.002], n))
        vectorised = predict_trajectory(lists, X, mode, t, tau_his_s)
        predictor = OnlinePredictor(lists, tau_his_s)
        streamed = [predictor.step(ti, xi, mi) for ti, xi, mi in zip(t, X, mode)]
        assert vectorised.atomic.tolist() == [o.atomic for o in streamed]
        assert vectorised.guard.tolist() == [o.guard for o in streamed]
        assert vectorised.falling.tolist() == [o.falling for o in streamed]
        assert vectorised.latched.tolist() == [o.latched for o in streamed]
        first = next((o.t for o in streamed if o.falling), None)
        assert vectorised.first_falling_time() == first
        # The comparison is not vacuous: both classes, guard on and off, the window active.
        assert 0.1 < vectorised.atomic.mean() < 0.9
        assert 0.1 < vectorised.guard.mean() < 0.9
        if tau_his_s > 0:
            assert (vectorised.atomic & ~vectorised.guard & ~vectorised.falling).any()


def test_vectorised_prediction_on_regular_samples_and_first_time_after_push():
    lists = momentum_lists()
    t = np.arange(8) * 0.001
    X = np.array([features(p) for p in [5, 0, 5, 5, 5, 0, 5, 5]])
    prediction = predict_trajectory(lists, X, np.zeros(8, dtype=int), t, tau_his_s=0.001)
    assert prediction.falling.tolist() == [False, False, False, True, True, False, False, True]
    assert prediction.first_falling_time() == 0.003
    assert prediction.first_falling_time(t_from=0.005) == 0.007
    assert prediction.first_falling_time(t_from=0.008) is None
    with pytest.raises(ValueError):
        predict_trajectory(lists, X, np.zeros(8, dtype=int), t[::-1], 0.0)
