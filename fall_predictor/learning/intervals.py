"""Confidence intervals for the reported figures (method §11).

* :func:`wilson_interval`: the Wilson score interval of a binomial proportion (used for every
  FPR: ``k`` false positives among ``n`` balanced trajectories).
* :func:`bootstrap_mean_interval`: a percentile bootstrap interval of a mean over independent
  units (used for every tau_lead: the per-trajectory leads of the fallen trajectories are
  resampled with replacement, so the interval is over trajectories, not samples);
  :func:`bootstrap_quantile_interval` the same for a quantile (the median and p90 of the
  time-to-fall and direction errors, one error per trajectory).
* :func:`wilson_upper_bound`: the one-sided Wilson upper confidence bound of a proportion at a
  stated level (the bound an FPR budget is checked on when an operating point is chosen,
  method §11 "A budget that holds").
* :func:`garwood_interval`: the exact (Garwood) interval of a Poisson rate: ``k`` events over an
  exposure (false alarm episodes per hour of undisturbed walking).

All return ``(low, high)``; with no data both bounds are NaN.
"""
from __future__ import annotations

import math
from typing import Sequence

from statistics import NormalDist

import numpy as np

#: two-sided 95 % standard normal quantile
Z_95 = 1.959963984540054


def wilson_interval(k: int, n: int, z: float = Z_95) -> tuple[float, float]:
    """Wilson score interval of the proportion ``k / n`` (default 95 %).

    Args:
        k: successes (e.g. false positives), ``0 <= k <= n``.
        n: trials (e.g. balanced trajectories); 0 gives ``(nan, nan)``.
        z: the normal quantile of the interval's level.
    """
    if not (0 <= k <= n):
        raise ValueError(f'need 0 <= k <= n, got k={k}, n={n}')
    if n == 0:
        return math.nan, math.nan
    p = k / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4 * n * n)) / denom
    # the bounds bracket p exactly (rounding could put 0/n's lower bound at +1e-17)
    return min(p, max(0.0, centre - half)), max(p, min(1.0, centre + half))


def wilson_upper_bound(k: int, n: int, level: float = 0.95) -> float:
    """One-sided Wilson upper confidence bound of ``k / n`` at ``level`` (0.95: the true
    proportion is below it with 95 % confidence; the upper end of a two-sided 90 % Wilson
    interval). ``n == 0`` gives 1.0: nothing observed bounds nothing."""
    if not 0.5 <= level < 1.0:
        raise ValueError(f'level must be in [0.5, 1), got {level!r}')
    if n == 0:
        if k != 0:
            raise ValueError(f'need 0 <= k <= n, got k={k}, n={n}')
        return 1.0
    return wilson_interval(k, n, NormalDist().inv_cdf(level))[1]


def garwood_interval(k: int, exposure: float, level: float = 0.95) -> tuple[float, float]:
    """Exact two-sided (Garwood) interval of a Poisson rate: ``k`` events over ``exposure``
    (e.g. hours), in events per unit of exposure, from the chi-square quantiles
    ``chi2(a/2; 2k) / 2`` and ``chi2(1 - a/2; 2k + 2) / 2``. 0 events in 10 h: [0, 0.3689] per
    hour at 95 %. No exposure gives ``(nan, nan)``."""
    from scipy.stats import chi2

    if isinstance(k, bool) or int(k) != k or k < 0:
        raise ValueError(f'k must be a count >= 0, got {k!r}')
    if not 0.0 < level < 1.0:
        raise ValueError(f'level must be in (0, 1), got {level!r}')
    if not (math.isfinite(exposure) and exposure >= 0.0):
        raise ValueError(f'exposure must be finite and >= 0, got {exposure!r}')
    if exposure == 0.0:
        return math.nan, math.nan
    alpha = 1.0 - level
    low = 0.0 if k == 0 else float(chi2.ppf(alpha / 2.0, 2 * k)) / 2.0
    high = float(chi2.ppf(1.0 - alpha / 2.0, 2 * k + 2)) / 2.0
    return low / exposure, high / exposure


def bootstrap_mean_interval(values: Sequence[float], level: float = 0.95,
                            n_resamples: int = 2000, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean of ``values`` (one value per trajectory).

    Deterministic for a given ``seed``. An empty sequence gives ``(nan, nan)``; a single value
    gives ``(value, value)``.
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f'level must be in (0, 1), got {level!r}')
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, x.size, size=(n_resamples, x.size))].mean(axis=1)
    alpha = (1.0 - level) / 2.0
    low, high = np.quantile(means, [alpha, 1.0 - alpha])
    return float(low), float(high)


def bootstrap_quantile_interval(values: Sequence[float], q: float, level: float = 0.95,
                                n_resamples: int = 2000, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap interval of the ``q``-quantile (0.5: the median) of ``values`` (one
    value per trajectory), as :func:`bootstrap_mean_interval`."""
    if not 0.0 < level < 1.0 or not 0.0 <= q <= 1.0:
        raise ValueError(f'need 0 < level < 1 and 0 <= q <= 1, got level={level!r}, q={q!r}')
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    quantiles = np.quantile(x[rng.integers(0, x.size, size=(n_resamples, x.size))], q, axis=1)
    alpha = (1.0 - level) / 2.0
    low, high = np.quantile(quantiles, [alpha, 1.0 - alpha])
    return float(low), float(high)
