"""A positive-definite kernel on the MDP-induced graph: Laplacian of the resistance distance.

The geodesic kernel ``exp(-SP^2 / (2 sigma_sp))`` is not positive definite in
general (Feragen et al., CVPR 2015; a cycle graph is a counterexample, pinned
in ``tests/kernels/test_geodesic.py``). This module offers a kernel on the
*same* graph (JC12 eq. 2 edges, same options) that is positive semi-definite on
every finite set of points, nodes or not:

    ``k(x, x') = amplitude * exp(-R(x, x') / lengthscale)``

with ``R`` the **effective resistance** of the graph whose edges are resistors
of resistance = edge weight (``||x_i - x_j||^2`` by default), i.e. conductance
``1 / w``. Off the nodes, a point is a pendant leaf hung on its nearest node by
a resistor of resistance ``w(x - a(x))`` (the same construction as JC12 eq. 4), so
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

Incremental updates (``ResistanceDistance`` follows the GP's basis set node by
node, O(s^2 k) per change for a component of ``s`` nodes and a node of degree
``k``, matrix products only; the from-scratch computation is O(s^3)). They pay
on sparse graphs: where ``k`` is a sizeable fraction of ``s`` (``eps = 0.3`` on
the scaled pendulum inputs links a node to ~70% of the others) an update costs
about as much as a recomputation, so above ``ResistanceDistance.RANK_FRACTION``
the distance marks ``R`` stale and recomputes it once at its next use, which
also absorbs every further change before that use (the GP adds and deletes a
node per point, then reads ``K_BV`` once).

The algebra (:mod:`geoq.kernels._resistance`): an added node is hung as a leaf
on its strongest neighbour, an edge into another component merges it (series
rule), the remaining edges close cycles and enter at once by Woodbury on
``L^+`` written in ``R`` alone; a removed node is shorted to its strongest
neighbour, then its other edges are taken out by Woodbury. The component is
recomputed from scratch (O(s^3)) where that does not apply: the removal splits
it (a cut vertex, read off the graph's exact shortest paths), the node has a
zero-length edge, or a capacitance matrix fails its Cholesky factorisation.
Removing the node added last, before any other change (the GP's "add, then
delete the least useful BV", often the new one: 370 of 550 deletions in
``benchmarks/bench_resistance.py``), restores ``R`` from before the addition.
An edge the graph adds or shortens while removing a node (the temporal bridge
between the node's roll-out neighbours) is a parallel resistor, added before
the node leaves.

The updates agree with :func:`effective_resistance` to rounding: the oracle test
(``tests/kernels/test_graph_pd.py``, random add/remove sequences with short
circuits, several components and splits) holds them within ``1e-9`` relative
(absolute ``1e-9`` times the largest finite resistance). Any change the
distance did not see node by node (a graph edited directly, a loaded graph)
triggers one recomputation from scratch at the next use.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoq._threads import one_blas_thread, single_blas_thread
from geoq._typing import ArrayLike, FloatArray, IntArray
from geoq._validation import check_positive
from geoq.graph.mdp_graph import EdgeWeight, MDPGraph
from geoq.kernels._graph_paths import pendant_distances
from geoq.kernels._resistance import (
    add_edges,
    components_of,
    effective_resistance,
    parallel_part,
    remove_node_resistances,
)
from geoq.kernels.geodesic import GraphKernel
from geoq.kernels.graph_distance import BasisGraphDistance

__all__ = [
    "ResistanceDistance",
    "ResistanceKernel",
    "add_edges",
    "components_of",
    "effective_resistance",
    "remove_node_resistances",
]


class ResistanceDistance(BasisGraphDistance):
    """``r^2(x, x') = 2 R(x, x') / lengthscale`` (so ``exp(-r^2/2) = exp(-R / lengthscale)``).

    ``R`` between the nodes is kept current node by node through the basis hooks
    (module docstring: O(s^2 r) for an update of rank ``r``) while that is cheaper
    than recomputing (``RANK_FRACTION``); otherwise, and after any change of the
    graph the hooks did not see (caught by its version), it is recomputed from
    scratch at its next use.
    """

    #: An update of rank ``r`` (the cycle-closing edges of an added node, the edges of a
    #: removed node minus one) in a component of ``s`` nodes costs O(s^2 r), about
    #: ``r / s`` of a recomputation (timings: ``docs/design-notes.md``). It is applied
    #: when ``r <= max(RANK_FLOOR, RANK_FRACTION * s)``; a larger one (a dense
    #: neighbourhood) leaves ``R`` stale, and the next use recomputes it once, whatever
    #: the number of changes in between (the GP's add + delete per point).
    RANK_FRACTION = 0.25
    RANK_FLOOR = 8

    def __init__(self, graph: MDPGraph, lengthscale: float = 1.0) -> None:
        super().__init__(graph)
        self.lengthscale = check_positive(lengthscale, "lengthscale")
        self._R = np.zeros((0, 0))  # [n, n] effective resistances, valid at self._version
        self._version = -1
        #: Diagnostics: recomputations from scratch of the whole graph / of one component.
        self.n_full_recomputes = 0
        self.n_component_recomputes = 0
        #: Removals of the node added last, undone by restoring ``R`` from before its addition.
        self.n_undone = 0
        self._undo: tuple[int, FloatArray] | None = None  # (graph version after an add, R before)

    # -- state ------------------------------------------------------------------------------
    def _current(self) -> FloatArray:
        """[n, n] effective resistances of the current graph (the internal array: do not edit)."""
        g = self.graph
        if self._version != g.version:
            n = g.n_nodes
            with one_blas_thread():
                self._R = effective_resistance(g._W[:n, :n], g.component_labels())
            self._version = g.version
            self.n_full_recomputes += 1
        return self._R

    @property
    def resistance(self) -> FloatArray:
        """[n, n] effective resistances between the nodes (a copy); ``inf`` across components."""
        return self._current().copy()

    def _cheap(self, rank: int, size: int) -> bool:
        """Whether an update of rank ``rank`` in a component of ``size`` nodes beats a recompute."""
        return rank <= max(self.RANK_FLOOR, self.RANK_FRACTION * size)

    def _component(self, node: int) -> IntArray | None:
        """Indices of ``node``'s component, or None if it is the whole graph."""
        finite = np.isfinite(self._R[node])
        return None if finite.all() else np.flatnonzero(finite)

    def _recompute(self, idx: IntArray | None) -> None:
        """Effective resistances of the nodes ``idx`` (None: all) from scratch."""
        W = self.graph.weights_view
        if idx is None:
            self._R = effective_resistance(W)
        else:
            self._R[np.ix_(idx, idx)] = effective_resistance(W[np.ix_(idx, idx)])
        self.n_component_recomputes += 1

    def _update_component(
        self,
        node: int,
        fn: Callable[[FloatArray, Callable[[IntArray], IntArray]], FloatArray | None],
    ) -> bool:
        """Apply ``fn(R_c, local)`` to ``node``'s component ``R_c``; False if it returned None.

        ``local`` maps global node indices to positions in ``R_c``.
        """
        idx = self._component(node)
        if idx is None:
            new = fn(self._R, lambda i: i)
            if new is None:
                return False
            self._R = new
            return True
        new = fn(self._R[np.ix_(idx, idx)], lambda i: np.searchsorted(idx, i))
        if new is None:
            return False
        self._R[np.ix_(idx, idx)] = new
        return True

    def _add_edges(self, p: int, q: IntArray, w: FloatArray) -> bool:
        """Edges ``p - q_e`` of resistances ``w_e`` inside ``p``'s component; False if singular."""
        return self._update_component(
            p, lambda Rc, loc: add_edges(Rc, int(loc(np.asarray(p))), loc(q), w)
        )

    def _merge(self, v: int, b: int, w: float) -> None:
        """A resistor ``w`` from ``v`` to ``b`` in another component: a bridge, series rule."""
        R = self._R
        X = np.flatnonzero(np.isfinite(R[v]))
        Z = np.flatnonzero(np.isfinite(R[b]))
        block = np.add.outer(R[X, v] + w, R[b, Z])  # R[x, v] + w + R[b, z]
        R[np.ix_(X, Z)] = block
        R[np.ix_(Z, X)] = block.T

    # -- basis hooks ------------------------------------------------------------------------
    @single_blas_thread  # products of [s, k] matrices: one BLAS thread
    def basis_added(self, x: FloatArray) -> None:
        g = self.graph
        if self._version != g.version:  # already stale: the next use recomputes
            super().basis_added(x)
            self._undo = None
            return
        self._version = -1  # stale until the update below has finished
        super().basis_added(x)
        self._undo = (g.version, self._R)  # R before the add (never edited in place)
        v = g.n_nodes - 1
        w_row = g.weights_view[v, :v]  # resistances of the new node's edges (inf: none)
        R = np.full((v + 1, v + 1), np.inf)
        R[:v, :v] = self._R
        R[v, v] = 0.0
        self._R = R
        nbr = np.flatnonzero(np.isfinite(w_row))
        if nbr.size:
            nbr = nbr[np.argsort(w_row[nbr], kind="stable")]
            a = int(nbr[0])
            R[v, :v] = R[a, :v] + w_row[a]  # a leaf on its strongest neighbour
            R[:v, v] = R[v, :v]
            cycle = []
            for b in nbr[1:].tolist():
                if np.isinf(R[v, b]):
                    self._merge(v, b, float(w_row[b]))
                else:
                    cycle.append(b)
            if cycle:
                if not self._cheap(len(cycle), int(np.isfinite(R[v]).sum())):
                    return  # stale: one recomputation at the next use is cheaper
                q = np.asarray(cycle)
                if not self._add_edges(v, q, w_row[q]):
                    self._recompute(self._component(v))
        self._version = g.version

    @single_blas_thread  # products of [s, k] matrices: one BLAS thread
    def basis_removed(self, index: int) -> None:
        g = self.graph
        n, v = g.n_nodes, int(index)
        undo, self._undo = self._undo, None
        if undo is not None and undo[0] == g.version and v == n - 1:
            # The node added last leaves before any other change: the graph's edges are
            # back to what they were (no temporal bridge: it has no successor), so is R.
            super().basis_removed(v)
            self._R, self._version = undo[1], g.version
            self.n_undone += 1
            return
        if self._version != g.version or not 0 <= v < n:  # stale, or the graph raises
            super().basis_removed(index)
            return
        self._version = -1
        w_row = g.weights_view[v].copy()
        w_row[v] = np.inf
        nbr = np.flatnonzero(np.isfinite(w_row))
        if not self._cheap(nbr.size - 1, int(np.isfinite(self._R[v]).sum())):
            super().basis_removed(v)
            return  # stale: one recomputation at the next use is cheaper
        W_nbr = g.weights_view[np.ix_(nbr, nbr)]  # a copy (fancy indexing)
        comp = self._component(v)
        super().basis_removed(v)
        new = nbr - (nbr > v)  # neighbours' indices after the removal
        ok = self._bridges(nbr, W_nbr, g.weights_view[np.ix_(new, new)])
        if ok and nbr.size >= 2:
            split = not bool(g.reachable_from(int(new[0]))[new].all())
            w = w_row[nbr]
            ok = not split and bool(np.all(w > 0.0))
            if ok:
                ok = self._update_component(
                    v,
                    lambda Rc, loc: remove_node_resistances(
                        Rc, int(loc(np.asarray(v))), loc(nbr), w
                    ),
                )
        keep = np.r_[0:v, v + 1 : n]
        self._R = self._R[np.ix_(keep, keep)]
        if not ok:
            self._recompute(None if comp is None else comp[comp != v] - (comp[comp != v] > v))
        self._version = g.version

    def _bridges(self, nbr: IntArray, W_old: FloatArray, W_new: FloatArray) -> bool:
        """Add the edges among ``v``'s neighbours that the graph created or shortened while
        removing ``v`` (temporal bridges) as parallel resistors, ``v`` still present.

        False if an edge changed otherwise (then the caller recomputes).
        """
        changed = np.argwhere(np.triu(W_new != W_old, 1))
        for i, j in changed.tolist():
            w_old, w_new = float(W_old[i, j]), float(W_new[i, j])
            if not w_new < w_old:
                return False
            r = parallel_part(w_old, w_new)
            if not self._add_edges(int(nbr[i]), nbr[j : j + 1], np.array([r])):
                return False
        return True

    def basis_cleared(self) -> None:
        super().basis_cleared()
        self._R = np.zeros((0, 0))
        self._undo = None
        self._version = self.graph.version

    # -- distances --------------------------------------------------------------------------
    def resistance_between(self, X: FloatArray, Y: FloatArray | None = None) -> FloatArray:
        """``R`` [N, n] from points to nodes (``Y`` None) or [N, M] between points."""
        return pendant_distances(self.graph, self._current(), X, Y)

    def _to_r2(self, R: FloatArray) -> FloatArray:
        return 2.0 * R / self.lengthscale

    def squared(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        return self._to_r2(self.resistance_between(X, Y))

    def node_r2(self) -> FloatArray:
        return self._to_r2(self._current())

    def to_nodes_r2(self, X: FloatArray) -> FloatArray:
        return self._to_r2(self.resistance_between(X))

    # -- persistence ------------------------------------------------------------------------
    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {"lengthscale": np.asarray(self.lengthscale)}
        out.update(super().to_arrays())
        out["resistance"] = self._current().copy()  # restored bit for bit, not recomputed
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> ResistanceDistance:
        graph = cls.graph_from_arrays(arrays)
        graph.lazy_paths = True  # as ResistanceKernel makes it (not saved)
        out = cls(graph, lengthscale=float(arrays["lengthscale"]))
        if "resistance" in arrays:  # files written before the incremental updates have none
            R = np.asarray(arrays["resistance"], dtype=np.float64)
            g = out.graph
            P = g.shortest_paths_view
            if (
                R.shape != P.shape
                or not np.array_equal(np.isinf(R), np.isinf(P))
                or np.any(np.isnan(R))
                or np.any(R < 0.0)
                or not np.array_equal(R, R.T)
            ):
                raise ValueError(
                    "saved effective resistances do not match the saved graph; save it again"
                )
            out._R, out._version = R, g.version
        return out

    def __repr__(self) -> str:
        return f"ResistanceDistance(lengthscale={self.lengthscale:g}, graph={self.graph!r})"


class ResistanceKernel(GraphKernel):
    """``k = amplitude * exp(-R / lengthscale)`` on the MDP-induced graph; PSD (module doc).

    Parameters
    ----------
    eps, edge_weight, period, temporal_edges, capacity : the graph, exactly as
        for :class:`~geoq.kernels.geodesic.GeodesicKernel` (JC12 eq. 2 edges; an
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
            lazy_paths=True,  # R needs components and reachability only
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
