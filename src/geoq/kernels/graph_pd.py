"""A positive-definite kernel on the MDP-induced graph: Laplacian of the resistance distance.

The geodesic kernel ``exp(-SP^2 / (2 sigma_sp))`` is not positive definite in
general (Feragen et al., CVPR 2015; a cycle graph is a counterexample, pinned
in ``tests/kernels/test_geodesic.py``). This module offers a kernel on the
*same* graph (eq. 2 edges, same options) that is positive semi-definite on
every finite set of points, nodes or not:

    ``k(x, x') = amplitude * exp(-R(x, x') / lengthscale)``

with ``R`` the **effective resistance** of the graph whose edges are resistors
of resistance = edge weight (``||x_i - x_j||^2`` by default), i.e. conductance
``1 / w``. Off the nodes, a point is a pendant leaf hung on its nearest node by
a resistor of resistance ``w(x - a(x))`` (the same construction as eq. 4), so
``R(x, x_j) = w(x - a(x)) + R[a(x), j]`` and, for two distinct points,
``R(x, y) = w(x - a(x)) + R[a(x), a(y)] + w(y - a(y))``; ``R(x, x) = 0``.

Why it is PD: on any finite set of points, ``R`` is the effective resistance of
one graph (the MDP graph with every off-node point added as a leaf), and
effective resistance is a squared Euclidean distance (``R_ij = (e_i - e_j)^T
L^+ (e_i - e_j)``), hence conditionally negative definite; by Schoenberg's
theorem ``exp(-R / l)`` is then positive semi-definite for every ``l > 0``.
Different components are unreachable (``R = inf``, ``k = 0``): the Gram
matrix is block diagonal with PSD blocks. Zero-length edges (coinciding
points) are short circuits: their end points are merged before ``L^+`` is
formed, so they have ``R = 0`` without an infinite conductance.

Computing ``R`` costs O(n^3) per graph change (a Cholesky solve per connected
component); it is cached until the graph changes.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse
from scipy.sparse.csgraph import connected_components

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import check_positive
from geoq.graph.mdp_graph import EdgeWeight, MDPGraph
from geoq.kernels.geodesic import BasisGraphDistance, GraphKernel, pendant_distances

__all__ = ["ResistanceDistance", "ResistanceKernel", "effective_resistance"]


def effective_resistance(W: FloatArray) -> FloatArray:
    """Effective resistances [n, n] of a graph with edge resistances ``W`` [n, n].

    ``W`` is symmetric, ``inf`` where there is no edge; zero entries are short
    circuits. ``R = inf`` between different connected components.
    """
    n = W.shape[0]
    edge = np.isfinite(W)
    np.fill_diagonal(edge, False)
    short = edge & (W == 0.0)
    n_super, label = connected_components(scipy.sparse.csr_array(short), directed=False)
    rows, cols = np.nonzero(edge & ~short)
    C = np.zeros((n_super, n_super))  # conductances between merged nodes; parallel ones add
    np.add.at(C, (label[rows], label[cols]), 1.0 / W[rows, cols])
    np.fill_diagonal(C, 0.0)
    n_comp, comp = connected_components(scipy.sparse.csr_array(C > 0), directed=False)
    Rq = np.full((n_super, n_super), np.inf)
    for c in range(n_comp):
        idx = np.flatnonzero(comp == c)
        s = idx.size
        if s == 1:
            Rq[idx[0], idx[0]] = 0.0
            continue
        Cc = C[np.ix_(idx, idx)]
        L = np.diag(Cc.sum(axis=1)) - Cc  # [s, s] Laplacian of a connected component
        G = np.zeros((s, s))  # inverse of the Laplacian grounded at node 0 (PD: connected)
        Lg = L[1:, 1:]
        try:
            G[1:, 1:] = scipy.linalg.cho_solve(scipy.linalg.cho_factor(Lg), np.eye(s - 1))
        except np.linalg.LinAlgError:  # conductances spanning ~1e16: fall back to L^+
            G = scipy.linalg.pinvh(L)
        g = np.diag(G)
        Rc = np.maximum(g[:, None] + g[None, :] - 2.0 * G, 0.0)
        np.fill_diagonal(Rc, 0.0)
        Rq[np.ix_(idx, idx)] = 0.5 * (Rc + Rc.T)
    return Rq[np.ix_(label, label)] if n else np.zeros((0, 0))


class ResistanceDistance(BasisGraphDistance):
    """``r^2(x, x') = 2 R(x, x') / lengthscale`` (so ``exp(-r^2/2) = exp(-R / lengthscale)``)."""

    def __init__(self, graph: MDPGraph, lengthscale: float = 1.0) -> None:
        super().__init__(graph)
        self.lengthscale = check_positive(lengthscale, "lengthscale")
        self._cache: tuple[int, FloatArray] | None = None

    @property
    def resistance(self) -> FloatArray:
        """[n, n] effective resistances between the nodes (cached per graph version)."""
        g = self.graph
        if self._cache is None or self._cache[0] != g.version:
            self._cache = (g.version, effective_resistance(g._W[: g.n_nodes, : g.n_nodes]))
        return self._cache[1]

    def resistance_between(self, X: FloatArray, Y: FloatArray | None = None) -> FloatArray:
        """``R`` [N, n] from points to nodes (``Y`` None) or [N, M] between points."""
        return pendant_distances(self.graph, self.resistance, X, Y)

    def _to_r2(self, R: FloatArray) -> FloatArray:
        return 2.0 * R / self.lengthscale

    def squared(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        return self._to_r2(self.resistance_between(X, Y))

    def node_r2(self) -> FloatArray:
        return self._to_r2(self.resistance)

    def to_nodes_r2(self, X: FloatArray) -> FloatArray:
        return self._to_r2(self.resistance_between(X))

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {"lengthscale": np.asarray(self.lengthscale)}
        out.update(super().to_arrays())
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> ResistanceDistance:
        return cls(cls.graph_from_arrays(arrays), lengthscale=float(arrays["lengthscale"]))

    def __repr__(self) -> str:
        return f"ResistanceDistance(lengthscale={self.lengthscale:g}, graph={self.graph!r})"


class ResistanceKernel(GraphKernel):
    """``k = amplitude * exp(-R / lengthscale)`` on the MDP-induced graph; PSD (module doc).

    Parameters
    ----------
    eps, edge_weight, period, temporal_edges, capacity : the graph, exactly as
        for :class:`~geoq.kernels.geodesic.GeodesicKernel` (eq. 2 edges; an
        edge's resistance is its weight).
    lengthscale : resistance scale ``l`` of ``exp(-R / l)``.
    amplitude : ``k(x, x)``.
    """

    def __init__(
        self,
        eps: float = 0.3,
        lengthscale: float = 1.0,
        amplitude: float = 1.0,
        edge_weight: EdgeWeight = "squared",
        period: ArrayLike | None = None,
        temporal_edges: bool = False,
        capacity: int = 64,
    ) -> None:
        graph = MDPGraph(
            eps,
            edge_weight=edge_weight,
            period=period,
            temporal_edges=temporal_edges,
            capacity=capacity,
        )
        super().__init__(ResistanceDistance(graph, lengthscale), variance=amplitude)

    @property
    def lengthscale(self) -> float:
        assert isinstance(self.distance, ResistanceDistance)
        return self.distance.lengthscale

    def __repr__(self) -> str:
        return (
            f"ResistanceKernel(eps={self.eps:g}, lengthscale={self.lengthscale:g}, "
            f"amplitude={self.variance:g}, n_nodes={self.graph.n_nodes})"
        )
