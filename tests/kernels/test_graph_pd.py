"""Incremental effective resistances of the resistance kernel against the from-scratch oracle.

The tolerance every comparison protects: ``|R_incremental - R_scratch| <= 1e-9 R_scratch +
1e-9 max(finite R)``, the same ``inf`` pattern (components), exact symmetry and a zero
diagonal, after every step of a random add/remove sequence.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoq.gp import NumericalWarning, SparseOnlineGP
from geoq.graph import MDPGraph
from geoq.kernels import ResistanceKernel, kernel_from_arrays, kernel_to_arrays
from geoq.kernels.graph_pd import ResistanceDistance, effective_resistance

RTOL = 1e-9


def scratch(graph: MDPGraph) -> np.ndarray:
    n = graph.n_nodes
    return effective_resistance(graph.weights) if n else np.zeros((0, 0))


def assert_matches_scratch(d: ResistanceDistance) -> None:
    R, ref = d._current(), scratch(d.graph)
    assert R.shape == ref.shape
    np.testing.assert_array_equal(np.isinf(R), np.isinf(ref))
    np.testing.assert_array_equal(R, R.T)
    np.testing.assert_array_equal(np.diag(R), 0.0)
    finite = np.isfinite(ref)
    scale = ref[finite].max() if finite.any() else 0.0
    np.testing.assert_allclose(R[finite], ref[finite], rtol=RTOL, atol=RTOL * scale)


def laplacian_pinv_resistance(W: np.ndarray) -> np.ndarray:
    """Brute force for a connected graph without zero-length edges: ``R = D(L^+)``."""
    C = np.where(np.isfinite(W), 1.0 / np.where(np.isfinite(W), W, 1.0), 0.0)
    np.fill_diagonal(C, 0.0)
    Lp = np.linalg.pinv(np.diag(C.sum(axis=1)) - C)
    g = np.diag(Lp)
    return g[:, None] + g[None, :] - 2.0 * Lp


def test_scratch_oracle_is_the_laplacian_pseudo_inverse():
    rng = np.random.default_rng(0)
    g = MDPGraph(0.05)
    for x in rng.uniform(-1, 1, (12, 2)):
        g.add_node(x)
    W = g.weights
    np.testing.assert_allclose(effective_resistance(W), laplacian_pinv_resistance(W), rtol=1e-10)


def test_scratch_oracle_on_short_circuits_and_components():
    inf = np.inf
    W = np.array(
        [
            [inf, 0.0, 3.0, inf, inf],  # 0 = 1 (short circuit); 0 - 2 and 1 - 2 in parallel
            [0.0, inf, 6.0, inf, inf],
            [3.0, 6.0, inf, inf, inf],
            [inf, inf, inf, inf, 2.0],  # a second component
            [inf, inf, inf, 2.0, inf],
        ]
    )
    R = effective_resistance(W)
    np.testing.assert_allclose(R[:3, :3], [[0, 0, 2], [0, 0, 2], [2, 2, 0]], rtol=1e-14)
    np.testing.assert_allclose(R[3:, 3:], [[0, 2], [2, 0]], rtol=1e-14)
    assert np.all(np.isinf(R[:3, 3:])) and np.all(np.isinf(R[3:, :3]))


# -- closed forms --------------------------------------------------------------------------


def square(eps: float = 0.5) -> ResistanceDistance:
    """A 4-cycle of unit resistors (squared edge lengths 1; diagonals 2 are not edges)."""
    d = ResistanceDistance(MDPGraph(eps))
    d.resistance  # noqa: B018 - current from the start: every change below is an update
    for x in ([0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]):
        d.basis_added(np.asarray(x))
    return d


def test_cycle_closed_form_and_removal_of_a_cycle_node():
    d = square(eps=float(np.exp(-1.5)))  # edges of length^2 1, not the diagonals (2)
    R = d.resistance
    np.testing.assert_allclose(R[0, 1], 0.75, rtol=1e-14)  # 1 || 3
    np.testing.assert_allclose(R[0, 2], 1.0, rtol=1e-14)  # 2 || 2
    d.basis_removed(1)  # the Woodbury removal: a path 0 - 3 - 2 (nodes 0, 1, 2 now)
    np.testing.assert_allclose(d.resistance, [[0, 2, 1], [2, 0, 1], [1, 1, 0]], rtol=1e-14)
    assert d.n_full_recomputes == 1 and d.n_component_recomputes == 0  # no fallback used


def test_removing_a_cut_vertex_splits_and_a_bridging_node_merges():
    d = ResistanceDistance(MDPGraph(float(np.exp(-1.5))))
    d.resistance  # noqa: B018 - current from the start: every change below is an update
    for x in ([0.0, 0.0], [1.0, 0.0], [2.0, 0.0]):
        d.basis_added(np.asarray(x))
    np.testing.assert_array_equal(d.resistance, [[0, 1, 2], [1, 0, 1], [2, 1, 0]])
    d.basis_removed(1)  # the middle node: two components
    np.testing.assert_array_equal(d.resistance, [[0, np.inf], [np.inf, 0]])
    assert d.n_component_recomputes == 1  # the split is recomputed (and said so)
    d.basis_added(np.array([1.0, 0.0]))  # bridges them again
    np.testing.assert_array_equal(d.resistance, [[0, 2, 1], [2, 0, 1], [1, 1, 0]])
    assert_matches_scratch(d)


def test_coinciding_points_are_short_circuits():
    d = square(eps=float(np.exp(-1.5)))
    d.basis_added(np.array([1.0, 1.0]))  # node 4 = node 2: a zero-length edge
    R = d.resistance
    assert R[2, 4] == 0.0
    np.testing.assert_array_equal(R[4, :4], R[2, :4])
    assert_matches_scratch(d)
    d.basis_removed(2)  # a node with a zero-length edge: its component is recomputed
    assert_matches_scratch(d)
    np.testing.assert_allclose(d.resistance[0, 3], 1.0, rtol=1e-14)


def test_temporal_bridge_is_a_parallel_resistor():
    g = MDPGraph(0.99, temporal_edges=True)  # JC12 eq. 2 links only very close points
    d = ResistanceDistance(g)
    for x in ([0.0, 0.0], [0.05, 0.0], [0.1, 0.0], [0.1, 0.05]):
        d.basis_added(np.asarray(x))
    d.basis_removed(1)  # the graph links nodes 0 and 2 (old indices) instead
    assert np.isfinite(g.weights[0, 1])
    assert_matches_scratch(d)
    assert d.n_component_recomputes == 0


# -- random add/remove sequences ------------------------------------------------------------

# Distinct points lie >= 1/64 apart: the from-scratch oracle factorises the Laplacian, and
# with conductances spanning ~1e16 and more (points 1e-45 apart) it is itself wrong.
coordinate = st.one_of(
    st.sampled_from(
        [-1.0, -0.5, 0.0, 0.5, 1.0]
    ),  # a coarse grid: coinciding points, short circuits
    st.integers(-96, 96).map(lambda i: i / 64.0),
)
operation = st.one_of(
    st.tuples(st.just("add"), st.tuples(coordinate, coordinate)),
    st.tuples(st.just("remove"), st.integers(0, 1000)),
    st.tuples(st.just("rollout"), st.none()),
)


@settings(max_examples=60, deadline=None)
@given(
    ops=st.lists(operation, min_size=1, max_size=40),
    eps=st.sampled_from([0.02, 0.3, 0.6, 0.9]),
    temporal=st.booleans(),
    edge_weight=st.sampled_from(["squared", "euclidean"]),
    always_update=st.booleans(),
)
def test_incremental_resistance_equals_scratch_after_random_changes(
    ops, eps, temporal, edge_weight, always_update
):
    g = MDPGraph(eps, temporal_edges=temporal, edge_weight=edge_weight, capacity=4)
    d = ResistanceDistance(g)
    if always_update:  # every change by an update, however dense the graph
        d.RANK_FRACTION = np.inf
    for kind, arg in ops:
        if kind == "add":
            d.basis_added(np.asarray(arg, dtype=np.float64))
        elif kind == "remove" and g.n_nodes:
            d.basis_removed(arg % g.n_nodes)
        elif kind == "rollout":
            g.start_rollout()
        assert_matches_scratch(d)
    if always_update:  # every step was an update (or a component recompute), never a full one
        assert d.n_full_recomputes == 1


@pytest.mark.parametrize("temporal", [False, True])
def test_removing_the_node_added_last_restores_r(temporal):
    d = square()
    d.graph.temporal_edges = temporal
    before = d.resistance
    d.basis_added(np.array([0.5, 0.4]))
    d.basis_removed(4)
    assert d.n_undone == 1
    np.testing.assert_array_equal(d.resistance, before)
    assert_matches_scratch(d)
    d.basis_added(np.array([0.5, 0.4]))
    d.basis_removed(0)  # another node: a real update
    assert d.n_undone == 1
    assert_matches_scratch(d)


def test_a_change_behind_the_kernels_back_is_caught_by_the_graph_version():
    d = square()
    d.graph.add_node(np.array([0.5, 0.5]))  # not through the basis hooks
    assert_matches_scratch(d)
    assert d.n_full_recomputes == 2


def test_resistance_is_a_copy():
    d = square()
    R = d.resistance
    R[0, 1] = 99.0
    assert d.resistance[0, 1] != 99.0


# -- persistence ----------------------------------------------------------------------------


def saved(kernel: ResistanceKernel) -> dict[str, np.ndarray]:
    return kernel_to_arrays(kernel)


def test_round_trip_restores_the_incremental_resistances_bit_for_bit():
    rng = np.random.default_rng(3)
    rk = ResistanceKernel(eps=0.3, lengthscale=0.5)
    for x in np.cumsum(rng.normal(scale=0.3, size=(30, 2)), axis=0):
        rk.basis_added(x)
    for i in (3, 10, 7):
        rk.basis_removed(i)
    loaded = kernel_from_arrays(saved(rk))
    assert isinstance(loaded, ResistanceKernel)
    np.testing.assert_array_equal(loaded.distance.resistance, rk.distance.resistance)  # type: ignore[attr-defined]
    old_format = {k: v for k, v in saved(rk).items() if not k.endswith(".resistance")}
    recomputed = kernel_from_arrays(old_format)  # files without it: recomputed on use
    assert_matches_scratch(recomputed.distance)  # type: ignore[arg-type]


def test_tampered_resistances_are_rejected():
    rk = ResistanceKernel(eps=0.3)
    for x in ([0.0, 0.0], [0.3, 0.0], [0.6, 0.1]):
        rk.basis_added(np.asarray(x))
    arrays = saved(rk)
    key = next(k for k in arrays if k.endswith(".resistance"))
    bad = arrays[key].copy()
    bad[0, 1] = np.inf
    with pytest.raises(ValueError, match="save it again"):
        kernel_from_arrays({**arrays, key: bad})


# -- inside the GP -------------------------------------------------------------------------


@pytest.mark.parametrize("always_update", [True, False])
def test_gp_fit_keeps_the_resistances_current(always_update):
    """A GP with deletions on a dense graph (every point novel): the oracle still holds."""
    rng = np.random.default_rng(7)
    X = np.cumsum(rng.normal(scale=0.15, size=(120, 3)), axis=0)
    rk = ResistanceKernel(eps=0.3, lengthscale=1.0, temporal_edges=True)
    d = rk.distance
    assert isinstance(d, ResistanceDistance)
    if always_update:
        d.RANK_FRACTION = np.inf
    gp = SparseOnlineGP(rk, noise=0.01, max_bv=40)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        gp.fit(X, np.sin(X[:, 0]))
    assert gp.diagnostics.n_deleted > 20
    assert rk.graph.degrees().mean() > 5
    assert_matches_scratch(d)
    assert d.n_undone > 0  # the GP often deletes the point it has just added
    if always_update:  # fit clears the graph, then every change is an update
        assert d.n_full_recomputes == 0


def test_the_resistance_kernel_needs_no_shortest_paths() -> None:
    """Its graph keeps ``P`` lazily (issue 31): the same GP, bit for bit, as on a graph
    whose shortest paths are kept current at every change."""
    import warnings

    from geoq.gp import NumericalWarning, SparseOnlineGP
    from geoq.kernels import ResistanceKernel

    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 8.0, 240)
    X = np.column_stack([np.sin(t), np.cos(1.7 * t), 0.2 * rng.normal(size=t.size)])
    y = np.sin(2.0 * t) + 0.05 * rng.normal(size=t.size)
    gps = []
    for lazy in (True, False):
        kernel = ResistanceKernel(eps=0.3, lengthscale=1.0)
        assert kernel.graph.lazy_paths
        kernel.graph.lazy_paths = lazy
        gp = SparseOnlineGP(kernel, noise=0.01, max_bv=30)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalWarning)
            for chunk in np.array_split(np.arange(t.size), 3):
                kernel.start_rollout()
                gp.partial_fit(X[chunk], y[chunk])
        gps.append(gp)
    lazy_gp, eager_gp = gps
    assert lazy_gp.kernel.distance.n_full_recomputes > 1  # components without P
    np.testing.assert_array_equal(lazy_gp.cholesky_factor, eager_gp.cholesky_factor)
    got, want = lazy_gp.predict(X, return_std=True), eager_gp.predict(X, return_std=True)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
    P, D = lazy_gp.kernel.graph.shortest_paths, eager_gp.kernel.graph.shortest_paths
    np.testing.assert_allclose(P, D, rtol=1e-12, atol=0)
