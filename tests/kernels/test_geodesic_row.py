"""The GP's fused per-point geodesic row against the numpy definitions, bit for bit.

Both paths sum JC12 eq. 5 by the same compiled :func:`row_sum` / :func:`row_dot`, so they
agree by construction; numpy's own sums are only a tolerance check of those."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.gp import SparseOnlineGP
from geoq.kernels import GeodesicKernel
from geoq.kernels._geodesic_row import (
    geodesic_r2,
    row_dot,
    row_dots,
    row_sum,
    row_sums,
    squares_over,
)
from geoq.kernels.geodesic import GraphKernel

pytestmark = pytest.mark.filterwarnings("ignore::geoq.gp.numerics.NumericalWarning")

PERIOD = np.array([2 * np.pi, 0.0, 0.0])

SETTINGS = [
    {"eps": 0.3, "sigma_sp": 0.01},
    {"eps": 0.5, "sigma_sp": 0.1, "edge_weight": "euclidean", "temporal_edges": True},
    {"eps": 0.995, "sigma_sp": 0.1},  # disconnected graph: unreachable pairs
    *[
        {
            "eps": eps,
            "method": "interpolated",
            "sigma_sp": 0.01,
            "sigma_se": sigma_se,
            "normalize": normalize,
            "attach": attach,
            "edge_weight": weight,
        }
        for eps, sigma_se, weight in ((0.3, 0.01, "squared"), (0.995, 0.2, "euclidean"))
        for normalize in (False, True)
        for attach in (False, True)
    ],
]


def _stream(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    X = np.cumsum(rng.normal(scale=0.15, size=(n, 3)), axis=0)
    return X, np.sin(X).sum(axis=1)


def test_jc12_eq3_r2_is_numpys_sp_squared_over_sigma_sp() -> None:
    """The one definition of JC12 eq. 3's r^2 gives numpy's ``SP * SP / sigma_sp`` bit for
    bit (so the batch and per-point paths agree), with inf for overflow and unreachable."""
    rng = np.random.default_rng(3)
    SP = np.concatenate([rng.exponential(size=40), [0.0, 1e200, np.inf]]).reshape(1, -1)
    for sigma_sp in (1.0, 0.01, 3.7):
        with np.errstate(over="ignore"):
            want = SP * SP / sigma_sp
        np.testing.assert_array_equal(squares_over(SP, sigma_sp), want)
        assert [geodesic_r2(float(v), sigma_sp) for v in SP[0]] == want[0].tolist()


def test_row_sums_are_sums_to_float64_accuracy() -> None:
    """What the tolerance protects: the compiled sums are correct sums (any order is
    within ``n eps sum|terms|`` of the exact one), not a copy of numpy's order."""
    rng = np.random.default_rng(0)
    eps = np.finfo(np.float64).eps
    for n in [*range(1, 300), 511, 1000, 4097]:
        w = np.exp(-rng.uniform(0, 40, (2, n)))
        w[:, rng.random(n) < 0.3] = 0.0
        b = rng.standard_normal((2, n))
        bound = 2 * n * eps
        assert abs(row_sum(w[0], n) - w[0].sum()) <= bound * np.abs(w[0]).sum()
        dot_bound = bound * np.abs(w[0] * b[0]).sum()
        assert abs(row_dot(w[0], b[0], n) - np.dot(w[0], b[0])) <= dot_bound
        assert np.array_equal(row_sums(w), [row_sum(w[0], n), row_sum(w[1], n)])
        assert np.array_equal(row_dots(w, b), [row_dot(w[0], b[0], n), row_dot(w[1], b[1], n)])


@pytest.mark.parametrize("kw", SETTINGS)
def test_row_exponent_matches_to_basis(kw: dict) -> None:
    rng = np.random.default_rng(2)
    k = GeodesicKernel(period=PERIOD, **kw)
    X, _ = _stream(rng, 60)
    for x in X[::2]:
        k.basis_added(x)
    bv = k.graph.nodes
    row = k._row_exponent_fn()
    assert row is not None
    queries = np.vstack([X[1::2], bv[::5], rng.uniform(-3, 3, (20, 3)), X[:5] + 1e-9])
    m = bv.shape[0]
    for x in queries:
        expo = row(x, bv, m)
        assert expo is not None
        assert np.array_equal(k.variance * np.exp(expo), k.to_basis(x[None, :], bv)[0])
    assert row(queries[0], bv + 1.0, m) is None  # basis out of sync: general path
    assert row(queries[0], bv, m - 1) is None


@pytest.mark.parametrize("kw", SETTINGS)
def test_gp_fit_identical_with_and_without_fused_row(kw: dict, monkeypatch) -> None:
    rng = np.random.default_rng(3)
    X, y = _stream(rng, 300)
    Xt = rng.uniform(-2, 2, (40, 3))

    def fit() -> tuple:
        k = GeodesicKernel(period=PERIOD, **kw)
        gp = SparseOnlineGP(k, noise=0.01, max_bv=25, resync_every=30)
        for lo in range(0, 300, 100):
            k.start_rollout()
            gp.partial_fit(X[lo : lo + 100], y[lo : lo + 100])
        mean, std = gp.predict(Xt, return_std=True)
        return mean, std, gp.basis_vectors, gp._S[: gp.n_bv, : gp.n_bv].copy(), gp.diagnostics, k

    fused = fit()
    monkeypatch.setattr(GraphKernel, "_row_exponent_fn", lambda self: None)
    plain = fit()
    for a, b in zip(fused[:4], plain[:4], strict=True):
        assert np.array_equal(a, b)
    assert fused[4] == plain[4]
    assert np.array_equal(fused[5].graph.shortest_paths, plain[5].graph.shortest_paths)
    S = fused[3]
    assert np.array_equal(S, S.T)


def test_fused_row_serves_every_eq5_variant() -> None:
    for normalize in (False, True):
        for attach in (False, True):
            k = GeodesicKernel(eps=0.3, method="interpolated", normalize=normalize, attach=attach)
            assert k._row_exponent_fn() is not None
