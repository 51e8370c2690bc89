"""Intervals over seeds: the log-scale interval of positive quantities (MSE, variance)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import stats

from geoq.experiments.stats import log_interval, mean_interval


def test_log_interval_stays_positive_where_the_t_interval_dips_below_zero():
    # Three seeds' MSEs, one a few times the others: the quick scale's typical case.
    mse = [0.8, 1.1, 6.0]
    t = mean_interval(mse)
    assert t.low < 0.0  # the problem: a negative lower bound for an MSE
    iv = log_interval(mse)
    assert 0.0 < iv.low < iv.mean < iv.high
    assert iv.center == "geometric mean"
    assert iv.mean == pytest.approx(float(np.exp(np.mean(np.log(mse)))))


def test_log_interval_is_the_t_interval_of_the_logs_mapped_back():
    x = np.array([0.3, 0.5, 0.45, 2.0])
    lo, hi = stats.t.interval(0.95, x.size - 1, loc=np.log(x).mean(), scale=stats.sem(np.log(x)))
    iv = log_interval(x)
    assert (iv.low, iv.high) == pytest.approx((np.exp(lo), np.exp(hi)), rel=1e-12)
    # Scale equivariance: MSEs in other units give the same interval in those units.
    iv10 = log_interval(10.0 * x)
    assert (iv10.mean, iv10.low, iv10.high) == pytest.approx(
        (10 * iv.mean, 10 * iv.low, 10 * iv.high)
    )


@pytest.mark.parametrize("n", [3, 10])
def test_log_interval_covers_the_lognormal_median_at_its_level(n):
    # Lognormal samples: the interval must cover exp(mu) in 95% of repetitions; the
    # Student-t interval of the raw values must not be used for it (it dips below 0).
    rng = np.random.default_rng(13)
    mu, sigma, reps = -1.0, 1.2, 4000
    samples = np.exp(rng.normal(mu, sigma, size=(reps, n)))
    hits, negative_t = 0, 0
    for row in samples:
        iv = log_interval(row)
        assert iv.low > 0.0
        hits += iv.low <= np.exp(mu) <= iv.high
        negative_t += mean_interval(row).low < 0.0
    coverage = hits / reps
    # Binomial standard error at 4000 repetitions is 0.0034: +-0.015 is > 4 of them.
    assert abs(coverage - 0.95) < 0.015
    if n == 3:
        assert negative_t > reps // 4  # the raw Student-t interval is below 0 that often


def test_log_interval_falls_back_to_a_clipped_t_interval_for_zeros():
    iv = log_interval([0.0, 0.2, 0.4])
    assert iv.center == "mean" and iv.low == 0.0 and iv.mean == pytest.approx(0.2)
    assert log_interval([2.0]).low == 0.0 and log_interval([2.0]).high == np.inf
    assert log_interval([np.nan, np.inf]).n == 0


def test_values_whose_spread_overflows_give_an_infinite_interval_without_warnings():
    """A diverged cell (MSE ~1e160 beside ~1) must not print numpy overflow warnings."""
    huge = [1e160, 2e200, 1.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        iv = mean_interval(huge)
        lg = log_interval([1e300, 1e-300, 1.0])
    assert iv.high == np.inf and np.isfinite(iv.mean)
    assert lg.high == np.inf and lg.low == 0.0 and lg.mean == pytest.approx(1.0)
