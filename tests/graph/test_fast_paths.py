"""Per-point fast paths of the geodesic kernel equal the batch definitions bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.kernels import GeodesicKernel
from geoq.kernels._geodesic_row import row_dots, row_sums, rows_equal, squares_over
from geoq.kernels._graph_paths import weighted_paths
from geoq.kernels.graph_distance import NEGLIGIBLE_WEIGHT


def reference_sp(k: GeodesicKernel, X: np.ndarray, numpy_sums: bool = False) -> np.ndarray:
    """JC12 eqs. 4-5 for the rows of ``X``, written out with plain numpy (the general path).

    The JC12 eq. 5 sums are the defined ones (:func:`row_sums`, :func:`row_dots`), or
    numpy's (``numpy_sums``; equal up to the summation order)."""
    g = k.graph
    P = g.shortest_paths
    r2 = g.squared_distances_to_nodes(X)
    on = r2.min(axis=1) == 0.0
    a = np.argmin(r2, axis=1)
    if k.method == "nearest":
        return g.weight_of(r2[np.arange(len(X)), a])[:, None] + P[a, :]
    z = r2 / (2.0 * k.sigma_se)
    rel = z - z.min(axis=1, keepdims=True)
    W = np.exp(-rel) if k.normalize else np.exp(-z)
    W[rel > -np.log(NEGLIGIBLE_WEIGHT)] = 0.0
    if k.normalize:
        W /= (W.sum(axis=1) if numpy_sums else row_sums(W))[:, None]
    W[on] = 0.0
    W[np.flatnonzero(on), a[on]] = 1.0
    wr = g.weight_of(r2)
    dots = np.einsum("nk,nk->n", W, wr) if numpy_sums else row_dots(W, wr)
    cost = dots if k.attach else np.zeros(len(X))
    return weighted_paths(W, P) + cost[:, None]


@pytest.mark.parametrize(
    "kw",
    [
        {},
        {"eps": 0.97},  # disconnected: P has inf
        {"method": "interpolated", "sigma_se": 0.05},
        {"method": "interpolated", "sigma_se": 0.05, "normalize": True, "attach": True},
        {"method": "interpolated", "sigma_se": 0.02, "eps": 0.97, "edge_weight": "euclidean"},
    ],
)
def test_single_point_rows_equal_batch_rows(kw: dict) -> None:
    rng = np.random.default_rng(3)
    k = GeodesicKernel(**{"eps": 0.5, **kw})
    nodes = rng.uniform(-1.5, 1.5, (40, 2))
    for x in nodes:
        k.basis_added(x)
    X = np.vstack([rng.uniform(-2, 2, (30, 2)), nodes[[0, 5, 39]], [[50.0, 50.0]]])
    bv = k.graph.nodes
    for i in range(X.shape[0]):  # one row at a time: the GP's per-point path
        x = X[i : i + 1]
        sp = reference_sp(k, x)
        assert np.array_equal(k.shortest_path_to_nodes(x), sp)
        with np.errstate(over="ignore"):
            kx = k.amplitude * np.exp(-0.5 * (sp * sp / k.sigma_sp))
        assert np.array_equal(k.to_basis(x, bv), kx)
    assert np.array_equal(k.shortest_path_to_nodes(X), reference_sp(k, X))
    # numpy's summation order gives the same paths to rounding: SP is a sum of
    # non-negative terms over 40 nodes, so the order moves it by < 40 ulps (rtol 1e-12).
    np.testing.assert_allclose(
        k.shortest_path_to_nodes(X), reference_sp(k, X, numpy_sums=True), rtol=1e-12, atol=0
    )


def test_compiled_helpers_match_numpy() -> None:
    rng = np.random.default_rng(0)
    X = rng.standard_normal((7, 9)) * 10.0 ** rng.integers(-200, 200, (7, 9))
    X[0, 0], X[1, 1] = np.inf, 0.0
    with np.errstate(over="ignore", under="ignore"):
        expected = X * X / 0.37
    assert np.array_equal(squares_over(X, 0.37), expected)
    assert np.array_equal(squares_over(X[:, ::2], 0.37), expected[:, ::2])
    B = np.vstack([X[:, :3], rng.standard_normal((2, 3))])
    assert rows_equal(X[:, :3].copy(), B, 7)
    assert not rows_equal(X[:6, :3].copy(), B, 7)
    C = X[:, :3].copy()
    C[6, 2] = np.nextafter(C[6, 2], np.inf)
    assert not rows_equal(C, B, 7)
    C[6, 2] = np.nan
    assert not rows_equal(C, B, 7)
