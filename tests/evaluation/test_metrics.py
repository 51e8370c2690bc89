"""Metrics against direct formulas."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from geoq.evaluation import mean_confidence_interval, mse, normalized_variance


def test_mse() -> None:
    assert mse([1.0, 2.0, 3.0], [1.0, 0.0, 6.0]) == pytest.approx((0 + 4 + 9) / 3)
    with pytest.raises(ValueError, match="entries"):
        mse([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="non-finite"):
        mse([np.nan], [1.0])


def test_normalized_variance() -> None:
    assert normalized_variance([0.5, 1.0], 2.0) == pytest.approx((0.25 + 0.5) / 2)
    assert normalized_variance([1.0, 1.0], [1.0, 4.0]) == pytest.approx(0.625)
    with pytest.raises(ValueError, match=">= 0"):
        normalized_variance([-0.1], 1.0)
    with pytest.raises(ValueError, match="prior_variance"):
        normalized_variance([0.1], 0.0)


def test_mean_confidence_interval_matches_scipy() -> None:
    x = np.random.default_rng(0).normal(size=(12, 3))
    mean, lo, hi = mean_confidence_interval(x, 0.95)
    for k in range(3):
        ref = stats.t.interval(0.95, df=11, loc=x[:, k].mean(), scale=stats.sem(x[:, k]))
        assert lo[k] == pytest.approx(ref[0]) and hi[k] == pytest.approx(ref[1])
    np.testing.assert_allclose(mean, x.mean(axis=0))
    with pytest.raises(ValueError, match=">= 2"):
        mean_confidence_interval(np.ones((1, 3)))
