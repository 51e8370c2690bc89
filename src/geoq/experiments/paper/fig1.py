"""Fig. 1: the MDP-induced graph (JC12 eq. 2) built online from roll-outs, for two ``eps``.

A sparse online GP with the geodesic kernel is fitted to the roll-outs; its
kernel's graph *is* the figure. Degree statistics and connectivity are
reported because they decide whether the graph carries information at all:
a graph where every BV is connected to every other makes the shortest-path
distance the Euclidean one, and a graph of isolated nodes gives zero
covariance between almost every pair.

Which way ``eps`` works. The paper's text says the number of edges "increases
exponentially with eps", but its JC12 eq. 2 links ``x_i`` and ``x_t`` iff
``exp(-||x_i - x_t||^2) > eps``, i.e. iff ``||x_i - x_t||^2 < -ln(eps)``: a *larger*
``eps`` is a *smaller* radius and gives *fewer* edges, so Fig. 1 (b) (``eps = 0.5``)
must have fewer edges than (a) (``eps = 0.3``). geoq follows JC12 eq. 2 as written.
:func:`edge_counts_by_eps` measures both readings' consequence on the Fig. 1 data:
the edges of the same node set re-linked by JC12 eq. 2 at each ``eps`` (monotone
non-increasing by construction), and of the graph rebuilt online at each ``eps``
(the node set then changes too, since novelty depends on the kernel).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph

from geoq._typing import FloatArray, IntArray
from geoq.graph import MDPGraph
from geoq.kernels import GeodesicKernel
from geoq.learners import GPQFunction, QGPConfig
from geoq.rollouts import Rollout

__all__ = [
    "EDGE_COUNT_COLUMNS",
    "GraphSnapshot",
    "build_graphs",
    "edge_counts_by_eps",
    "graph_statistics",
    "relink",
]

#: Column order of ``fig1_eps.csv``.
EDGE_COUNT_COLUMNS = (
    "mode",
    "node_eps",
    "eps",
    "n_nodes",
    "n_edges",
    "mean_degree",
    "isolated_nodes",
    "n_components",
    "largest_component_fraction",
)


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


def _fitted_graph(
    rollouts: Sequence[Rollout], learner: QGPConfig, eps: float, max_bv: int
) -> MDPGraph:
    """The MDP graph (scaled units) of a geodesic GP fitted to ``rollouts`` with ``eps``."""
    cfg = learner.replace(kernel="nearest", eps=float(eps), max_bv=int(max_bv), refit="none")
    q = GPQFunction(cfg).fit(rollouts)
    assert q.gp_ is not None and isinstance(q.gp_.kernel, GeodesicKernel)
    return q.gp_.kernel.graph


def build_graphs(
    rollouts: Sequence[Rollout], learner: QGPConfig, eps_values: Sequence[float], max_bv: int
) -> list[GraphSnapshot]:
    """Fit a geodesic GP per ``eps`` to ``rollouts`` and snapshot its graph."""
    snapshots = []
    for eps in eps_values:
        graph = _fitted_graph(rollouts, learner, eps, max_bv)
        A = scipy.sparse.triu(scipy.sparse.csr_array(graph.adjacency), k=1).tocoo()
        edges = np.column_stack([A.row, A.col]).astype(np.int64)
        nodes = learner.scaling.inverse(graph.nodes)
        snapshots.append(GraphSnapshot(float(eps), nodes, edges, graph_statistics(graph.adjacency)))
    return snapshots


def relink(nodes: FloatArray, eps: float, period: FloatArray | None = None) -> MDPGraph:
    """The graph of JC12 eq. 2 at threshold ``eps`` over fixed ``nodes`` [n, d] (scaled units).

    Proximity edges only (no temporal edges); ``period`` as in :class:`MDPGraph`.
    """
    graph = MDPGraph(eps, period=period)
    for x in np.asarray(nodes, dtype=np.float64):
        graph.add_node(x)
    return graph


def edge_counts_by_eps(
    rollouts: Sequence[Rollout],
    learner: QGPConfig,
    node_eps: Sequence[float],
    eps_values: Sequence[float],
    max_bv: int,
) -> list[dict[str, Any]]:
    """Edge counts, mean degree and components of the Fig. 1 graphs over a range of ``eps``.

    Rows of two kinds (``mode``):

    * ``"same nodes"``: for each ``e0`` in ``node_eps`` (the Fig. 1 panels), the basis
      set the GP kept with ``eps = e0`` re-linked by JC12 eq. 2 at every ``eps`` in
      ``eps_values``: the effect of the threshold alone.
    * ``"rebuilt"``: a GP fitted with ``eps`` itself (what Fig. 1 would show for that
      ``eps``; ``node_eps`` is then ``eps``).
    """
    rows: list[dict[str, Any]] = []
    keys = EDGE_COUNT_COLUMNS[3:]
    for e0 in node_eps:
        graph = _fitted_graph(rollouts, learner, e0, max_bv)
        for eps in eps_values:
            stats = graph_statistics(relink(graph.nodes, float(eps), graph.period).adjacency)
            rows.append(
                {"mode": "same nodes", "node_eps": float(e0), "eps": float(eps)}
                | {k: stats[k] for k in keys}
            )
    for eps in eps_values:
        stats = graph_statistics(_fitted_graph(rollouts, learner, eps, max_bv).adjacency)
        rows.append(
            {"mode": "rebuilt", "node_eps": float(eps), "eps": float(eps)}
            | {k: stats[k] for k in keys}
        )
    return rows
