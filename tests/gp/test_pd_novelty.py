"""Novelty under the flip repair of the augmented Gram (geoq.gp.pd_novelty)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from geoq.gp import NumericalWarning, SparseOnlineGP
from geoq.gp.pd_novelty import PDNoveltyOnlineGP, flipped_novelty
from geoq.kernels import GeodesicKernel, SquaredExponential


def _schur_last(G):
    return 1.0 / np.linalg.inv(G)[-1, -1]


@pytest.mark.parametrize("seed", range(5))
def test_flipped_novelty_is_the_schur_complement_of_the_flipped_whitened_gram(seed):
    # Oracle: whiten the augmented Gram by the factor of K_BV, flip every negative
    # eigenvalue (numpy eigh on the full matrix), take the new point's Schur complement.
    rng = np.random.default_rng(seed)
    m = 6
    A = rng.normal(size=(m, m))
    K = A @ A.T + 0.5 * np.eye(m)
    k = rng.normal(size=m) * 3.0
    c = 1.0
    L = np.linalg.cholesky(K)
    v = np.linalg.solve(L, k)
    assert v @ v > c  # an indefinite augmented Gram: negative novelty
    W = np.block([[np.eye(m), v[:, None]], [v[None, :], np.array([[c]])]])
    w, U = np.linalg.eigh(W)
    assert np.count_nonzero(w < 0) == 1
    flipped = (U * np.abs(w)) @ U.T
    assert flipped_novelty(float(v @ v), c) == pytest.approx(_schur_last(flipped), rel=1e-9)
    # Clipping the negative eigenvalue to a floor instead leaves a novelty of that
    # order: no useful tolerance would accept the point (why the flip is used).
    floor = 1e-10 * np.max(w)
    clipped = (U * np.maximum(w, floor)) @ U.T
    assert _schur_last(clipped) < 10 * floor
    # Positive semi-definite case: the plain novelty.
    assert flipped_novelty(0.25, 1.0) == 0.75


class _PerPointSE(SquaredExponential):
    """A positive-definite kernel that takes the per-point path (not the compiled SE loop)."""


def test_identical_to_the_default_with_a_positive_definite_kernel():
    rng = np.random.default_rng(1)
    X = rng.uniform(-2, 2, size=(150, 2))
    y = np.sin(X[:, 0]) + 0.1 * rng.normal(size=150)
    a = SparseOnlineGP(_PerPointSE(lengthscale=0.7), noise=0.01, max_bv=20, resync_every=1)
    a.fit(X, y)
    b = PDNoveltyOnlineGP(_PerPointSE(lengthscale=0.7), noise=0.01, max_bv=20).fit(X, y)
    assert b.novelty_flips == 0
    np.testing.assert_array_equal(a.basis_vectors, b.basis_vectors)
    Xt = rng.uniform(-2, 2, size=(30, 2))
    for u, w in zip(a.predict(Xt, return_std=True), b.predict(Xt, return_std=True), strict=True):
        np.testing.assert_array_equal(u, w)


def test_the_geodesic_basis_set_grows_to_the_budget():
    # A noisy spiral walk: the geodesic Gram turns indefinite and the default GP stops
    # adding points well below the budget; measured under the flip it fills the budget.
    rng = np.random.default_rng(0)
    t = np.linspace(0, 6 * np.pi, 600)
    X = np.column_stack([np.cos(t) * (1 + 0.1 * t), np.sin(t) * (1 + 0.1 * t), 0.3 * t])
    X += 0.05 * rng.normal(size=X.shape)
    y = np.sin(t)
    budget = 80
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        gps = {}
        for name, cls, resync in (
            ("default", SparseOnlineGP, None),
            ("re-anchored", SparseOnlineGP, 1),
            ("pd", PDNoveltyOnlineGP, None),
        ):
            kernel = GeodesicKernel(eps=0.3, method="nearest", sigma_sp=1.0)
            gp = cls(kernel, noise=0.01, max_bv=budget, resync_every=resync)
            gps[name] = gp.fit(X, y)
    default, pd = gps["default"], gps["pd"]
    assert gps["re-anchored"].n_bv < budget  # re-anchoring alone does not make it grow
    assert default.diagnostics.negative_novelty > 0
    assert default.n_bv < budget
    assert pd.n_bv == budget and pd.novelty_flips > 0
    assert pd.diagnostics.negative_novelty >= pd.novelty_flips
    mean, std = pd.predict(X[::7], return_std=True)
    assert np.all(np.isfinite(mean)) and np.all(std >= 0)
