"""Evidence maximisation: the log evidence against scipy's Gaussian density, the
gradient against finite differences, and the optimum against its neighbours."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize
import scipy.stats

from geoq.gp import ExactGP
from geoq.gp.evidence import (
    _negative_evidence_and_gradient,
    fit_squared_exponential,
    log_marginal_likelihood,
)
from geoq.kernels import SquaredExponential


def _data(seed: int, n: int = 80) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2, 2, (n, 2))
    y = np.sin(2.0 * X[:, 0]) + 0.1 * X[:, 1] + 0.1 * rng.normal(size=n)
    return X, y


def test_log_evidence_equals_multivariate_normal_density() -> None:
    X, y = _data(0)
    kern = SquaredExponential(np.array([0.7, 2.0]), variance=1.3)
    noise = 0.02
    cov = kern(X) + noise * np.eye(len(y))
    oracle = scipy.stats.multivariate_normal(mean=np.zeros(len(y)), cov=cov).logpdf(y)
    assert log_marginal_likelihood(kern, noise, X, y) == pytest.approx(oracle, rel=1e-10)
    assert ExactGP(kern, noise).fit(X, y).log_marginal_likelihood() == pytest.approx(
        oracle, rel=1e-10
    )


@pytest.mark.parametrize("ard", [True, False])
def test_gradient_matches_finite_differences(ard: bool) -> None:
    X, y = _data(1, n=40)
    theta = np.log([0.8, 1.5, 0.9, 0.05]) if ard else np.log([0.8, 0.9, 0.05])

    def f(t: np.ndarray) -> float:
        return _negative_evidence_and_gradient(t, X, y, ard)[0]

    def g(t: np.ndarray) -> np.ndarray:
        return _negative_evidence_and_gradient(t, X, y, ard)[1]

    fd = scipy.optimize.approx_fprime(theta, f, 1e-6)
    np.testing.assert_allclose(g(theta), fd, rtol=1e-4, atol=1e-4)


def test_fit_is_a_local_maximum_and_recovers_the_noise() -> None:
    X, y = _data(2, n=150)
    fit = fit_squared_exponential(X, y, lengthscale0=1.0, noise0=0.5)
    assert fit.converged, fit.message
    assert fit.n_used == 150
    # The data were generated with noise variance 0.01.
    assert 0.003 < fit.noise < 0.03
    # The second input barely matters: its length-scale is longer.
    ls = np.asarray(fit.kernel.lengthscale)
    assert ls.shape == (2,) and ls[1] > ls[0]
    best = fit.log_evidence
    for factor in (0.8, 1.25):
        worse = log_marginal_likelihood(
            SquaredExponential(ls * factor, fit.kernel.variance), fit.noise, X, y
        )
        assert worse < best
        assert log_marginal_likelihood(fit.kernel, fit.noise * factor, X, y) < best


def test_subsample_is_seeded_and_required() -> None:
    X, y = _data(3, n=120)
    a = fit_squared_exponential(X, y, max_points=50, rng=np.random.default_rng(7))
    b = fit_squared_exponential(X, y, max_points=50, rng=np.random.default_rng(7))
    assert a.n_used == 50
    assert a.log_evidence == b.log_evidence
    np.testing.assert_array_equal(a.kernel.lengthscale, b.kernel.lengthscale)
    with pytest.raises(ValueError, match="rng"):
        fit_squared_exponential(X, y, max_points=50)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"noise0": 0.0}, "noise0"),
        ({"lengthscale0": -1.0}, "lengthscale0"),
        ({"max_points": 1}, "max_points"),
    ],
)
def test_bad_input(kwargs: dict[str, float], match: str) -> None:
    X, y = _data(4, n=20)
    with pytest.raises(ValueError, match=match):
        fit_squared_exponential(X, y, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="non-finite"):
        fit_squared_exponential(X, np.where(np.arange(20) == 3, np.nan, y))
