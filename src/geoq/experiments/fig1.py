"""Fig. 1: the MDP-induced graph (JC12 eq. 2) built online from roll-outs, for two ``eps``.

A sparse online GP with the geodesic kernel is fitted to the roll-outs; its
kernel's graph *is* the figure. Degree statistics and connectivity are
reported because they decide whether the graph carries information at all:
a graph where every BV is connected to every other makes the shortest-path
distance the Euclidean one, and a graph of isolated nodes gives zero
covariance between almost every pair.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph

from geoq._typing import FloatArray, IntArray
from geoq.kernels import GeodesicKernel
from geoq.learners import GPQFunction, QGPConfig
from geoq.rollouts import Rollout

__all__ = ["GraphSnapshot", "build_graphs", "graph_statistics"]


@dataclass(frozen=True)
class GraphSnapshot:
    """The graph over the basis set after learning, in raw units.

    Attributes
    ----------
    eps : threshold of JC12 eq. 2.
    nodes : ``[n, d]`` node coordinates in raw units (theta, omega, torque).
    edges : ``[m, 2]`` node index pairs ``i < j``.
    stats : degree and connectivity statistics (:func:`graph_statistics`).
    """

    eps: float
    nodes: FloatArray
    edges: IntArray
    stats: dict[str, Any]


def graph_statistics(adjacency: scipy.sparse.spmatrix | scipy.sparse.sparray) -> dict[str, Any]:
    """Node/edge counts, degree statistics and connected components of a graph."""
    A = scipy.sparse.csr_array(adjacency)
    n = A.shape[0]
    degree = np.diff(A.indptr) if n else np.zeros(0, dtype=np.int64)
    n_comp, labels = scipy.sparse.csgraph.connected_components(A, directed=False)
    sizes = np.bincount(labels) if n else np.zeros(0, dtype=np.int64)
    return {
        "n_nodes": int(n),
        "n_edges": int(A.nnz // 2),
        "mean_degree": float(np.mean(degree)) if n else 0.0,
        "median_degree": float(np.median(degree)) if n else 0.0,
        "max_degree": int(np.max(degree)) if n else 0,
        "isolated_nodes": int(np.count_nonzero(degree == 0)),
        "density": float(A.nnz / (n * (n - 1))) if n > 1 else 0.0,
        "n_components": int(n_comp),
        "largest_component_fraction": float(np.max(sizes) / n) if n else 0.0,
    }


def build_graphs(
    rollouts: Sequence[Rollout], learner: QGPConfig, eps_values: Sequence[float], max_bv: int
) -> list[GraphSnapshot]:
    """Fit a geodesic GP per ``eps`` to ``rollouts`` and snapshot its graph."""
    snapshots = []
    for eps in eps_values:
        cfg = learner.replace(kernel="nearest", eps=float(eps), max_bv=int(max_bv), refit="none")
        q = GPQFunction(cfg).fit(rollouts)
        assert q.gp_ is not None and isinstance(q.gp_.kernel, GeodesicKernel)
        graph = q.gp_.kernel.graph
        A = scipy.sparse.triu(scipy.sparse.csr_array(graph.adjacency), k=1).tocoo()
        edges = np.column_stack([A.row, A.col]).astype(np.int64)
        nodes = cfg.scaling.inverse(graph.nodes)
        snapshots.append(GraphSnapshot(float(eps), nodes, edges, graph_statistics(graph.adjacency)))
    return snapshots
