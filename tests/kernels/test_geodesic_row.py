"""The GP's fused per-point geodesic row against the numpy definitions, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

import geoq.kernels.geodesic as geodesic
from geoq.gp import SparseOnlineGP
from geoq.kernels import GeodesicKernel
from geoq.kernels._geodesic_row import (
    EINSUM_ROW_MAX,
    _pairwise_sum,
    einsum_row_dot,
    numpy_summation_reproduced,
)
from geoq.kernels.geodesic import GraphKernel

#: The fused row copies numpy's summation order; another numpy build disables it.
needs_numpy_order = pytest.mark.skipif(
    not numpy_summation_reproduced(),
    reason="this numpy sums in another order: the fused row is disabled (tested below)",
)

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


@needs_numpy_order
def test_pairwise_sum_is_numpys() -> None:
    rng = np.random.default_rng(0)
    for n in [*range(1, 300), 511, 1000, 1029, 4097]:
        w = np.exp(-rng.uniform(0, 40, (1, n)))
        w[0, rng.random(n) < 0.3] = 0.0
        assert _pairwise_sum(w[0], 0, n) == w.sum(axis=1, keepdims=True)[0, 0]


@needs_numpy_order
def test_einsum_row_dot_is_numpys() -> None:
    rng = np.random.default_rng(1)
    for n in [*range(1, 200), 1000, EINSUM_ROW_MAX]:
        a = rng.random((1, n)) * 10.0 ** rng.integers(-6, 6, (1, n))
        b = rng.standard_normal((1, n))
        assert einsum_row_dot(a[0], b[0], n) == np.einsum("nk,nk->n", a, b)[0]


@needs_numpy_order
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


def test_fused_row_is_disabled_when_numpy_sums_differently(monkeypatch) -> None:
    k = GeodesicKernel(eps=0.3, method="interpolated", normalize=True, attach=True)
    monkeypatch.setattr(geodesic, "numpy_summation_reproduced", lambda: False)
    assert k._row_exponent_fn() is None
