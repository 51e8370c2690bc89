"""The online MDP-induced graph over the GP's basis vectors, with exact incremental APSP.

JC12 §4 and eq. 2: when ``x_t`` enters the basis set it becomes a node, linked
to every node ``x_i`` with ``exp(-||x_i - x_t||^2) > eps`` by an edge of weight
``||x_i - x_t||^2``. When the GP deletes a basis vector its node goes too. The
all-pairs shortest-path matrix ``P`` (``inf`` = unreachable) is kept equal to
what Dijkstra gives on the current graph after every change:

* **add** (O(n^2) worst case): ``d(v, j) = min_i w(v, i) + P[i, j]`` over the
  neighbours ``i`` of ``v``, then ``P = min(P, d[:, None] + d[None, :])``. Only
  rows whose best neighbour of ``v`` takes part in a *shortcut* (a neighbour
  pair ``i, k`` with ``w(v, i) + w(v, k) < P[i, k]``) can change, so the
  O(n^2) pass is skipped when ``v`` creates no shortcut (the common case on
  trajectories), and restricted to the useful rows otherwise.
* **delete** node ``v``: for a source ``a`` only the targets ``T_a`` with a
  shortest path through ``v`` (``P[a, v] + P[v, b] == P[a, b]``, tested with a
  relative slack) can change. They are recomputed by a compiled Dijkstra
  restricted to ``T_a`` and seeded from the unchanged distances
  (:func:`geoq.graph._apsp.delete_node_paths`): the work is about the
  betweenness of ``v`` times the degree, not one full Dijkstra per affected
  source (``benchmarks/bench_graph.py`` compares it with
  ``scipy.sparse.csgraph.dijkstra(indices=affected)``). On graphs with many
  edges per node (``DENSE_DELETE_FILL``) the restricted Dijkstra scans dense
  weight rows instead of adjacency lists and a heap, with bit-identical results.

Options beyond the paper, all off by default:

* ``edge_weight="euclidean"``: edges weigh ``||x_i - x_j||`` instead of the
  squared distance (the JC12 eq. 2 *criterion* is unchanged).
* ``period``: per-dimension wrap-around period (``0`` = ordinary dimension),
  with the convention of :class:`geoq.kernels.stationary.Euclidean`: the
  difference on a periodic dimension is taken on the circle, so ``theta = pi``
  and ``-pi`` are the same point. Used for the JC12 eq. 2 criterion, the edge
  weights and every distance the kernels take to nodes.
* ``temporal_edges=True``: successive basis vectors *of the same roll-out* are
  also linked (weight = the same edge weight, whatever ``eps`` says). Call
  :meth:`MDPGraph.start_rollout` before the points of each new roll-out; nodes
  remember their roll-out id. Successive means successive among the nodes that
  currently exist: when a node is deleted, its temporal predecessor and
  successor are linked, so every roll-out stays a chain.

Nearest-node queries use a cached :class:`scipy.spatial.cKDTree` for large
batches (it pays for prediction on grids); single-point queries and the
JC12 eq. 2 neighbour search of an added node are brute force, O(n d), which is
cheaper than rebuilding a tree after every change (measured in
``benchmarks/bench_graph.py``).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.sparse
from scipy.sparse.csgraph import shortest_path
from scipy.spatial import cKDTree

from geoq._geometry import (
    as_period_vector,
    squared_distances_row,
    wrap_difference,
    wrapped_squared_distances,
)
from geoq._typing import ArrayLike, FloatArray, IntArray
from geoq._validation import as_float_point
from geoq.graph._apsp import add_linked_node, dense_components, dense_reachable, insert_edge
from geoq.graph._apsp_delete import DELETE_RTOL, delete_node_paths, drop_index
from geoq.graph._persist import graph_from_arrays, graph_to_arrays

__all__ = ["EdgeWeight", "MDPGraph"]

EdgeWeight = Literal["squared", "euclidean"]

#: Batch size (queries x nodes) from which nearest-node queries use the KD-tree.
_KDTREE_MIN_WORK = 50_000
_KDTREE_MIN_QUERIES = 32


class MDPGraph:
    """Online graph over basis vectors with exact all-pairs shortest paths (JC12 eq. 2).

    Parameters
    ----------
    eps : edge threshold in ``[0, 1]``: nodes ``i, t`` are linked iff
        ``exp(-||x_i - x_t||^2) > eps`` (JC12 eq. 2). ``eps = 0`` links every pair,
        ``eps = 1`` none.
    edge_weight : ``"squared"`` (JC12 eq. 2, default) or ``"euclidean"``.
    period : optional per-dimension wrap-around period ``[d]`` (``0`` = ordinary).
    temporal_edges : also link successive nodes of the same roll-out.
    capacity : initial size of the preallocated buffers; they double when full.
    lazy_paths : keep ``P`` exact only when it is read: a removed node leaves it
        stale (no update of the paths through the node, the costly part), and the next
        read recomputes it from the weights (scipy's shortest paths). For a graph whose
        owner reads ``P`` rarely: the resistance kernel reads only components and
        reachability (:meth:`component_labels`, :meth:`reachable_from`), which come
        from the weights without ``P``. Not saved: a loaded graph keeps ``P`` current.

    Attributes (returned as copies)
    ----------
    nodes : [n, d] node coordinates, in insertion order (= the GP's BV order).
    adjacency : scipy.sparse.csr_array [n, n] of edge weights (explicit zeros
        are zero-length edges between coinciding points).
    shortest_paths : [n, n] matrix ``P``; ``inf`` where unreachable, 0 on the diagonal.
    weights : [n, n] dense edge weights; ``inf`` where there is no edge.
    rollout_ids : [n] roll-out id of each node.

    ``nodes_view``, ``shortest_paths_view`` and ``weights_view`` are the same arrays
    as read-only views without a copy, for hot paths (valid until the next change).
    """

    def __init__(
        self,
        eps: float = 0.3,
        *,
        edge_weight: EdgeWeight = "squared",
        period: ArrayLike | None = None,
        temporal_edges: bool = False,
        capacity: int = 16,
        lazy_paths: bool = False,
    ) -> None:
        eps = float(eps)
        if not 0.0 <= eps <= 1.0:
            raise ValueError(f"eps must lie in [0, 1] (JC12 eq. 2), got {eps!r}")
        if edge_weight not in ("squared", "euclidean"):
            raise ValueError(f"edge_weight must be 'squared' or 'euclidean', got {edge_weight!r}")
        self.eps = eps
        self.edge_weight: EdgeWeight = edge_weight
        self.period = as_period_vector(period, None)
        self.temporal_edges = bool(temporal_edges)
        self.lazy_paths = bool(lazy_paths)
        self._paths_stale = False  # P[:n, :n] not the shortest paths (lazy_paths only)
        self._zero_period: FloatArray | None = None
        self._dim: int | None = None if self.period is None else int(self.period.shape[0])
        self._cap = max(int(capacity), 1)
        self._n = 0
        self._rollout = 0
        self._alloc(self._cap, self._dim or 0)
        self._tree: cKDTree | None = None
        #: Incremented by every change of nodes or edges (lets dependants cache derived state).
        self.version = 0
        #: Diagnostics: rows scanned by the last add, sources recomputed by the last delete.
        self.last_add_rows = 0
        self.last_delete_sources = 0

    # -- storage ------------------------------------------------------------------------
    def _alloc(self, cap: int, dim: int) -> None:
        self._view_cache: tuple[FloatArray, FloatArray, FloatArray] | None = None
        self._X = np.zeros((cap, dim))
        self._W = np.full((cap, cap), np.inf)  # dense edge weights, inf = no edge
        self._P = np.full((cap, cap), np.inf)
        self._ids = np.zeros(cap, dtype=np.int64)
        self._d = np.empty(cap)
        self._via = np.empty(cap, dtype=np.int64)
        self._r2 = np.empty(cap)  # scratch of add_node
        self._neg = np.empty(cap)
        self._nbr = np.empty(cap, dtype=np.int64)
        self._wn = np.empty(cap)

    def _grow(self) -> None:
        n, old = self._n, (self._X, self._W, self._P, self._ids)
        self._cap = max(2 * self._cap, 16)
        self._alloc(self._cap, self._X.shape[1])
        self._X[:n] = old[0][:n]
        self._W[:n, :n] = old[1][:n, :n]
        self._P[:n, :n] = old[2][:n, :n]
        self._ids[:n] = old[3][:n]

    # -- read-only views ----------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        """Number of nodes ``n``."""
        return self._n

    def __len__(self) -> int:
        return self._n

    @property
    def dim(self) -> int | None:
        """Input dimension ``d`` (None until the first node, unless ``period`` fixes it)."""
        return self._dim

    @property
    def nodes(self) -> FloatArray:
        """[n, d] node coordinates (a copy)."""
        return self._X[: self._n].copy()

    @property
    def shortest_paths(self) -> FloatArray:
        """[n, n] shortest-path lengths ``P`` (a copy); ``inf`` where unreachable."""
        self._refresh_paths()
        return self._P[: self._n, : self._n].copy()

    def _refresh_paths(self) -> None:
        """Recompute a stale ``P`` (``lazy_paths``) from the weights, in place."""
        if self._paths_stale:
            n = self._n
            if n:
                P = shortest_path(_to_csgraph(self._W[:n, :n]), method="D", directed=False)
                self._P[:n, :n] = np.minimum(P, P.T)  # exactly symmetric, as the updates keep it
            self._paths_stale = False

    def component_labels(self) -> IntArray:
        """[n] connected-component label of each node (from the weights; ``P`` not needed)."""
        n = self._n
        label = np.empty(n, dtype=np.int64)
        dense_components(self._W, n, label)  # scipy's numbering, without the sparse copy
        return label

    def reachable_from(self, i: int) -> np.ndarray:
        """[n] whether each node is connected to node ``i`` (itself included)."""
        n = self._n
        if not self._paths_stale:
            return np.isfinite(self._P[i, :n])
        if not 0 <= int(i) < n:
            raise IndexError(f"node {i} out of range for a graph of {n} nodes")
        out = np.zeros(n, dtype=np.bool_)
        dense_reachable(self._W, n, int(i), out)
        return out

    @property
    def weights(self) -> FloatArray:
        """[n, n] dense edge weights (a copy); ``inf`` where there is no edge."""
        return self._W[: self._n, : self._n].copy()

    # Views without a copy, for code that reads the graph once per point (the kernels'
    # rows): O(1) instead of the O(n^2) copies above. Read-only (writing raises), made
    # once per change of the graph, and a view shows the graph as it was when taken:
    # take a new one after any change (an added node may move the buffers).
    @property
    def nodes_view(self) -> FloatArray:
        """[n, d] node coordinates as a read-only view of the graph's buffer (no copy)."""
        return (self._view_cache or self._views())[0]

    @property
    def shortest_paths_view(self) -> FloatArray:
        """[n, n] shortest paths ``P`` as a read-only view of the graph's buffer (no copy)."""
        self._refresh_paths()
        return (self._view_cache or self._views())[1]

    @property
    def weights_view(self) -> FloatArray:
        """[n, n] dense edge weights as a read-only view of the graph's buffer (no copy)."""
        return (self._view_cache or self._views())[2]

    def _views(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        views = self._view_cache
        if views is None:
            n = self._n
            views = self._view_cache = (
                _read_only(self._X[:n]),
                _read_only(self._P[:n, :n]),
                _read_only(self._W[:n, :n]),
            )
        return views

    def __getstate__(self) -> dict[str, object]:
        """Copies (``copy.deepcopy``, pickling) leave out the cached views: a deep copy
        would turn them into arrays independent of the copied buffers."""
        state = dict(self.__dict__)
        state["_view_cache"] = None
        return state

    @property
    def adjacency(self) -> scipy.sparse.csr_array:
        """[n, n] sparse matrix of edge weights (JC12 eq. 2, plus temporal edges if enabled)."""
        return _to_csgraph(self._W[: self._n, : self._n])

    @property
    def rollout_ids(self) -> IntArray:
        """[n] roll-out id of each node (see :meth:`start_rollout`)."""
        return self._ids[: self._n].copy()

    @property
    def current_rollout(self) -> int:
        """Roll-out id given to the next added node."""
        return self._rollout

    def degrees(self) -> IntArray:
        """[n] number of edges of each node."""
        return np.isfinite(self._W[: self._n, : self._n]).sum(axis=1).astype(np.int64)

    # -- distances to nodes -------------------------------------------------------------
    def _check_dim(self, X: FloatArray) -> None:
        if self._dim is not None and X.shape[1] != self._dim:
            raise ValueError(
                f"points have {X.shape[1]} columns; the graph's nodes have {self._dim}"
            )

    def squared_distances(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        """Wrap-aware squared Euclidean distances ``[N, d] x [M, d] -> [N, M]``."""
        if X.shape[0] == 0 or Y.shape[0] == 0:
            return np.zeros((X.shape[0], Y.shape[0]))
        return wrapped_squared_distances(
            np.ascontiguousarray(X, dtype=np.float64),
            np.ascontiguousarray(Y, dtype=np.float64),
            self.period_or_zeros(X.shape[1]),
        )

    def period_or_zeros(self, d: int) -> FloatArray:
        """[d] wrap-around period, zeros (no wrap) if the graph has none; do not modify it."""
        if self.period is not None:
            return self.period
        if self._zero_period is None or self._zero_period.shape[0] != d:
            self._zero_period = np.zeros(d)
        return self._zero_period

    def weight_of(self, r2: FloatArray) -> FloatArray:
        """Edge weight for squared distances ``r2``: ``r2`` or ``sqrt(r2)``."""
        return r2 if self.edge_weight == "squared" else np.sqrt(r2)

    def squared_distances_to_nodes(self, X: FloatArray) -> FloatArray:
        """[N, n] wrap-aware squared distances from the rows of ``X`` [N, d] to the nodes."""
        self._check_dim(X)
        if self._n == 0:
            return np.zeros((X.shape[0], 0))
        return self.squared_distances(X, self._X[: self._n])

    def nearest(self, X: FloatArray) -> tuple[IntArray, FloatArray]:
        """Nearest node of each row of ``X`` [N, d] -> (index [N], squared distance [N]).

        Ties are broken towards the lowest node index, whatever the batch size
        (the KD-tree path re-resolves near-ties by brute force).
        """
        self._check_dim(X)
        n, N = self._n, X.shape[0]
        if n == 0:
            raise ValueError("the graph has no nodes")
        if N < _KDTREE_MIN_QUERIES or N * n < _KDTREE_MIN_WORK or n < 2:
            r2 = self.squared_distances_to_nodes(X)
            idx = np.argmin(r2, axis=1)
            return idx, r2[np.arange(N), idx]
        tree = self._kdtree()
        dist, idx = tree.query(self._tree_coords(X), k=2)
        idx = idx[:, 0].astype(np.int64)
        tie = dist[:, 1] <= dist[:, 0] * (1.0 + 1e-9) + 1e-300
        if np.any(tie):
            r2t = self.squared_distances_to_nodes(X[tie])
            idx[tie] = np.argmin(r2t, axis=1)
        nodes = self._X[:n]
        diff = wrap_difference(X - nodes[idx], self.period)
        return idx, np.einsum("nd,nd->n", diff, diff)

    def _tree_coords(self, X: FloatArray) -> FloatArray:
        if self.period is None:
            return X
        p = self.period
        return np.where(p > 0, np.mod(X, np.where(p > 0, p, 1.0)), X)

    def _kdtree(self) -> cKDTree:
        if self._tree is None:
            box = None if self.period is None else self.period
            coords = self._tree_coords(self._X[: self._n])
            if box is not None:  # np.mod can round up to the period itself
                coords = np.where((box > 0) & (coords >= box), 0.0, coords)
            self._tree = cKDTree(coords, boxsize=box)
        return self._tree

    # -- mutation -----------------------------------------------------------------------
    def start_rollout(self) -> int:
        """Mark the start of a new roll-out: later nodes are not temporally linked to earlier ones.

        Returns the new roll-out id. Has an effect on edges only with ``temporal_edges=True``.
        """
        self._rollout += 1
        return self._rollout

    def add_node(self, x: ArrayLike) -> int:
        """Append ``x`` [d] as node ``n``, link it (JC12 eq. 2), update ``P``; return its index."""
        xa = as_float_point(x, "x", self._dim)
        if self._dim is None:
            self._dim = int(xa.shape[0])
            self._X = np.zeros((self._cap, self._dim))
            self._view_cache = None
        if self._n == self._cap:
            self._grow()
        n, v = self._n, self._n
        d = xa.shape[0]
        r2, neg = self._r2, self._neg
        squared_distances_row(
            np.ascontiguousarray(xa), self._X, n, self.period_or_zeros(d), r2, neg
        )
        e = np.exp(neg[:n])  # JC12 eq. 2, evaluated literally: exp(-r2) > eps
        prev = -1
        if self.temporal_edges:
            prev = self._temporal_neighbour(v, self._rollout, before=True)
        self._X[v] = xa
        self._ids[v] = self._rollout
        squared = self.edge_weight == "squared"
        rows = add_linked_node(
            self._P, self._W, n, e, self.eps, r2, squared, prev,
            self._d, self._via, self._nbr, self._wn,
        )  # fmt: skip
        self.last_add_rows = int(rows)
        self._n = n + 1
        self._changed()
        return v

    def _temporal_neighbour(self, i: int, rollout: int, *, before: bool) -> int:
        """Closest node index before (or after) ``i`` with roll-out id ``rollout``; -1 if none."""
        ids = self._ids[: self._n]
        if before:
            cand = np.flatnonzero(ids[:i] == rollout)
            return int(cand[-1]) if cand.size else -1
        cand = np.flatnonzero(ids[i + 1 :] == rollout)
        return int(cand[0]) + i + 1 if cand.size else -1

    def remove_node(self, index: int) -> None:
        """Delete node ``index``; later indices shift down by one; ``P`` stays exact (with
        ``lazy_paths``: is recomputed at its next read)."""
        n = self._n
        v = int(index)
        if not 0 <= v < n:
            raise IndexError(f"node index {index} out of range for a graph of {n} nodes")
        bridge: tuple[int, int] | None = None
        if self.temporal_edges:
            p = self._temporal_neighbour(v, int(self._ids[v]), before=True)
            s = self._temporal_neighbour(v, int(self._ids[v]), before=False)
            if p >= 0 and s >= 0:
                bridge = (p - (p > v), s - (s > v))
        if self.lazy_paths:
            self._paths_stale = True
            self.last_delete_sources = 0
        else:
            self.last_delete_sources = int(delete_node_paths(self._P, self._W, n, v, DELETE_RTOL))
        drop_index(self._P, n, v, np.inf)
        drop_index(self._W, n, v, np.inf)
        self._X[v : n - 1] = self._X[v + 1 : n]
        self._ids[v : n - 1] = self._ids[v + 1 : n]
        self._n = m = n - 1
        if bridge is not None:
            a, b = bridge
            wab = float(
                self.weight_of(self.squared_distances(self._X[a : a + 1], self._X[b : b + 1]))[0, 0]
            )
            if wab < self._W[a, b]:
                self._W[a, b] = self._W[b, a] = wab
            if not self._paths_stale:
                insert_edge(self._P, m, a, b, wab)
        self._changed()

    def clear(self) -> None:
        """Remove every node (the roll-out counter is kept)."""
        self._n = 0
        self._W.fill(np.inf)
        self._P.fill(np.inf)
        self._paths_stale = False
        self._changed()

    def _changed(self) -> None:
        self._tree = None
        self._view_cache = None
        self.version += 1

    # -- persistence --------------------------------------------------------------------
    def to_arrays(self) -> dict[str, np.ndarray]:
        """Configuration and full state (nodes, weights, P, roll-out bookkeeping) as arrays."""
        return graph_to_arrays(self)

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> MDPGraph:
        """Inverse of :meth:`to_arrays`; restores the state bit for bit (no replay)."""
        return graph_from_arrays(cls, arrays)

    def __repr__(self) -> str:
        return (
            f"MDPGraph(n_nodes={self._n}, eps={self.eps:g}, edge_weight={self.edge_weight!r}, "
            f"temporal_edges={self.temporal_edges}, period={self.period!r})"
        )


def _read_only(view: FloatArray) -> FloatArray:
    """``view`` (a fresh view of a buffer) marked read-only; the buffer stays writable."""
    view.flags.writeable = False
    return view


def _to_csgraph(W: FloatArray) -> scipy.sparse.csr_array:
    """Dense weights (``inf`` = no edge) -> CSR graph; zero weights stay explicit edges."""
    rows, cols = np.nonzero(np.isfinite(W))
    return scipy.sparse.csr_array((W[rows, cols], (rows, cols)), shape=W.shape)
