import math

import numpy as np
import pytest

from fall_predictor.learning.intervals import bootstrap_mean_interval, wilson_interval


def test_wilson_known_values():
    # Newcombe (1998), Table I: 81/263 -> [0.2553, 0.3662]; 15/148 -> [0.0624, 0.1605]
    assert wilson_interval(81, 263) == pytest.approx((0.2553, 0.3662), abs=1e-4)
    assert wilson_interval(15, 148) == pytest.approx((0.0624, 0.1605), abs=1e-4)
    # 0/n has a positive upper bound (z^2 / (n + z^2)), n/n a lower bound below 1
    low, high = wilson_interval(0, 50)
    assert low == 0.0 and high == pytest.approx(1.959964 ** 2 / (50 + 1.959964 ** 2), rel=1e-6)
    assert wilson_interval(50, 50)[1] == 1.0 and wilson_interval(50, 50)[0] < 1.0


def test_wilson_interval_of_fp_l2s_false_alarms_and_errors():
    # FP-L2's 28 false alarms of 529 -> about [0.037, 0.075]
    low, high = wilson_interval(28, 529)
    assert low == pytest.approx(0.037, abs=1e-3) and high == pytest.approx(0.075, abs=1e-3)
    assert all(math.isnan(v) for v in wilson_interval(0, 0))
    with pytest.raises(ValueError):
        wilson_interval(3, 2)


def test_bootstrap_interval_matches_normal_theory_for_a_large_sample():
    x = np.random.default_rng(1).normal(0.8, 0.3, size=400)
    low, high = bootstrap_mean_interval(x, n_resamples=4000)
    half = 1.96 * x.std() / math.sqrt(x.size)
    assert low == pytest.approx(x.mean() - half, abs=0.006)
    assert high == pytest.approx(x.mean() + half, abs=0.006)
    assert bootstrap_mean_interval(x) == bootstrap_mean_interval(x)       # deterministic seed
    assert bootstrap_mean_interval([0.4]) == (0.4, 0.4)
    assert all(math.isnan(v) for v in bootstrap_mean_interval([]))


def test_bootstrap_median_interval_matches_order_statistic_theory():
    """The median of n = 400 uniform(0, 1) values: its 95 % interval is about
    0.5 +- 1.96 * 0.5 / sqrt(n) (the median's asymptotic standard error 1 / (2 f(m) sqrt(n)),
    f = 1 on [0, 1]); the bootstrap's must agree within a quarter of that half-width."""
    from fall_predictor.learning.intervals import bootstrap_quantile_interval
    x = np.random.default_rng(3).uniform(size=400)
    low, high = bootstrap_quantile_interval(x, 0.5)
    half = 1.96 * 0.5 / math.sqrt(400)
    centre = float(np.median(x))
    assert low < centre < high
    assert (high - low) / 2 == pytest.approx(half, rel=0.25)
    assert bootstrap_quantile_interval([0.3] * 5, 0.9) == (0.3, 0.3)
    assert all(math.isnan(v) for v in bootstrap_quantile_interval([], 0.5))
    with pytest.raises(ValueError):
        bootstrap_quantile_interval(x, 1.5)


def test_garwood_interval_known_values():
    """The exact Poisson interval (Garwood 1936): 0 events -> upper 3.689 (= -ln(0.025)) per
    exposure; 3 events -> [0.6187, 8.7673]; 10 events in 2 h -> [2.398, 9.195] per hour."""
    from fall_predictor.learning.intervals import garwood_interval

    low, high = garwood_interval(0, 10.0)
    assert low == 0.0 and high == pytest.approx(0.3689, abs=1e-4)
    assert high == pytest.approx(-math.log(0.025) / 10.0, rel=1e-9)
    assert garwood_interval(3, 1.0) == pytest.approx((0.6187, 8.7673), abs=1e-4)
    assert garwood_interval(10, 2.0) == pytest.approx((4.7954 / 2, 18.3904 / 2), abs=1e-3)
    assert all(math.isnan(v) for v in garwood_interval(0, 0.0))
    for bad in ((-1, 1.0), (1.5, 1.0), (1, -1.0), (1, math.inf)):
        with pytest.raises(ValueError):
            garwood_interval(*bad)


def test_wilson_upper_bound_is_one_sided():
    """At 95 % one-sided, the upper end of the two-sided 90 % interval: 0/n -> z^2 / (n + z^2)
    with z = 1.645; higher than the point estimate, lower than the two-sided 95 % bound."""
    from fall_predictor.learning.intervals import wilson_upper_bound

    z = 1.6448536269514722
    assert wilson_upper_bound(0, 150) == pytest.approx(z * z / (150 + z * z), rel=1e-9)
    assert wilson_upper_bound(3, 100) == pytest.approx(wilson_interval(3, 100, z)[1], rel=1e-12)
    assert 0.03 < wilson_upper_bound(3, 100) < wilson_interval(3, 100)[1]
    assert wilson_upper_bound(0, 0) == 1.0
    with pytest.raises(ValueError):
        wilson_upper_bound(1, 10, level=0.3)
