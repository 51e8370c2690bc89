"""MDPGraph: JC12 eq. 2 by brute force and P == scipy Dijkstra after every add and delete."""

from __future__ import annotations

import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse.csgraph import dijkstra

from geoq.graph import MDPGraph


def brute_weights(
    nodes: np.ndarray,
    ids: list[int],
    eps: float,
    edge_weight: str = "squared",
    period: np.ndarray | None = None,
    temporal: bool = False,
) -> np.ndarray:
    """Dense JC12 eq. 2 weights (inf = no edge) by Python loops, plus the temporal chains."""
    n = len(nodes)
    W = np.full((n, n), np.inf)

    def r2(a: np.ndarray, b: np.ndarray) -> float:
        total = 0.0
        for k in range(len(a)):
            diff = a[k] - b[k]
            if period is not None and period[k] > 0:
                diff = diff - period[k] * round(diff / period[k])
            total += diff * diff
        return total

    def weight(a: np.ndarray, b: np.ndarray) -> float:
        s = r2(a, b)
        return s if edge_weight == "squared" else float(np.sqrt(s))

    for i in range(n):
        for j in range(n):
            if i != j and np.exp(-r2(nodes[i], nodes[j])) > eps:
                W[i, j] = weight(nodes[i], nodes[j])
    if temporal:
        for i in range(n):
            later = [j for j in range(i + 1, n) if ids[j] == ids[i]]
            if later:
                j = later[0]
                W[i, j] = W[j, i] = weight(nodes[i], nodes[j])
    return W


