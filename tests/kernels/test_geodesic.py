"""GeodesicKernel (JC12 eqs. 3-5) against brute-force loops; ResistanceKernel is PD."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoq.kernels import (
    GeodesicKernel,
    ResistanceKernel,
    SquaredExponential,
    kernel_from_arrays,
    kernel_to_arrays,
)


def build(kernel, X):
    for x in X:
        kernel.basis_added(np.asarray(x, dtype=float))
    return kernel


def trajectory(rng, n, d=2, step=0.4):
    return np.cumsum(rng.normal(scale=step, size=(n, d)), axis=0)


# -- brute-force references (Python loops over points and nodes) ---------------------------


def sqdist(a, b):
    return float(sum((a[k] - b[k]) ** 2 for k in range(len(a))))


def brute_eq4(nodes, P, x):
    """SP(x*, x_j) = ||x* - x_i||^2 + P_ij with x_i the nearest node (JC12 eq. 4)."""
    best, bi = math.inf, -1
    for i, node in enumerate(nodes):
        r2 = sqdist(x, node)
        if r2 < best:
            best, bi = r2, i
    return [best + P[bi][j] for j in range(len(nodes))], bi, best


def brute_weights(nodes, x, sigma_se, normalize):
    r2 = [sqdist(x, node) for node in nodes]
    if min(r2) == 0.0:
        i = r2.index(0.0)
        return [1.0 if k == i else 0.0 for k in range(len(nodes))]
    zmin = min(r2) / (2 * sigma_se)
    w = [
        0.0 if r / (2 * sigma_se) - zmin > -math.log(1e-12) else math.exp(-r / (2 * sigma_se))
        for r in r2
    ]
    if normalize:
        total = sum(w)
        w = [v / total for v in w]
    return w


def brute_eq5(nodes, P, x, sigma_se, normalize=False, attach=False):
    """SP(x*, x_j) = sum_i k_SE(x*, x_i) (P_ij [+ ||x* - x_i||^2 if attach]); 0 * inf := 0."""
    w = brute_weights(nodes, x, sigma_se, normalize)
    out = []
    for j in range(len(nodes)):
        s = 0.0
        for i in range(len(nodes)):
            if w[i] > 0.0:
                s += w[i] * (P[i][j] + (sqdist(x, nodes[i]) if attach else 0.0))
        out.append(s)
    return out


def brute_pair(nodes, P, x, y, method, sigma_se=0.01, normalize=False, attach=False):
    """SP between two arbitrary points (pendant leaves / bilinear JC12 eq. 5), 0 if identical."""
    if sqdist(x, y) == 0.0:
        return 0.0
    if method == "nearest":
        _, ax, cx = brute_eq4(nodes, P, x)
        _, ay, cy = brute_eq4(nodes, P, y)
        return cx + P[ax][ay] + cy
    wx = brute_weights(nodes, x, sigma_se, normalize)
    wy = brute_weights(nodes, y, sigma_se, normalize)
    s = 0.0
    for i in range(len(nodes)):
        for j in range(len(nodes)):
            if wx[i] > 0.0 and wy[j] > 0.0:
                via = sqdist(x, nodes[i]) + sqdist(y, nodes[j]) if attach else 0.0
                s += wx[i] * wy[j] * (P[i][j] + via)
    return s


def k_of(sp, amplitude=1.0, sigma_sp=1.0):
    return amplitude * np.exp(-(np.asarray(sp) ** 2) / (2 * sigma_sp))


# -- JC12 eq. 3, 4, 5 --------------------------------------------------------------------------


def test_eq3_convention_sigma_sp_not_squared():
    gk = build(GeodesicKernel(eps=0.3, sigma_sp=0.5, amplitude=2.0), [[0.0, 0.0], [0.5, 0.0]])
    P01 = 0.25  # one edge of weight ||dx||^2
    assert gk.graph.shortest_paths[0, 1] == P01
    K = gk.basis_gram(gk.graph.nodes)
    assert K[0, 1] == pytest.approx(2.0 * np.exp(-(P01**2) / (2 * 0.5)), rel=1e-15)
    np.testing.assert_array_equal(gk.diag(np.zeros((3, 2))), [2.0, 2.0, 2.0])


@pytest.mark.parametrize(
    ("method", "normalize", "attach"),
    [
        ("nearest", False, False),
        ("interpolated", False, False),
        ("interpolated", True, False),
        ("interpolated", False, True),
        ("interpolated", True, True),
    ],
)
def test_eq4_eq5_match_brute_force(method, normalize, attach):
    rng = np.random.default_rng(10)
    nodes = trajectory(rng, 25)
    gk = GeodesicKernel(
        eps=0.3, method=method, sigma_se=0.3, normalize=normalize, sigma_sp=2.0, attach=attach
    )
    build(gk, nodes)
    P = gk.graph.shortest_paths
    Q = np.vstack([nodes[[3, 7]], nodes[:6] + rng.normal(scale=0.2, size=(6, 2))])
    SP = gk.shortest_path_to_nodes(Q)
    for q, row in zip(Q, SP, strict=True):
        ref = (
            brute_eq4(nodes, P, q)[0]
            if method == "nearest"
            else brute_eq5(nodes, P, q, 0.3, normalize, attach)
        )
        np.testing.assert_allclose(row, ref, rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(SP[0], P[3])  # a point on a node uses the node's P row
    # the kernel: JC12 eq. 3 of SP, through every entry point the GP uses
    K = k_of(SP, sigma_sp=2.0)
    np.testing.assert_allclose(gk(Q, nodes), K, rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(gk.to_basis(Q, gk.graph.nodes), K, rtol=1e-12, atol=1e-300)
    np.testing.assert_array_equal(gk.basis_gram(gk.graph.nodes), k_of(P, sigma_sp=2.0))
    # two arbitrary points
    Kqq = gk(Q)
    for a in range(len(Q)):
        for b in range(len(Q)):
            ref = brute_pair(nodes, P, Q[a], Q[b], method, 0.3, normalize, attach)
            assert Kqq[a, b] == pytest.approx(k_of(ref, sigma_sp=2.0), rel=1e-9, abs=1e-300)


def test_normalised_weights_far_from_nodes_fall_back_to_nearest_node_row():
    """Every naive weight underflows; the softmax weights concentrate on the nearest node."""
    gk = build(
        GeodesicKernel(eps=0.3, method="interpolated", normalize=True, sigma_se=1e-3),
        [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]],
    )
    far = np.array([[40.0, 0.0]])
    assert np.all(np.exp(-gk.graph.squared_distances_to_nodes(far) / 2e-3) == 0.0)
    np.testing.assert_array_equal(gk.shortest_path_to_nodes(far)[0], gk.graph.shortest_paths[2])
    unnormalised = build(
        GeodesicKernel(eps=0.3, method="interpolated", sigma_se=1e-3), gk.graph.nodes
    )
    np.testing.assert_array_equal(unnormalised.shortest_path_to_nodes(far), 0.0)  # JC12 eq. 5 as is
    w = gk.graph_distance.interpolation_weights(np.array([[0.3, 0.1], [2.0, 1.0]]))
    np.testing.assert_allclose(w.sum(axis=1), 1.0, rtol=1e-15)


def test_euclidean_edge_weight_also_prices_the_eq4_attachment():
    gk = build(GeodesicKernel(eps=0.3, edge_weight="euclidean"), [[0.0, 0.0], [0.6, 0.0]])
    assert gk.graph.shortest_paths[0, 1] == pytest.approx(0.6)
    sp = gk.shortest_path_to_nodes(np.array([[0.0, 0.3]]))
    np.testing.assert_allclose(sp, [[0.3, 0.9]], rtol=1e-12)


def test_periodic_kernel_identifies_pi_and_minus_pi():
    rng = np.random.default_rng(4)
    nodes = np.c_[rng.uniform(-np.pi, np.pi, 30), rng.uniform(-1, 1, 30)]
    for method in ("nearest", "interpolated"):
        gk = build(
            GeodesicKernel(eps=0.3, method=method, sigma_se=0.1, period=[2 * np.pi, 0.0]), nodes
        )
        K = gk(np.array([[np.pi, 0.2], [-np.pi, 0.2]]), nodes)
        np.testing.assert_allclose(K[0], K[1], rtol=1e-9, atol=1e-12)
        assert gk(np.array([[np.pi, 0.2]]), np.array([[-np.pi, 0.2]]))[0, 0] == 1.0
    raw = build(GeodesicKernel(eps=0.3), nodes)
    K = raw(np.array([[np.pi - 0.01, 0.2], [-np.pi + 0.01, 0.2]]), nodes)
    assert not np.allclose(K[0], K[1])  # faithful default: raw angles


def test_temporal_edges_through_the_kernel():
    far_apart = [[0.0, 0.0], [3.0, 0.0], [6.0, 0.0]]
    plain = build(GeodesicKernel(eps=0.3), far_apart)
    assert np.all(plain.basis_gram(plain.graph.nodes)[~np.eye(3, dtype=bool)] == 0.0)
    tk = GeodesicKernel(eps=0.3, temporal_edges=True, sigma_sp=1e4)
    tk.start_rollout()
    build(tk, far_apart[:2])
    tk.start_rollout()
    build(tk, far_apart[2:])
    K = tk.basis_gram(tk.graph.nodes)
    assert K[0, 1] == pytest.approx(np.exp(-(9.0**2) / 2e4)) and K[1, 2] == 0.0


# -- paper-silent points --------------------------------------------------------------------


def cycle_points(n=6, radius=0.5):
    th = 2 * np.pi * np.arange(n) / n
    return np.c_[radius * np.cos(th), radius * np.sin(th)]


def test_geodesic_gram_is_indefinite_on_a_cycle_counterexample():
    """Six points on a circle, eps linking only neighbours: the graph is C6 and the
    Gaussian of its shortest paths is indefinite; SE and resistance kernels are PD."""
    X = cycle_points()
    s2, s2b = 0.25, 0.75  # squared distance to the 1st and 2nd neighbour
    eps = float(np.exp(-(s2 + s2b) / 2))
    gk = build(GeodesicKernel(eps=eps), X)
    np.testing.assert_array_equal(gk.graph.degrees(), 2)
    np.testing.assert_allclose(gk.graph.shortest_paths[0], [0, 0.25, 0.5, 0.75, 0.5, 0.25])
    lam = np.linalg.eigvalsh(gk.basis_gram(gk.graph.nodes))
    assert lam.min() < -0.09  # measured -0.097
    assert np.linalg.eigvalsh(SquaredExponential(lengthscale=1.0)(X)).min() > 0
    rk = build(ResistanceKernel(eps=eps), X)
    assert np.linalg.eigvalsh(rk.basis_gram(rk.graph.nodes)).min() > 0


def test_disconnected_components_give_exactly_zero_and_no_nan():
    A = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]]
    B = [[10.0, 0.0], [10.5, 0.0]]
    for method in ("nearest", "interpolated"):
        gk = build(GeodesicKernel(eps=0.3, method=method, sigma_se=0.01), A + B)
        P = gk.graph.shortest_paths
        assert np.isinf(P[0, 3]) and np.isfinite(P[0, 2])
        K = gk.basis_gram(gk.graph.nodes)
        assert np.all(K[:3, 3:] == 0.0) and np.all(K[:3, :3] > 0)
        # near A: B's JC12 eq. 5 weights underflow to 0, 0 * inf := 0 -> finite, no NaN
        q = np.array([[0.2, 0.1]])
        assert np.all(np.exp(-gk.graph.squared_distances_to_nodes(q)[0, 3:] / 0.02) == 0)
        Kq = gk(q, gk.graph.nodes)
        assert np.all(np.isfinite(Kq)) and np.all(Kq[0, 3:] == 0.0) and np.all(Kq[0, :3] > 0)
    # a weight that is positive but < 1e-12 of the row's largest is negligible: dropped
    mid = build(GeodesicKernel(eps=0.3, method="interpolated", sigma_se=0.5), A + B)
    q = np.array([[0.2, 0.1]])
    w_b = np.exp(-mid.graph.squared_distances_to_nodes(q)[0, 3:] / 1.0)
    assert np.all(w_b > 0) and np.all(w_b < 1e-12 * 0.9)
    assert np.all(np.isfinite(mid.shortest_path_to_nodes(q)[0, :3]))
    # a non-negligible weight on a node with no path makes SP infinite (JC12 eq. 5 literally)
    wide = build(GeodesicKernel(eps=0.3, method="interpolated", sigma_se=10.0), A + B)
    q = np.array([[0.2, 0.1]])
    assert np.all(wide.shortest_path_to_nodes(q) == np.inf)
    assert np.all(wide(q, wide.graph.nodes) == 0.0)


def test_empty_graph_kernel_is_identity_like():
    X = np.array([[0.0, 1.0], [1.0, 2.0], [0.0, 1.0]])
    for method in ("nearest", "interpolated"):
        gk = GeodesicKernel(method=method, amplitude=3.0)
        K = gk(X)
        np.testing.assert_array_equal(K, [[3, 0, 3], [0, 3, 0], [3, 0, 3]])
        assert gk.shortest_path_to_nodes(X).shape == (3, 0)
        assert gk.to_basis(X, np.zeros((0, 2))).shape == (3, 0)


finite = st.floats(-3.0, 3.0, allow_nan=False, width=32)
points = st.lists(st.tuples(finite, finite), min_size=1, max_size=14)


@settings(max_examples=40, deadline=None)
@given(
    nodes=points,
    queries=points,
    eps=st.sampled_from([0.05, 0.3, 0.6]),
    method=st.sampled_from(["nearest", "interpolated"]),
    normalize=st.booleans(),
    sigma_se=st.sampled_from([0.01, 0.3, 3.0]),
    attach=st.booleans(),
)
def test_kernel_properties_on_random_graphs(
    nodes, queries, eps, method, normalize, sigma_se, attach
):
    gk = GeodesicKernel(
        eps=eps,
        method=method,
        normalize=normalize,
        sigma_se=sigma_se,
        amplitude=1.5,
        attach=attach,
    )
    build(gk, nodes)
    N = gk.graph.nodes
    Q = np.array(queries, dtype=float)
    Kqn, Knq = gk(Q, N), gk(N, Q)
    np.testing.assert_allclose(Kqn, Knq.T, rtol=1e-12, atol=1e-300)
    Kqq = gk(Q)
    np.testing.assert_allclose(Kqq, Kqq.T, rtol=0, atol=0)
    np.testing.assert_array_equal(np.diag(Kqq), 1.5)
    for K in (Kqn, Kqq):
        assert np.all(np.isfinite(K)) and np.all(K >= 0) and np.all(K <= 1.5)
    P = gk.graph.shortest_paths
    np.testing.assert_array_equal(gk.basis_gram(N), k_of(P, 1.5))
    np.testing.assert_allclose(gk.to_basis(Q, N), Kqn, rtol=1e-12, atol=1e-300)
    SP = gk.shortest_path_to_nodes(Q)
    np.testing.assert_allclose(Kqn, k_of(SP, 1.5), rtol=1e-12, atol=1e-300)
    for a in range(min(len(Q), 4)):
        if normalize and method == "interpolated":
            r2 = gk.graph.squared_distances_to_nodes(Q[a : a + 1])
            if np.exp(-r2 / (2 * sigma_se)).sum() < 1e-250:  # naive reference underflows
                continue
        ref = (
            brute_eq4(N, P, Q[a])[0]
            if method == "nearest"
            else brute_eq5(N, P, Q[a], sigma_se, normalize, attach)
        )
        np.testing.assert_allclose(SP[a], ref, rtol=1e-9, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(
    nodes=points,
    queries=points,
    eps=st.sampled_from([0.05, 0.3, 0.6]),
    lengthscale=st.sampled_from([0.1, 1.0, 10.0]),
    edge_weight=st.sampled_from(["squared", "euclidean"]),
    temporal=st.booleans(),
)
def test_resistance_kernel_is_positive_semidefinite(
    nodes, queries, eps, lengthscale, edge_weight, temporal
):
    rk = ResistanceKernel(
        eps=eps, lengthscale=lengthscale, edge_weight=edge_weight, temporal_edges=temporal
    )
    half = len(nodes) // 2
    build(rk, nodes[:half])
    rk.start_rollout()
    build(rk, nodes[half:])
    if rk.graph.n_nodes > 3:
        rk.basis_removed(1)
    N = rk.graph.nodes
    Z = np.vstack([N, np.array(queries, dtype=float), N[:1]])  # nodes, off-node, a repeat
    K = rk(Z)
    lam = np.linalg.eigvalsh(K)
    assert lam.min() >= -1e-9 * len(Z)
    np.testing.assert_array_equal(np.diag(K), 1.0)
    np.testing.assert_allclose(rk.basis_gram(N), K[: len(N), : len(N)], rtol=1e-12, atol=1e-15)


def test_resistance_of_series_and_parallel_resistors():
    rk = ResistanceKernel(eps=0.0, lengthscale=2.0)  # eps = 0: complete graph
    build(rk, [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])  # edges 1, 1, 2 (squared lengths)
    R = rk.distance.resistance  # type: ignore[attr-defined]
    # R01: 1 in parallel with (1 + 2) = 3/4; R02: 2 in parallel with (1 + 1) = 1
    np.testing.assert_allclose(R[0, 1], 0.75, rtol=1e-12)
    np.testing.assert_allclose(R[0, 2], 1.0, rtol=1e-12)
    np.testing.assert_allclose(rk.basis_gram(rk.graph.nodes)[0, 2], np.exp(-1.0 / 2.0))


# -- persistence ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kernel",
    [
        GeodesicKernel(eps=0.3, method="nearest"),
        GeodesicKernel(
            eps=0.5,
            method="interpolated",
            normalize=True,
            sigma_se=0.2,
            sigma_sp=0.7,
            amplitude=2.0,
            edge_weight="euclidean",
            period=[2 * np.pi, 0.0],
            temporal_edges=True,
            attach=True,
        ),
        ResistanceKernel(eps=0.3, lengthscale=0.5, temporal_edges=True),
    ],
    ids=["nearest", "interpolated-all-options", "resistance"],
)
def test_save_load_round_trip(kernel):
    rng = np.random.default_rng(5)
    X = trajectory(rng, 50)
    kernel.start_rollout()
    build(kernel, X[:20])
    kernel.start_rollout()
    build(kernel, X[20:35])
    kernel.basis_removed(4)
    buf = io.BytesIO()
    np.savez(buf, **kernel_to_arrays(kernel))
    buf.seek(0)
    with np.load(buf, allow_pickle=False) as npz:
        loaded = kernel_from_arrays({k: npz[k] for k in npz.files})
    assert type(loaded) is type(kernel) and repr(loaded) == repr(kernel)
    Q = X[35:] + 0.1
    np.testing.assert_array_equal(loaded(Q, kernel.graph.nodes), kernel(Q, kernel.graph.nodes))
    np.testing.assert_array_equal(loaded.graph.shortest_paths, kernel.graph.shortest_paths)
    np.testing.assert_array_equal(loaded.graph.rollout_ids, kernel.graph.rollout_ids)
    build(loaded, X[35:])  # continues identically (temporal bookkeeping included)
    build(kernel, X[35:])
    np.testing.assert_array_equal(loaded.graph.weights, kernel.graph.weights)
    np.testing.assert_array_equal(loaded(Q), kernel(Q))


def test_invalid_arguments():
    with pytest.raises(ValueError, match="method"):
        GeodesicKernel(method="geodesic")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="sigma_sp"):
        GeodesicKernel(sigma_sp=0.0)
    with pytest.raises(ValueError, match="lengthscale"):
        ResistanceKernel(lengthscale=-1.0)
    gk = build(GeodesicKernel(), [[0.0, 0.0]])
    with pytest.raises(ValueError, match="columns"):
        gk(np.zeros((2, 3)))
    assert gk.tracks_basis and ResistanceKernel().tracks_basis


def test_names_moved_out_of_geodesic_stay_importable_from_it():
    """The distances and path helpers live in graph_distance / _graph_paths; the old
    import path ``geoq.kernels.geodesic`` gives the same objects."""
    from geoq.kernels import _graph_paths, geodesic, graph_distance

    for name in ("NEGLIGIBLE_WEIGHT", "BasisGraphDistance", "GraphDistance", "Method"):
        assert getattr(geodesic, name) is getattr(graph_distance, name)
    for name in ("pendant_distances", "split_unreachable", "weighted_paths"):
        assert getattr(geodesic, name) is getattr(_graph_paths, name)
    assert set(geodesic.__all__) <= set(dir(geodesic))
