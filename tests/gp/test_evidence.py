"""Evidence maximisation: the log evidence against scipy's Gaussian density, the
gradient against finite differences, the fit against a grid search on the data set
of issue 14 and against the known hyper-parameters of a GP prior, and the
warnings of a fit that ends at a bound or at its start."""

from __future__ import annotations

import itertools
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize
import scipy.stats

from geoq.gp import ExactGP, NumericalWarning, safe_cholesky
from geoq.gp.evidence import (
    LOG_BOUNDS,
    _negative_evidence_and_gradient,
    fit_squared_exponential,
    log_marginal_likelihood,
    median_lengthscales,
)
from geoq.kernels import SquaredExponential

#: 344 state-action points of the two-room task (x, y, ax, ay) and a standardised
#: target, on which the old fit stalled at its start (issue 14).
STALL_CSV = Path(__file__).parent / "data" / "evidence_stall.csv"


def _data(seed: int, n: int = 80) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2, 2, (n, 2))
    y = np.sin(2.0 * X[:, 0]) + 0.1 * X[:, 1] + 0.1 * rng.normal(size=n)
    return X, y


def _stall_data() -> tuple[np.ndarray, np.ndarray]:
    data = np.loadtxt(STALL_CSV, delimiter=",", skiprows=1)
    assert data.shape == (344, 5)
    return data[:, :4], data[:, 4]


def _grid_best(X: np.ndarray, y: np.ndarray) -> tuple[float, tuple[float, float, float]]:
    """Best log evidence of a coarse grid: one length-scale x variance x noise."""
    best = (-np.inf, (np.nan, np.nan, np.nan))
    for ls, var, noise in itertools.product(
        np.logspace(-2, 1, 7), (0.5, 1.0, 2.0), np.logspace(-4, 0, 5)
    ):
        value = log_marginal_likelihood(SquaredExponential(ls, var), noise, X, y)
        if value > best[0]:
            best = (value, (ls, var, noise))
    return best


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


def test_objective_is_finite_at_every_corner_of_the_bounds() -> None:
    """The old objective returned (inf, 0) at 7 of these 64 corners (its K_y was not
    positive definite there), which stopped L-BFGS-B at its start (issue 14)."""
    X, y = _stall_data()
    box = [LOG_BOUNDS["lengthscale"]] * 4 + [LOG_BOUNDS["variance"], LOG_BOUNDS["noise"]]
    for corner in itertools.product(*box):
        value, grad = _negative_evidence_and_gradient(np.array(corner), X, y, True)
        assert np.isfinite(value), corner
        assert np.all(np.isfinite(grad)) and np.any(grad != 0.0), corner


def test_objective_uses_the_jitter_policy_where_k_y_is_indefinite() -> None:
    """Repeated inputs and a noise of 1e-20 (below the bounds): a plain Cholesky fails;
    the objective is the evidence of ``K_y + jitter I`` with the policy's jitter."""
    X, y = _data(5, n=30)
    X, y = np.vstack([X, X]), np.concatenate([y, y])
    theta = np.log([1.0, 1.0, 1.0, 1e-20])
    K_y = SquaredExponential(1.0, 1.0)(X) + 1e-20 * np.eye(60)
    with pytest.raises(np.linalg.LinAlgError):
        scipy.linalg.cholesky(K_y, lower=True)
    with pytest.warns(NumericalWarning, match="jitter"):
        _, jitter = safe_cholesky(K_y)
    K_j = K_y + jitter * np.eye(60)  # [60, 60]; an LU-based oracle, not a Cholesky one
    sign, logdet = np.linalg.slogdet(K_j)
    assert sign > 0
    oracle = -0.5 * y @ np.linalg.solve(K_j, y) - 0.5 * logdet - 30.0 * np.log(2.0 * np.pi)
    value, grad = _negative_evidence_and_gradient(theta, X, y, True)
    assert value == pytest.approx(-oracle, rel=1e-6)
    assert np.all(np.isfinite(grad))


def test_the_stalled_start_of_issue_14_now_moves() -> None:
    """From the old start (length-scales 1, noise 0.1) the old fit stayed put with
    log evidence -17.6 and converged=True."""
    X, y = _stall_data()
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        fit = fit_squared_exponential(X, y, lengthscale0=1.0, noise0=0.1, n_restarts=0)
    assert fit.log_evidence_start == pytest.approx(-17.58, abs=0.01)
    assert fit.converged, fit.message
    assert fit.log_evidence > 58.9  # the issue's hand-picked point (0.3, 1e-2)
    assert fit.log_evidence_runs == (pytest.approx(fit.log_evidence, abs=1e-6),)


@pytest.mark.parametrize("ard", [True, False])
def test_fit_beats_a_coarse_grid_on_the_stall_data(ard: bool) -> None:
    X, y = _stall_data()
    grid_value, grid_point = _grid_best(X, y)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        fit = fit_squared_exponential(X, y, ard=ard, rng=np.random.default_rng(0))
    assert fit.converged, fit.message
    assert fit.n_restarts == 3 and len(fit.log_evidence_runs) == 4
    assert fit.log_evidence >= grid_value - 1e-6, (fit, grid_value, grid_point)
    assert fit.log_evidence > fit.log_evidence_start
    assert fit.log_evidence == pytest.approx(max(fit.log_evidence_runs), abs=1e-6)
    assert fit.at_bound == ()


