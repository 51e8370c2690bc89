"""``delete_node_paths``: the dense-row and the adjacency-list solvers agree bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from geoq.graph import MDPGraph
from geoq.graph._apsp_delete import DELETE_RTOL, delete_node_paths
from geoq.graph.mdp_graph import _to_csgraph


@pytest.mark.parametrize("eps", [0.0, 0.3, 0.6, 0.9])
@pytest.mark.parametrize("edge_weight", ["squared", "euclidean"])
def test_dense_and_heap_deletes_are_identical_and_exact(eps: float, edge_weight: str) -> None:
    """Lattice coordinates (equal-length paths, duplicate nodes) and temporal edges."""
    rng = np.random.default_rng(int(eps * 10) + (edge_weight == "squared"))
    for trial in range(15):
        g = MDPGraph(eps, edge_weight=edge_weight, temporal_edges=bool(trial % 2))  # type: ignore[arg-type]
        for _ in range(int(rng.integers(3, 45))):
            if rng.random() < 0.1:
                g.start_rollout()
            g.add_node(rng.uniform(-2, 2, 2).round(int(rng.integers(0, 3))))
        n = g.n_nodes
        for v in range(n):
            P0, W = g.shortest_paths, g.weights
            out = {}
            for mode in (0, 1, -1):
                P = P0.copy()
                updated = delete_node_paths(P, W, n, v, DELETE_RTOL, mode)
                out[mode] = (updated, P)
            assert out[0][0] == out[1][0] == out[-1][0]
            assert np.array_equal(out[0][1], out[1][1])
            assert np.array_equal(out[0][1], out[-1][1])
            keep = np.r_[0:v, v + 1 : n]
            P = out[1][1][np.ix_(keep, keep)]
            assert np.array_equal(P, P.T)
            D = dijkstra(_to_csgraph(W[np.ix_(keep, keep)]), directed=False)
            np.testing.assert_allclose(P, D, rtol=1e-12, atol=1e-12)
