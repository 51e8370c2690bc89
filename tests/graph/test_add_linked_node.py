"""MDPGraph.add_node (fused neighbour selection) against the numpy JC12 eq. 2 selection,
bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.graph import MDPGraph
from geoq.graph._apsp import add_node_paths


def _reference_add(g: MDPGraph, P: np.ndarray, W: np.ndarray, x: np.ndarray, ids: list) -> None:
    """The former add_node: np.exp(-r2) > eps, temporal predecessor, flatnonzero order."""
    n = len(ids)
    r2 = g.squared_distances(x[None, :], g._X[:n])[0]
    link = np.exp(-r2) > g.eps
    w = g.weight_of(r2)
    if g.temporal_edges:
        same = np.flatnonzero(np.asarray(ids, dtype=np.int64) == g.current_rollout)
        if same.size:
            link[same[-1]] = True
    nbr = np.flatnonzero(link).astype(np.int64)
    add_node_paths(P, W, n, nbr, w[nbr], np.empty(n + 1), np.empty(n + 1, dtype=np.int64))
    ids.append(g.current_rollout)


@pytest.mark.parametrize(
    "kw",
    [
        {"eps": 0.3},
        {"eps": 0.9, "temporal_edges": True},
        {"eps": 0.6, "edge_weight": "euclidean", "period": [2 * np.pi, 0.0]},
        {"eps": 1.0, "temporal_edges": True, "edge_weight": "euclidean"},
    ],
)
def test_add_node_matches_numpy_selection(kw: dict) -> None:
    rng = np.random.default_rng(0)
    X = np.cumsum(rng.normal(scale=0.5, size=(120, 2)), axis=0)
    g = MDPGraph(capacity=4, **kw)
    cap = 128
    P, W = np.full((cap, cap), np.inf), np.full((cap, cap), np.inf)
    ids: list = []
    for t, x in enumerate(X):
        if t % 30 == 0:
            g.start_rollout()
        _reference_add(g, P, W, x, ids)
        g.add_node(x)
        n = g.n_nodes
        assert np.array_equal(g.shortest_paths, P[:n, :n])
        assert np.array_equal(g.weights, W[:n, :n])