def test_recovers_the_hyper_parameters_of_a_gp_prior() -> None:
    """N = 500 draws from a GP prior with known hyper-parameters. Tolerances: over
    ten seeds of this design the estimates fell within 12% (length-scales), 17%
    (noise) and a factor 1.7 (prior variance, the least identified on a bounded
    domain) of the truth; the test allows 25%, 35% and a factor 2."""
    lengthscale, variance, noise = np.array([0.5, 1.5]), 1.0, 0.01
    rng = np.random.default_rng(11)
    X = rng.uniform(0.0, 5.0, (500, 2))
    cov = SquaredExponential(lengthscale, variance)(X) + noise * np.eye(500)
    y = np.linalg.cholesky(cov) @ rng.normal(size=500)
    fit = fit_squared_exponential(X, y, rng=np.random.default_rng(12))
    assert fit.converged, fit.message
    np.testing.assert_allclose(fit.kernel.lengthscale, lengthscale, rtol=0.25)
    assert fit.noise == pytest.approx(noise, rel=0.35)
    assert 0.5 < fit.kernel.variance / variance < 2.0
    assert fit.log_evidence >= log_marginal_likelihood(
        SquaredExponential(lengthscale, variance), noise, X, y
    )


def test_warns_when_the_fit_ends_at_a_bound() -> None:
    """The target ignores the second input: its length-scale runs to the upper bound."""
    rng = np.random.default_rng(5)
    X = rng.uniform(-2, 2, (80, 2))
    y = np.sin(2.0 * X[:, 0]) + 0.1 * rng.normal(size=80)
    with pytest.warns(NumericalWarning, match=r"bound \(lengthscale\[1\] upper\)"):
        fit = fit_squared_exponential(X, y, rng=np.random.default_rng(6))
    assert fit.at_bound == ("lengthscale[1] upper",)
    assert fit.kernel.lengthscale[1] == pytest.approx(np.exp(LOG_BOUNDS["lengthscale"][1]))
    # A bound that the optimum presses against is still a local optimum.
    assert fit.converged, fit.message


def test_warns_and_does_not_claim_convergence_when_the_fit_ends_at_its_start() -> None:
    X, y = _data(2, n=60)
    first = fit_squared_exponential(X, y, n_restarts=0)
    with pytest.warns(NumericalWarning, match="ended at its starting point"):
        again = fit_squared_exponential(
            X,
            y,
            lengthscale0=first.kernel.lengthscale,
            variance0=first.kernel.variance,
            noise0=first.noise,
            n_restarts=0,
        )
    assert not again.converged
    assert again.log_evidence == pytest.approx(again.log_evidence_start, abs=1e-6)


def test_fit_is_a_local_maximum_and_recovers_the_noise() -> None:
    X, y = _data(2, n=150)
    fit = fit_squared_exponential(X, y, lengthscale0=1.0, noise0=0.5, n_restarts=0)
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


def test_median_lengthscales_skip_repeated_values() -> None:
    X = np.array([[0.0, 1.0, 2.0], [1.0, 1.0, 2.0], [3.0, 1.0, 2.0], [3.0, 4.0, 2.0]])
    # Dimension 0 nonzero gaps {1, 3, 3, 2, 2}; dimension 1 {3, 3, 3}; dimension 2 constant.
    np.testing.assert_array_equal(median_lengthscales(X), [2.0, 3.0, 1.0])
    (euclid,) = median_lengthscales(X, ard=False)
    dists = [np.linalg.norm(X[i] - X[j]) for i, j in itertools.combinations(range(4), 2)]
    assert euclid == pytest.approx(np.median(dists))


def test_subsample_and_restarts_are_seeded_and_need_rng() -> None:
    X, y = _data(3, n=120)
    a = fit_squared_exponential(X, y, max_points=50, rng=np.random.default_rng(7))
    b = fit_squared_exponential(X, y, max_points=50, rng=np.random.default_rng(7))
    assert a.n_used == 50
    assert a.log_evidence == b.log_evidence
    assert a.log_evidence_runs == b.log_evidence_runs
    np.testing.assert_array_equal(a.kernel.lengthscale, b.kernel.lengthscale)
    with pytest.raises(ValueError, match="rng"):
        fit_squared_exponential(X, y, max_points=50, n_restarts=0)
    with pytest.raises(ValueError, match="n_restarts=3 needs random starts"):
        fit_squared_exponential(X, y)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"noise0": 0.0}, "noise0"),
        ({"variance0": -1.0}, "variance0"),
        ({"lengthscale0": -1.0}, "lengthscale0"),
        ({"max_points": 1}, "max_points"),
        ({"n_restarts": -1}, "n_restarts"),
        ({"n_restarts": 1.5}, "n_restarts"),
    ],
)
def test_bad_input(kwargs: dict[str, float], match: str) -> None:
    X, y = _data(4, n=20)
    with pytest.raises(ValueError, match=match):
        fit_squared_exponential(X, y, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="non-finite"):
        fit_squared_exponential(X, np.where(np.arange(20) == 3, np.nan, y), n_restarts=0)
