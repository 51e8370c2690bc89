"""The geodesic kernel's distance ``SP(x, x')`` on the MDP-induced graph (JC12 eqs. 4, 5).

:class:`GraphDistance` gives ``r^2 = SP^2 / sigma_sp``, so that
``GaussianOfDistance(GraphDistance(...))`` is JC12 eq. 3 (the kernel shell is
:class:`geoq.kernels.geodesic.GeodesicKernel`). :class:`BasisGraphDistance` is
the part shared with the resistance distance of :mod:`geoq.kernels.graph_pd`: a
distance on an :class:`~geoq.graph.MDPGraph` whose nodes follow the GP's basis set.

Definitions (``P`` = the graph's all-pairs shortest paths, ``w(.)`` = the
graph's edge-weight function: ``||.||^2`` by default, ``||.||`` with
``edge_weight="euclidean"``; distances are wrap-aware if ``period`` is set):

* **Between nodes** ``SP(x_i, x_j) = P_ij``. A point that coincides exactly
  with a node (zero wrap-aware distance) *is* that node (lowest index if
  several nodes coincide); the GP's basis vectors are the nodes, by identity.
* ``method="nearest"`` (JC12 eq. 4): ``SP(x*, x_j) = w(x* - x_i) + P_ij``, ``x_i``
  the nearest node. Two points that are not nodes are pendant leaves hung on
  their nearest nodes: ``SP(x, y) = w(x - a(x)) + P[a(x), a(y)] + w(y - a(y))``,
  i.e. the shortest path in the graph augmented with both points — a metric.
* ``method="interpolated"`` (JC12 eq. 5): ``SP(x*, x_j) = sum_i k_SE(x*, x_i) P_ij``,
  ``k_SE(x, x') = exp(-||x - x'||^2 / (2 sigma_se))``; node weights are the unit
  vector ``e_i``. For two non-node points the bilinear extension
  ``SP(x, y) = k_x^T P k_y`` is used: symmetric, JC12 eq. 5 when either side is a
  node, ``P`` on nodes. ``normalize=True`` uses weights that sum to one,
  computed as a softmax of ``-||x - x_i||^2 / (2 sigma_se)``: they never all
  underflow, and far from every node they concentrate on the nearest node(s)
  (the limit of the normalised weights), i.e. ``SP(x*, x_j) -> P[a(x*), j]``.
  Unnormalised weights vanish far from the nodes, so there ``SP -> 0`` and
  ``k -> amplitude``: that is JC12 eq. 5 as published.
* **JC12 eq. 5 stalls the sparse GP** (measured, ``tests/integration/test_geodesic_gp.py``):
  with one node, ``P = [[0]]`` so ``SP(x*, x_0) = 0`` and ``k(x*, x_0) = A`` for
  *every* ``x*``; the novelty of every later point is exactly 0 and the BV set
  never grows past its first point. ``attach=True`` (beyond the paper, off by
  default) averages JC12 eq. 4's path *through each node* instead:
  ``SP(x*, x_j) = sum_i k_SE(x*, x_i) (w(x* - x_i) + P_ij)``, i.e. JC12 eq. 5 with
  the attaching edge of JC12 eq. 4 kept; with ``normalize=True`` it is a soft
  nearest-node version of JC12 eq. 4 (equal to JC12 eq. 4 in the limit
  ``sigma_se -> 0``). Between two non-node points it is
  ``sum_{l,m} k_x,l k_y,m (w(x - x_l) + P_lm + w(y - x_m))``.
* **Identical points** have ``SP = 0``, so ``k(x, x) = amplitude`` for every
  ``x`` (JC12 eq. 3 at distance 0). For distinct non-node points the extensions
  above are used even when the points are very close: the kernel has a
  nugget-like jump at the diagonal off the nodes.
* **Disconnected components.** ``P_ij = inf`` gives ``k = 0`` exactly. In
  JC12 eq. 5 a node with zero weight contributes nothing (``0 * inf := 0``, so
  underflowed weights never give NaN), and weights below
  ``NEGLIGIBLE_WEIGHT = 1e-12`` times the largest weight of their row are set
  to zero first (they cannot change a finite sum in float64). A node with a
  non-negligible weight and no path to ``x_j`` makes ``SP(x*, x_j) = inf``
  (the formula read literally), hence ``k = 0``. With no nodes at all,
  distinct points are unreachable (``k = 0``).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from geoq._typing import FloatArray
from geoq._validation import check_positive
from geoq.graph.mdp_graph import MDPGraph
from geoq.kernels._geodesic_row import (
    interpolated_row_exponent,
    interpolated_row_prepare,
    interpolated_row_weights,
    nearest_row_exponent,
    row_dots,
    row_sums,
    rows_equal,
    squares_over,
)
from geoq.kernels._graph_paths import (
    empty_graph_distances,
    pendant_distances,
    split_unreachable,
    weighted_paths_split,
    zero_identical,
)
from geoq.kernels.base import Distance

__all__ = ["NEGLIGIBLE_WEIGHT", "BasisGraphDistance", "GraphDistance", "Method"]

Method = Literal["nearest", "interpolated"]

#: JC12 eq. 5 weights below this fraction of the largest weight of their row are
#: dropped (set to 0). They cannot change a finite sum at float64 precision, and
#: with ``0 * inf := 0`` they no longer make ``SP`` infinite on their own.
NEGLIGIBLE_WEIGHT = 1e-12
_NEGLIGIBLE_LOG = float(-np.log(NEGLIGIBLE_WEIGHT))


class BasisGraphDistance(Distance):
    """A distance defined on an :class:`~geoq.graph.MDPGraph` that follows the GP's basis set.

    Holds the graph, forwards the GP's ``basis_*`` hooks to it, recognises the
    GP's basis set as the node set (node identity), and saves the full graph
    state. Subclasses define :meth:`node_r2` (``r^2`` between nodes),
    :meth:`to_nodes_r2` (``r^2`` from arbitrary points to the nodes) and
    :meth:`squared` (between arbitrary points).
    """

    tracks_basis = True

    def __init__(self, graph: MDPGraph) -> None:
        self.graph = graph
        self.input_dim = graph.dim

    def node_r2(self) -> FloatArray:
        """[n, n] ``r^2`` between the nodes."""
        raise NotImplementedError

    def to_nodes_r2(self, X: FloatArray) -> FloatArray:
        """[N, n] ``r^2`` from the rows of ``X`` to the nodes."""
        raise NotImplementedError

    def _is_node_set(self, basis: FloatArray) -> bool:
        g = self.graph
        n = g.n_nodes
        if basis.shape[0] != n:
            return False
        if n == 0:
            return True
        nodes = g.nodes_view
        if basis.shape != nodes.shape:
            return False
        if basis.dtype == np.float64 and basis.ndim == 2:
            return bool(rows_equal(basis, nodes, n))  # np.array_equal without its overhead
        return bool(np.array_equal(basis, nodes))

    def follows_basis(self, basis: FloatArray) -> bool:
        return self._is_node_set(basis)

    def squared_to_basis(self, X: FloatArray, basis: FloatArray) -> FloatArray:
        """``r^2(X, BV)`` [N, m]; BV row ``j`` is node ``j`` when BV == graph nodes.

        If ``basis`` is not the graph's node set (out of sync), the general
        definition :meth:`squared` is used instead.
        """
        if not self._is_node_set(basis):
            return self.squared(X, basis)
        if X is basis or (X.shape == basis.shape and np.array_equal(X, basis)):
            return self.node_r2()  # node identity
        return self.to_nodes_r2(X)

    def basis_added(self, x: FloatArray) -> None:
        self.graph.add_node(x)
        self.input_dim = self.graph.dim

    def basis_removed(self, index: int) -> None:
        self.graph.remove_node(index)

    def basis_cleared(self) -> None:
        self.graph.clear()

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {f"graph.{k}": v for k, v in self.graph.to_arrays().items()}

    @staticmethod
    def graph_from_arrays(arrays: dict[str, np.ndarray]) -> MDPGraph:
        """The graph saved under the ``graph.`` prefix by :meth:`to_arrays`."""
        pre = "graph."
        return MDPGraph.from_arrays(
            {k[len(pre) :]: v for k, v in arrays.items() if k.startswith(pre)}
        )


class GraphDistance(BasisGraphDistance):
    """``r^2(x, x') = SP(x, x')^2 / sigma_sp`` on the MDP-induced graph (JC12 eqs. 3-5).

    See the module docstring for the exact definitions on and off the nodes.

    Parameters
    ----------
    graph : the :class:`~geoq.graph.MDPGraph` that follows the GP's basis set.
    method : ``"nearest"`` (JC12 eq. 4) or ``"interpolated"`` (JC12 eq. 5).
    sigma_sp : JC12 eq. 3 width (divides ``SP^2``; not squared).
    sigma_se : JC12 eq. 5 width of the interpolation weights (not squared).
    normalize : JC12 eq. 5 weights sum to one (off by default, as in the paper).
    attach : JC12 eq. 5 averages ``w(x* - x_i) + P_ij`` instead of ``P_ij`` (module doc).
    """

    def __init__(
        self,
        graph: MDPGraph,
        method: Method = "nearest",
        sigma_sp: float = 1.0,
        sigma_se: float = 0.01,
        normalize: bool = False,
        attach: bool = False,
    ) -> None:
        if method not in ("nearest", "interpolated"):
            raise ValueError(
                f"method must be 'nearest' (JC12 eq. 4) or 'interpolated' (JC12 eq. 5), "
                f"got {method!r}"
            )
        super().__init__(graph)
        self.method: Method = method
        self.sigma_sp = check_positive(sigma_sp, "sigma_sp")
        self.sigma_se = check_positive(sigma_se, "sigma_se")
        self.normalize = bool(normalize)
        self.attach = bool(attach)
        self._split_cache: tuple[int, FloatArray, FloatArray, bool] | None = None
        #: Scratch rows of :meth:`row_exponent`: r2, log_rel, exp argument, exponent.
        self._row_scratch = np.empty((4, 0))

    @property
    def _P(self) -> FloatArray:
        return self.graph.shortest_paths_view

    def _split(self) -> tuple[FloatArray, FloatArray, bool]:
        """``split_unreachable(P)`` and whether any pair is unreachable, cached until the
        graph changes (JC12 eq. 5 is O(n^2) otherwise)."""
        cache = self._split_cache
        if cache is None or cache[0] != self.graph.version:
            P = self._P
            if np.isinf(P).any():
                Pf, Ui = split_unreachable(P)
                cache = (self.graph.version, Pf, Ui, True)
            else:  # connected: P itself, and no indicator is needed
                cache = (self.graph.version, P.copy(), np.zeros((0, 0)), False)
            self._split_cache = cache
        return cache[1], cache[2], cache[3]

    # -- shortest paths -------------------------------------------------------------------
    def interpolation_weights(self, X: FloatArray) -> FloatArray:
        """[N, n] JC12 eq. 5 weights ``k_SE(x*, x_i)``; rows of points on node ``i`` are ``e_i``."""
        return self._weights_and_costs(X)[0]

    def _weights_and_costs(self, X: FloatArray) -> tuple[FloatArray, FloatArray]:
        """JC12 eq. 5 weights [N, n] and, with ``attach``, ``sum_i weight_i w(x - x_i)`` [N]."""
        r2 = self.graph.squared_distances_to_nodes(X)
        N, n = r2.shape
        if n == 0:
            return r2, np.zeros(N)
        if N == 1:  # the GP's per-point path: same operations, less overhead
            i = int(r2[0].argmin())
            if r2[0, i] == 0.0:  # on node i: e_i
                W = np.zeros((1, n))
                W[0, i] = 1.0
            else:
                W = self._weights_off_nodes(r2, i)
        else:
            W = self._weights_off_nodes(r2, -1)
            on_node = np.flatnonzero(r2.min(axis=1) == 0.0)
            if on_node.size:
                W[on_node] = 0.0
                W[on_node, np.argmin(r2[on_node], axis=1)] = 1.0
        cost = row_dots(W, self.graph.weight_of(r2)) if self.attach else np.zeros(r2.shape[0])
        return W, cost

    def _weights_off_nodes(self, r2: FloatArray, argmin: int) -> FloatArray:
        """JC12 eq. 5 weights [N, n] from ``r2`` [N, n], ignoring points on nodes.

        ``argmin >= 0``: ``N = 1`` and ``r2[0, argmin]`` is the row's minimum. Then so
        is ``z[0, argmin]`` (division by a positive constant is monotone after
        rounding), which spares a reduction.
        """
        with np.errstate(over="ignore", invalid="ignore"):  # far points: handled below
            z = r2 / (2.0 * self.sigma_se)
            zmin = z.min(axis=1, keepdims=True) if argmin < 0 else z[:, argmin : argmin + 1]
            # log(weight / largest weight of the row); zmin - z == -(z - zmin) exactly
            log_rel = zmin - z
        far = ~np.isfinite(zmin[:, 0])
        if np.any(far):
            # Far from every node, z overflows (tiny sigma_se or huge r2) and inf - inf is
            # NaN: take the difference before the division, (r2min - r2) / (2 sigma_se) <= 0,
            # 0 at the nearest node (the limit of the softmax). The unnormalised weights
            # exp(-z) underflow to 0 there, as they should.
            r2f = r2[far]
            with np.errstate(over="ignore"):
                log_rel[far] = (r2f.min(axis=1, keepdims=True) - r2f) / (2.0 * self.sigma_se)
        W = np.exp(log_rel) if self.normalize else np.exp(-z)
        W[log_rel < -_NEGLIGIBLE_LOG] = 0.0  # negligible next to the row's largest weight
        if self.normalize:
            W /= row_sums(W)[:, None]
        return W

    def shortest_path_to_nodes(self, X: FloatArray) -> FloatArray:
        """``SP(x*, x_j)`` [N, n] by JC12 eq. 4 or 5 (``P`` rows for points on nodes)."""
        if self.method == "nearest":
            return pendant_distances(self.graph, self._P, X)
        W, cost = self._weights_and_costs(X)
        Pf, Ui, unreachable = self._split()
        return weighted_paths_split(W, Pf, Ui, None, unreachable) + cost[:, None]

    def shortest_path(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        """``SP(x, y)`` [N, M] for arbitrary points (module docstring); symmetric, 0 if x == y."""
        g = self.graph
        if self.method == "nearest":
            return pendant_distances(g, self._P, X, Y)
        if g.n_nodes == 0:
            return empty_graph_distances(g, X, Y)
        Wx, cx = self._weights_and_costs(X)
        Wy, cy = (Wx, cx) if Y is X else self._weights_and_costs(Y)
        Pf, Ui, unreachable = self._split()
        D = weighted_paths_split(Wx, Pf, Ui, Wy, unreachable)
        if self.attach:  # sum_{l,m} wx_l wy_m (cx_l + cy_m) = cx sum(wy) + sum(wx) cy
            D += cx[:, None] * row_sums(Wy)[None, :] + row_sums(Wx)[:, None] * cy[None, :]
        if Y is X:
            D = 0.5 * (D + D.T)
        return zero_identical(g, D, X, Y)

    def row_exponent(self, x: FloatArray, basis: FloatArray, m: int) -> FloatArray | None:
        """``-0.5 r^2(x, BV_j)`` [m] for one point ``x`` [d] (the GP's per-point path).

        ``basis`` is the GP's BV buffer (``[>= m, d]``). The same floating-point
        operations as :meth:`squared_to_basis` on ``x[None, :]``, fused into compiled
        calls around the numpy ``exp`` (JC12 eq. 5 weights) and ``W @ P``; both paths sum
        by :mod:`geoq.kernels._geodesic_row`, so the result is bit-identical. Returns a
        view of scratch space (valid until the next call), or None where the general
        path must be used (fewer than two nodes, basis out of sync, another dimension).
        """
        g = self.graph
        n = g.n_nodes
        d = x.shape[0]
        if n < 2 or n != m or g.dim != d:
            return None
        scr = self._row_scratch
        if scr.shape[1] < n:
            scr = self._row_scratch = np.empty((4, 2 * n))  # grows geometrically
        # Views made here, not stored: a deep copy (the GP's all-or-nothing snapshot)
        # would turn stored views into arrays independent of ``scr``.
        r2, log_rel, arg, out = scr[0], scr[1], scr[2], scr[3]
        period = g.period_or_zeros(d)
        nodes, P = g.nodes_view, g.shortest_paths_view  # [n, d], [n, n]
        if self.method == "nearest":
            squared = g.edge_weight == "squared"
            ok = nearest_row_exponent(
                x, nodes, n, basis, period, squared, P, self.sigma_sp, r2, out
            )
            return out[:m] if ok else None
        a = interpolated_row_prepare(
            x, nodes, n, basis, period, 2.0 * self.sigma_se, self.normalize, r2, log_rel, arg
        )
        if a == -1:
            return None
        squared = g.edge_weight == "squared"
        if a < 0:  # on node -2 - a: e_a
            W = np.zeros((1, n))
            W[0, -2 - a] = 1.0
            wr = g.weight_of(scr[0:1, :n])
            cost = float(row_dots(W, wr)[0]) if self.attach else 0.0
        else:
            W = np.exp(scr[2:3, :n])
            cost = interpolated_row_weights(
                W, log_rel, r2, n, _NEGLIGIBLE_LOG, self.normalize, self.attach, squared
            )
        Pf, _, unreachable = self._split()
        interpolated_row_exponent(W @ Pf, W, P, n, unreachable, cost, self.sigma_sp, out)
        return out[:m]

    # -- Distance interface -----------------------------------------------------------------
    def _to_r2(self, SP: FloatArray) -> FloatArray:
        """JC12 eq. 3's ``r^2`` [N, M] of shortest paths ``SP`` [N, M]
        (:func:`~geoq.kernels._geodesic_row.geodesic_r2`)."""
        return squares_over(np.asarray(SP, dtype=np.float64), self.sigma_sp)

    def squared(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        return self._to_r2(self.shortest_path(X, Y))

    def node_r2(self) -> FloatArray:
        return self._to_r2(self._P)

    def to_nodes_r2(self, X: FloatArray) -> FloatArray:
        return self._to_r2(self.shortest_path_to_nodes(X))

    # -- persistence --------------------------------------------------------------------------
    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {
            "method": np.asarray(self.method),
            "sigma_sp": np.asarray(self.sigma_sp),
            "sigma_se": np.asarray(self.sigma_se),
            "normalize": np.asarray(self.normalize),
            "attach": np.asarray(self.attach),
        }
        out.update(super().to_arrays())
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> GraphDistance:
        method = str(arrays["method"])
        if method not in ("nearest", "interpolated"):
            raise ValueError(f"saved geodesic kernel has an unknown method {method!r}")
        return cls(
            cls.graph_from_arrays(arrays),
            method=method,  # type: ignore[arg-type]
            sigma_sp=float(arrays["sigma_sp"]),
            sigma_se=float(arrays["sigma_se"]),
            normalize=bool(arrays["normalize"]),
            attach=bool(arrays.get("attach", False)),
        )

    def __repr__(self) -> str:
        return (
            f"GraphDistance(method={self.method!r}, sigma_sp={self.sigma_sp:g}, "
            f"sigma_se={self.sigma_se:g}, normalize={self.normalize}, attach={self.attach}, "
            f"graph={self.graph!r})"
        )
