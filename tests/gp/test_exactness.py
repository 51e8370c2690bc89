"""Oracle tests: the sparse online GP with every point kept is the exact GP."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.gp import ExactGP, SparseOnlineGP
from geoq.kernels import SquaredExponential

from .reference import exact_posterior


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("lengthscale", [0.3, np.array([0.5, 1.5])])
def test_all_points_kept_equals_exact_gp(seed: int, lengthscale: object) -> None:
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2, 2, (60, 2))
    y = np.sin(2 * X[:, 0]) * X[:, 1] + 0.1 * rng.normal(size=60)
    Xs = rng.uniform(-2.5, 2.5, (50, 2))
    kern = SquaredExponential(lengthscale, variance=1.7)
    noise = 0.05
    gp = SparseOnlineGP(kern, noise=noise, max_bv=60, tol=0.0).fit(X, y)
    assert gp.n_bv == 60
    mean, std = gp.predict(Xs, return_std=True)
    m_solve, s_solve = exact_posterior(kern(X), kern(Xs, X), kern.diag(Xs), y, noise)
    m_chol, s_chol = ExactGP(kern, noise).fit(X, y).predict(Xs, return_std=True)
    np.testing.assert_allclose(mean, m_solve, rtol=0, atol=1e-8)
    np.testing.assert_allclose(std, s_solve, rtol=0, atol=1e-8)
    np.testing.assert_allclose(mean, m_chol, rtol=0, atol=1e-8)
    np.testing.assert_allclose(std, s_chol, rtol=0, atol=1e-8)
    A = kern(X) + noise * np.eye(60)
    np.testing.assert_allclose(gp.alpha, np.linalg.solve(A, y), rtol=0, atol=1e-8)
    np.testing.assert_allclose(gp.C, -np.linalg.inv(A), rtol=0, atol=1e-8)