def check_graph(
    g: MDPGraph, expected_nodes: list[np.ndarray], ids: list[int], period: np.ndarray | None = None
) -> None:
    n = len(expected_nodes)
    assert g.n_nodes == n
    if n == 0:
        assert g.shortest_paths.shape == (0, 0)
        return
    np.testing.assert_array_equal(g.nodes, np.array(expected_nodes))
    np.testing.assert_array_equal(g.rollout_ids, np.array(ids))
    W = brute_weights(g.nodes, ids, g.eps, g.edge_weight, period, g.temporal_edges)
    np.testing.assert_allclose(g.weights, W, rtol=1e-14, atol=0)
    A = g.adjacency
    assert A.shape == (n, n)
    dense = np.full((n, n), np.inf)
    coo = A.tocoo()
    dense[coo.row, coo.col] = coo.data
    np.testing.assert_array_equal(dense, g.weights)
    D = dijkstra(A, directed=False)
    P = g.shortest_paths
    np.testing.assert_array_equal(np.isinf(P), np.isinf(D))
    np.testing.assert_allclose(P, D, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(P, P.T)


coords = st.floats(-2.0, 2.0, allow_nan=False, width=32)
ops = st.lists(
    st.one_of(
        st.tuples(st.just("add"), st.tuples(coords, coords)),
        st.tuples(st.just("dup"), st.integers(0, 10_000)),
        st.tuples(st.just("del"), st.integers(0, 10_000)),
        st.tuples(st.just("rollout"), st.just(0)),
    ),
    min_size=1,
    max_size=40,
)


def run_ops(g: MDPGraph, sequence: list, period: np.ndarray | None = None) -> None:
    mirror: list[np.ndarray] = []
    ids: list[int] = []
    rollout = g.current_rollout
    for op, arg in sequence:
        if op == "add" or (op == "dup" and mirror):
            x = np.array(arg, dtype=float) if op == "add" else mirror[arg % len(mirror)].copy()
            assert g.add_node(x) == len(mirror)
            mirror.append(x)
            ids.append(rollout)
        elif op == "del" and mirror:
            i = arg % len(mirror)
            g.remove_node(i)
            del mirror[i]
            del ids[i]
        elif op == "rollout":
            rollout = g.start_rollout()
        check_graph(g, mirror, ids, period)


@settings(max_examples=60, deadline=None)
@given(
    sequence=ops,
    eps=st.sampled_from([0.0, 0.05, 0.3, 0.5, 0.9, 1.0]),
    edge_weight=st.sampled_from(["squared", "euclidean"]),
    temporal=st.booleans(),
)
def test_random_add_delete_matches_eq2_and_dijkstra(sequence, eps, edge_weight, temporal):
    g = MDPGraph(eps, edge_weight=edge_weight, temporal_edges=temporal, capacity=2)
    run_ops(g, sequence)


@settings(max_examples=30, deadline=None)
@given(sequence=ops, eps=st.sampled_from([0.3, 0.7]), temporal=st.booleans())
def test_random_add_delete_periodic(sequence, eps, temporal):
    period = np.array([2.0, 0.0])  # first coordinate wraps with period 2 (data spans [-2, 2])
    g = MDPGraph(eps, period=period, temporal_edges=temporal, capacity=3)
    run_ops(g, sequence, period)


def trajectory(rng: np.random.Generator, n: int, d: int = 2, step: float = 0.3) -> np.ndarray:
    return np.cumsum(rng.normal(scale=step, size=(n, d)), axis=0)


@pytest.mark.parametrize("temporal", [False, True])
def test_long_trajectory_with_budget_deletions(temporal):
    """A few hundred adds with interleaved deletions: P exact after every change."""
    rng = np.random.default_rng(3)
    g = MDPGraph(0.3, temporal_edges=temporal)
    mirror: list[np.ndarray] = []
    ids: list[int] = []
    for t, x in enumerate(trajectory(rng, 250)):
        if t % 60 == 0:
            g.start_rollout()
        g.add_node(x)
        mirror.append(x)
        ids.append(g.current_rollout)
        if len(mirror) > 40:
            i = int(rng.integers(len(mirror)))
            g.remove_node(i)
            del mirror[i]
            del ids[i]
        check_graph(g, mirror, ids)


def test_eq2_threshold_is_literal():
    """exp(-||dx||^2) > eps: just inside links, just outside does not."""
    eps = 0.3
    r = np.sqrt(-np.log(eps))
    g = MDPGraph(eps)
    g.add_node([0.0, 0.0])
    g.add_node([r * (1 - 1e-9), 0.0])
    g.add_node([0.0, -r * (1 + 1e-9)])
    W = g.weights
    assert np.isfinite(W[0, 1]) and W[0, 1] == pytest.approx(r**2 * (1 - 1e-9) ** 2)
    assert np.isinf(W[0, 2])
    assert g.shortest_paths[0, 2] == np.inf  # node 2 is isolated: no path


def test_edge_weight_euclidean_changes_weights_not_edges():
    rng = np.random.default_rng(0)
    X = trajectory(rng, 30)
    gs, ge = MDPGraph(0.3), MDPGraph(0.3, edge_weight="euclidean")
    for x in X:
        gs.add_node(x)
        ge.add_node(x)
    Ws, We = gs.weights, ge.weights
    np.testing.assert_array_equal(np.isfinite(Ws), np.isfinite(We))
    fin = np.isfinite(Ws)
    np.testing.assert_allclose(We[fin], np.sqrt(Ws[fin]), rtol=1e-15)
    np.testing.assert_allclose(
        ge.shortest_paths, dijkstra(ge.adjacency, directed=False), rtol=1e-12
    )


def test_periodic_distance_wraps_angles():
    period = np.array([2 * np.pi, 0.0])
    g = MDPGraph(0.3, period=period)
    g.add_node([np.pi - 0.05, 1.0])
    g.add_node([-np.pi + 0.05, 1.0])  # 0.1 rad apart across the seam
    assert g.weights[0, 1] == pytest.approx(0.01, rel=1e-9)
    raw = MDPGraph(0.3)
    raw.add_node([np.pi - 0.05, 1.0])
    raw.add_node([-np.pi + 0.05, 1.0])
    assert np.isinf(raw.weights[0, 1])  # raw angles: 6.18 rad apart, no edge (faithful default)
    _, r2 = g.nearest(np.array([[np.pi, 1.0], [-np.pi, 1.0]]))
    np.testing.assert_allclose(r2, [0.0025, 0.0025], rtol=1e-9)


def test_temporal_edges_link_successive_nodes_of_a_rollout():
    g = MDPGraph(1.0, temporal_edges=True)  # eps = 1: JC12 eq. 2 never links
    for x in ([0.0, 0.0], [5.0, 0.0], [10.0, 0.0]):
        g.add_node(x)
    g.start_rollout()
    g.add_node([5.0, 0.0])  # new roll-out: not linked to node 2
    P = g.shortest_paths
    assert P[0, 2] == pytest.approx(50.0) and np.isinf(P[0, 3])
    g.remove_node(1)  # the chain 0 - 1 - 2 is bridged as 0 - 2
    assert g.weights[0, 1] == pytest.approx(100.0)
    assert g.shortest_paths[0, 1] == pytest.approx(100.0)
    without = MDPGraph(1.0)
    for x in ([0.0, 0.0], [5.0, 0.0]):
        without.add_node(x)
    assert np.isinf(without.shortest_paths[0, 1])


def test_nearest_kdtree_matches_brute_force_including_ties():
    rng = np.random.default_rng(1)
    g = MDPGraph(0.5, period=np.array([2 * np.pi, 0.0, 0.0]))
    grid = np.stack(np.meshgrid(np.linspace(-3, 3, 8), np.linspace(-2, 2, 6), [0.0]), -1).reshape(
        -1, 3
    )
    for x in grid:
        g.add_node(x)
    Q = np.vstack([rng.uniform(-4, 4, size=(2000, 3)), grid + 0.5 * (grid[1] - grid[0])])
    idx, r2 = g.nearest(Q)
    full = g.squared_distances_to_nodes(Q)
    np.testing.assert_array_equal(idx, np.argmin(full, axis=1))
    np.testing.assert_allclose(r2, full.min(axis=1), rtol=1e-12, atol=1e-15)


def test_save_load_round_trip_is_exact_and_continues_identically():
    rng = np.random.default_rng(2)
    g = MDPGraph(0.3, edge_weight="euclidean", period=np.array([0.0, 4.0]), temporal_edges=True)
    X = trajectory(rng, 60)
    for t, x in enumerate(X[:40]):
        if t % 15 == 0:
            g.start_rollout()
        g.add_node(x)
    g.remove_node(7)
    buf = io.BytesIO()
    np.savez(buf, **g.to_arrays())
    buf.seek(0)
    with np.load(buf, allow_pickle=False) as npz:
        h = MDPGraph.from_arrays({k: npz[k] for k in npz.files})
    for attr in ("nodes", "weights", "shortest_paths", "rollout_ids"):
        np.testing.assert_array_equal(getattr(h, attr), getattr(g, attr))
    assert h.current_rollout == g.current_rollout and repr(h) == repr(g)
    for i, x in enumerate(X[40:]):
        g.add_node(x)
        h.add_node(x)
        if i % 3 == 0:
            g.remove_node(i)
            h.remove_node(i)
    np.testing.assert_array_equal(h.shortest_paths, g.shortest_paths)
    np.testing.assert_array_equal(h.weights, g.weights)


def test_delete_recomputes_only_affected_sources():
    """Removing a leaf changes no path between others: zero sources recomputed."""
    g = MDPGraph(0.3)
    for x in ([0.0, 0.0], [0.5, 0.0], [1.0, 0.0], [1.5, 0.0], [1.5, 0.5]):
        g.add_node(x)
    g.remove_node(4)  # pendant leaf
    assert g.last_delete_sources == 0
    g.remove_node(1)  # middle of the chain: its sources are affected
    assert g.last_delete_sources > 0
    check_graph(g, [np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([1.5, 0.0])], [0, 0, 0])


def test_clear_and_errors():
    g = MDPGraph(0.3)
    with pytest.raises(ValueError, match="eps"):
        MDPGraph(1.5)
    with pytest.raises(ValueError, match="edge_weight"):
        MDPGraph(0.3, edge_weight="manhattan")  # type: ignore[arg-type]
    g.add_node([0.0, 1.0])
    with pytest.raises(ValueError, match="expected"):
        g.add_node([0.0, 1.0, 2.0])
    with pytest.raises(IndexError):
        g.remove_node(3)
    g.clear()
    assert g.n_nodes == 0 and g.shortest_paths.shape == (0, 0)
    g.add_node([1.0, 1.0])
    assert g.shortest_paths[0, 0] == 0.0


def test_seeded_random_operations_on_a_lattice_stay_exact_and_symmetric():
    """Coordinates on a coarse lattice make equal-length paths common (sums in different
    orders then differ by an ulp); duplicates make zero-length edges. P must still equal
    Dijkstra and be exactly symmetric after every add, delete and roll-out mark.

    Regression: an add could lower ``P[a, b]`` by an ulp through the new node without
    touching ``P[b, a]`` (found by this sequence, seed 0, within 30 trials).
    """
    rng = np.random.default_rng(0)
    for _ in range(120):
        g = MDPGraph(
            float(rng.choice([0.0, 0.1, 0.3, 0.6, 0.9])),
            edge_weight=str(rng.choice(["squared", "euclidean"])),  # type: ignore[arg-type]
            temporal_edges=bool(rng.integers(2)),
            capacity=2,
        )
        mirror: list[np.ndarray] = []
        ids: list[int] = []
        for _ in range(int(rng.integers(5, 60))):
            r = rng.random()
            if r < 0.55 or len(mirror) < 2:
                if mirror and rng.random() < 0.2:
                    x = mirror[int(rng.integers(len(mirror)))].copy()
                else:
                    x = rng.uniform(-2, 2, 2).round(int(rng.integers(0, 3)))
                g.add_node(x)
                mirror.append(x)
                ids.append(g.current_rollout)
            elif r < 0.9:
                i = int(rng.integers(len(mirror)))
                g.remove_node(i)
                del mirror[i]
                del ids[i]
            else:
                g.start_rollout()
            check_graph(g, mirror, ids)


def test_views_equal_the_copies_are_read_only_and_do_not_copy():
    rng = np.random.default_rng(3)
    g = MDPGraph(0.2, period=[2 * np.pi, 0.0])
    for x in rng.normal(size=(12, 2)):
        g.add_node(x)
    g.remove_node(4)
    views = (g.nodes_view, g.shortest_paths_view, g.weights_view)
    for view, copy in zip(views, (g.nodes, g.shortest_paths, g.weights), strict=True):
        assert np.array_equal(view, copy)
        assert not view.flags.writeable and not view.flags.owndata
        with pytest.raises(ValueError):
            view[0, 0] = 1.0
        assert not np.shares_memory(view, copy)
    assert np.shares_memory(g.nodes_view, g.nodes_view)  # two views of one buffer
    g.add_node([0.1, 0.2])  # the graph itself stays writable
    assert g.shortest_paths_view.shape == (12, 12)
    assert np.array_equal(g.period_or_zeros(2), [2 * np.pi, 0.0])
    assert np.array_equal(MDPGraph().period_or_zeros(3), np.zeros(3))


@settings(max_examples=40, deadline=None)
@given(sequence=ops, eps=st.sampled_from([0.0, 0.3, 0.7, 1.0]), temporal=st.booleans())
def test_lazy_paths_give_the_eager_graphs_edges_components_and_paths(sequence, eps, temporal):
    """``lazy_paths`` (issue 31): the same weights after every change; components and
    reachability from the weights alone while ``P`` is stale; ``P`` exact when read."""
    lazy = MDPGraph(eps, temporal_edges=temporal, capacity=2, lazy_paths=True)
    eager = MDPGraph(eps, temporal_edges=temporal, capacity=2)
    n = 0
    for op, arg in sequence:
        for g in (lazy, eager):
            if op == "add" or (op == "dup" and n):
                x = np.array(arg, dtype=float) if op == "add" else g.nodes[arg % n].copy()
                g.add_node(x)
            elif op == "del" and n:
                g.remove_node(arg % n)
            elif op == "rollout":
                g.start_rollout()
        n = eager.n_nodes
        np.testing.assert_array_equal(lazy.weights_view, eager.weights_view)
        reach = np.isfinite(eager.shortest_paths)
        labels = lazy.component_labels()
        np.testing.assert_array_equal(labels[:, None] == labels[None, :], reach)
        for i in range(n):
            np.testing.assert_array_equal(lazy.reachable_from(i), reach[i])
    P, D = lazy.shortest_paths, eager.shortest_paths
    np.testing.assert_array_equal(np.isinf(P), np.isinf(D))
    np.testing.assert_allclose(P, D, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(P, P.T)


@pytest.mark.parametrize("seed", range(6))
def test_dense_component_labels_and_reachability_match_scipy(seed: int) -> None:
    """Oracle (issue 31): the compiled dense search gives scipy's component labels (same
    numbering) and breadth-first reachability, on graphs with isolated nodes, several
    components and zero-length edges."""
    from scipy.sparse import csr_array
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    from geoq.graph._apsp import dense_components, dense_reachable

    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 60))
    W = np.full((n + 3, n + 3), np.inf)  # a buffer larger than the graph, as MDPGraph's
    for _ in range(int(rng.integers(0, 2 * n))):
        i, j = rng.integers(0, n, size=2)
        if i != j:
            W[i, j] = W[j, i] = 0.0 if rng.random() < 0.1 else rng.random()
    W[n:, :] = W[:, n:] = 1.0  # outside the graph: must be ignored
    mask = np.isfinite(W[:n, :n])
    n_comp, want = connected_components(csr_array(mask), directed=False)
    label = np.empty(n, dtype=np.int64)
    assert dense_components(W, n, label) == n_comp
    np.testing.assert_array_equal(label, want)
    for start in range(n):
        order = breadth_first_order(csr_array(mask), start, directed=False,
                                    return_predecessors=False)  # fmt: skip
        out = np.zeros(n, dtype=np.bool_)
        dense_reachable(W, n, start, out)
        np.testing.assert_array_equal(np.flatnonzero(out), np.sort(order))
