"""The geodesic (shortest-path) kernel of the paper, JC12 eqs. (3)-(5).

``k_sp(x, x') = amplitude * exp(-SP(x, x')^2 / (2 sigma_sp))`` (JC12 eq. 3; note
``sigma_sp`` is *not* squared, the paper's convention), built as tinygp-style
``GaussianOfDistance(GraphDistance(...))`` with ``r^2 = SP^2 / sigma_sp``.

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
* **Eq. 5 stalls the sparse GP** (measured, ``tests/integration/test_geodesic_gp.py``):
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

``SP`` is not a Euclidean distance, so ``k_sp`` is in general *not* positive
definite (Feragen et al., CVPR 2015); see :mod:`geoq.kernels.graph_pd` for a
positive-definite kernel on the same graph.

Usage with the sparse online GP: the GP calls ``basis_added``/``basis_removed``/
``basis_cleared`` and the graph follows its basis set. For temporal edges call
:meth:`GeodesicKernel.start_rollout` before streaming each roll-out.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import numpy as np

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import as_float_matrix, check_positive
from geoq.graph.mdp_graph import EdgeWeight, MDPGraph
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
from geoq.kernels.base import Distance, GaussianOfDistance, Kernel, RowExponent

__all__ = [
    "NEGLIGIBLE_WEIGHT",
    "BasisGraphDistance",
    "GeodesicKernel",
    "GraphDistance",
    "GraphKernel",
    "Method",
    "pendant_distances",
    "split_unreachable",
    "weighted_paths",
]

Method = Literal["nearest", "interpolated"]

#: Eq. 5 weights below this fraction of the largest weight of their row are
#: dropped (set to 0). They cannot change a finite sum at float64 precision, and
#: with ``0 * inf := 0`` they no longer make ``SP`` infinite on their own.
NEGLIGIBLE_WEIGHT = 1e-12
_NEGLIGIBLE_LOG = float(-np.log(NEGLIGIBLE_WEIGHT))


def split_unreachable(P: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(P with inf -> 0, indicator of inf as 0/1 floats)``, both [n, n]."""
    unreachable = np.isinf(P)
    return np.where(unreachable, 0.0, P), unreachable.astype(np.float64)


def weighted_paths(
    A: FloatArray,
    P: FloatArray,
    B: FloatArray | None = None,
    split: tuple[FloatArray, FloatArray] | None = None,
) -> FloatArray:
    """``A P`` [N, n] (or ``A P B^T`` [N, M]) with the convention ``0 * inf = 0``.

    Entries of ``P`` may be ``inf``; a product term counts only where its
    weights are positive, and any such term with ``P = inf`` makes the result
    ``inf``. ``A`` [N, n] and ``B`` [M, n] hold non-negative weights. ``split``
    is ``split_unreachable(P)`` if the caller has it cached.
    """
    Pf, Ui = split_unreachable(P) if split is None else split
    return _weighted_paths(A, Pf, Ui, B, True)


def _weighted_paths(
    A: FloatArray, Pf: FloatArray, Ui: FloatArray, B: FloatArray | None, unreachable: bool
) -> FloatArray:
    """:func:`weighted_paths` on a split ``P``; ``unreachable=False`` promises ``Ui == 0``."""
    if B is None:
        out = A @ Pf
        if unreachable:
            hits = (A > 0).astype(np.float64) @ Ui
            out[hits > 0] = np.inf
    else:
        out = (A @ Pf) @ B.T
        if unreachable:
            hits = ((A > 0).astype(np.float64) @ Ui) @ (B > 0).astype(np.float64).T
            out[hits > 0] = np.inf
    return out


def pendant_distances(
    graph: MDPGraph, M: FloatArray, X: FloatArray, Y: FloatArray | None = None
) -> FloatArray:
    """Graph distances with off-node points as pendant leaves on their nearest nodes.

    ``D(x, x_j) = w(x - a(x)) + M[a(x), j]`` ([N, n] when ``Y`` is None), and
    ``D(x, y) = w(x - a(x)) + M[a(x), a(y)] + w(y - a(y))`` [N, M] with ``D = 0``
    for identical points. ``M`` [n, n] is a node-to-node distance (shortest
    paths for JC12 eq. 4, effective resistances for the PD kernel); ``w`` is the
    graph's edge weight of the attaching edge (0 for points on a node).
    """
    n = graph.n_nodes
    if n == 0:
        return _empty_graph_distances(graph, X, Y)
    if Y is None and X.shape[0] == 1:  # the GP's per-point path: same sums, less overhead
        r2 = graph.squared_distances_to_nodes(X)[0]
        i = int(r2.argmin())  # graph.nearest's choice (lowest index among ties)
        return graph.weight_of(r2[i : i + 1])[:, None] + M[i : i + 1, :]
    ax, r2x = graph.nearest(X)
    cx = graph.weight_of(r2x)
    if Y is None:
        return cx[:, None] + M[ax, :]
    ay, r2y = graph.nearest(Y)
    cy = graph.weight_of(r2y)
    D = (cx[:, None] + cy[None, :]) + M[np.ix_(ax, ay)]  # this order is exactly symmetric
    return _zero_identical(graph, D, X, Y)


def _empty_graph_distances(graph: MDPGraph, X: FloatArray, Y: FloatArray | None) -> FloatArray:
    if Y is None:
        return np.zeros((X.shape[0], 0))
    return _zero_identical(graph, np.full((X.shape[0], Y.shape[0]), np.inf), X, Y)


def _zero_identical(graph: MDPGraph, D: FloatArray, X: FloatArray, Y: FloatArray) -> FloatArray:
    """Set ``D = 0`` where a row of ``X`` and a row of ``Y`` are the same point."""
    if X is Y:
        np.fill_diagonal(D, 0.0)
    D[graph.squared_distances(X, Y) == 0.0] = 0.0
    return D


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
        nodes = g._X[:n]
        if basis.shape != nodes.shape:
            return False
        if basis.dtype == np.float64 and basis.ndim == 2:
            return bool(rows_equal(basis, g._X, n))  # np.array_equal without its overhead
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
                f"method must be 'nearest' (JC12 eq. 4) or 'interpolated' (eq. 5), got {method!r}"
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
        n = self.graph.n_nodes
        return self.graph._P[:n, :n]

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
        """Eq. 5 weights [N, n] and, with ``attach``, ``sum_i weight_i w(x - x_i)`` [N]."""
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
        """Eq. 5 weights [N, n] from ``r2`` [N, n], ignoring points on nodes.

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
        """``SP(x*, x_j)`` [N, n] by JC12 eq. 4 or eq. 5 (``P`` rows for points on nodes)."""
        if self.method == "nearest":
            return pendant_distances(self.graph, self._P, X)
        W, cost = self._weights_and_costs(X)
        Pf, Ui, unreachable = self._split()
        return _weighted_paths(W, Pf, Ui, None, unreachable) + cost[:, None]

    def shortest_path(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        """``SP(x, y)`` [N, M] for arbitrary points (module docstring); symmetric, 0 if x == y."""
        g = self.graph
        if self.method == "nearest":
            return pendant_distances(g, self._P, X, Y)
        if g.n_nodes == 0:
            return _empty_graph_distances(g, X, Y)
        Wx, cx = self._weights_and_costs(X)
        Wy, cy = (Wx, cx) if Y is X else self._weights_and_costs(Y)
        Pf, Ui, unreachable = self._split()
        D = _weighted_paths(Wx, Pf, Ui, Wy, unreachable)
        if self.attach:  # sum_{l,m} wx_l wy_m (cx_l + cy_m) = cx sum(wy) + sum(wx) cy
            D += cx[:, None] * row_sums(Wy)[None, :] + row_sums(Wx)[:, None] * cy[None, :]
        if Y is X:
            D = 0.5 * (D + D.T)
        return _zero_identical(g, D, X, Y)

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
        n = g._n
        d = x.shape[0]
        if n < 2 or n != m or g._dim != d:
            return None
        scr = self._row_scratch
        if scr.shape[1] < n:
            scr = self._row_scratch = np.empty((4, g._cap))
        # Views made here, not stored: a deep copy (the GP's all-or-nothing snapshot)
        # would turn stored views into arrays independent of ``scr``.
        r2, log_rel, arg, out = scr[0], scr[1], scr[2], scr[3]
        period = g.period if g.period is not None else g._period_or_zeros(d)
        if self.method == "nearest":
            squared = g.edge_weight == "squared"
            ok = nearest_row_exponent(
                x, g._X, n, basis, period, squared, g._P, self.sigma_sp, r2, out
            )
            return out[:m] if ok else None
        a = interpolated_row_prepare(
            x, g._X, n, basis, period, 2.0 * self.sigma_se, self.normalize, r2, log_rel, arg
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
        interpolated_row_exponent(W @ Pf, W, g._P, n, unreachable, cost, self.sigma_sp, out)
        return out[:m]

    # -- Distance interface -----------------------------------------------------------------
    def _to_r2(self, SP: FloatArray) -> FloatArray:
        if SP.ndim == 2 and SP.dtype == np.float64:
            return squares_over(SP, self.sigma_sp)  # same bits, no errstate overhead
        with np.errstate(over="ignore"):
            return SP * SP / self.sigma_sp

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


class GraphKernel(GaussianOfDistance):
    """``variance * exp(-r^2 / 2)`` of a :class:`BasisGraphDistance`: the shared shell of
    the graph kernels (graph access, roll-out marks, persistence without hook replay)."""

    @property
    def basis_distance(self) -> BasisGraphDistance:
        assert isinstance(self.distance, BasisGraphDistance)
        return self.distance

    @property
    def graph(self) -> MDPGraph:
        """The MDP-induced graph over the basis vectors (nodes = the GP's BVs, same order)."""
        return self.basis_distance.graph

    @property
    def amplitude(self) -> float:
        """``k(x, x)``."""
        return self.variance

    @property
    def eps(self) -> float:
        return self.graph.eps

    def start_rollout(self) -> int:
        """Start a new roll-out (temporal edges link only nodes of the same roll-out).

        With ``temporal_edges=True`` call it before streaming each roll-out, e.g.
        ``for X, y in rollouts: gk.start_rollout(); gp.partial_fit(X, y)``.
        """
        return self.graph.start_rollout()

    def _row_exponent_fn(self) -> Callable[[FloatArray, FloatArray, int], FloatArray | None] | None:
        """``GraphDistance.row_exponent`` if this kernel's ``to_basis`` is exactly
        ``variance * exp(row_exponent)`` and ``k(x, x) = variance``, else None."""
        cls = type(self)
        if (
            cls.to_basis is not GaussianOfDistance.to_basis
            or cls._diag is not GaussianOfDistance._diag
            or type(self.distance) is not GraphDistance
        ):
            return None
        return self.distance.row_exponent

    def fused_row(self) -> tuple[RowExponent, float] | None:
        fn = self._row_exponent_fn()
        return None if fn is None else (fn, self.variance)

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> Kernel:
        base = GaussianOfDistance.from_arrays(arrays)
        assert isinstance(base, GaussianOfDistance)
        out = cls.__new__(cls)
        GaussianOfDistance.__init__(out, base.distance, variance=base.variance)
        return out


class GeodesicKernel(GraphKernel):
    """Shortest-path kernel ``k_sp = amplitude * exp(-SP^2 / (2 sigma_sp))`` (JC12 eqs. 3-5).

    Parameters
    ----------
    eps : JC12 eq. 2 edge threshold in ``[0, 1]``.
    method : ``"nearest"`` (JC12 eq. 4) or ``"interpolated"`` (JC12 eq. 5).
    sigma_sp : JC12 eq. 3 width (paper default 1; divides ``SP^2``, not squared).
    sigma_se : JC12 eq. 5 width of the interpolation weights (small; not squared).
    amplitude : ``A`` of JC12 eq. 3, ``k(x, x) = A``.
    normalize : JC12 eq. 5 weights sum to one (off = the paper).
    attach : JC12 eq. 5 keeps JC12 eq. 4's attaching edge, ``sum_i k_SE (w(x* - x_i) + P_ij)``
        (off = the paper; needed for the sparse GP to grow, see the module doc).
    edge_weight : ``"squared"`` (JC12 eq. 2) or ``"euclidean"``; also the cost of the
        JC12 eq. 4 attaching edge.
    period : optional per-dimension wrap-around period ``[d]`` (0 = ordinary).
    temporal_edges : link successive basis vectors of the same roll-out; call
        :meth:`start_rollout` before each roll-out.
    capacity : initial graph buffer size (grows geometrically).

    ``gk.graph`` is the :class:`~geoq.graph.MDPGraph`; its nodes are the GP's
    basis vectors in the same order. ``tracks_basis`` is True;
    ``positive_definite`` is False (a Gaussian of a graph distance is not PD in
    general: Feragen et al., CVPR 2015).
    """

    positive_definite = False

    def __init__(
        self,
        eps: float = 0.3,
        method: Method = "nearest",
        sigma_sp: float = 1.0,
        sigma_se: float = 0.01,
        amplitude: float = 1.0,
        normalize: bool = False,
        edge_weight: EdgeWeight = "squared",
        period: ArrayLike | None = None,
        temporal_edges: bool = False,
        capacity: int = 64,
        attach: bool = False,
    ) -> None:
        graph = MDPGraph(
            eps,
            edge_weight=edge_weight,
            period=period,
            temporal_edges=temporal_edges,
            capacity=capacity,
        )
        distance = GraphDistance(graph, method, sigma_sp, sigma_se, normalize, attach)
        super().__init__(distance, variance=amplitude)

    @property
    def graph_distance(self) -> GraphDistance:
        assert isinstance(self.distance, GraphDistance)
        return self.distance

    @property
    def method(self) -> Method:
        return self.graph_distance.method

    @property
    def sigma_sp(self) -> float:
        return self.graph_distance.sigma_sp

    @property
    def sigma_se(self) -> float:
        return self.graph_distance.sigma_se

    @property
    def normalize(self) -> bool:
        return self.graph_distance.normalize

    @property
    def attach(self) -> bool:
        return self.graph_distance.attach

    def shortest_path_to_nodes(self, X: ArrayLike) -> FloatArray:
        """``SP(x*, x_j)`` [N, n_bv] by JC12 eq. 4 or eq. 5 (rows of ``P`` for points on nodes)."""
        Xa = as_float_matrix(X, "X", self.graph.dim)
        return self.graph_distance.shortest_path_to_nodes(Xa)

    def shortest_path(self, X: ArrayLike, Y: ArrayLike | None = None) -> FloatArray:
        """``SP(x, y)`` [N, M] between arbitrary points (see the module docstring)."""
        Xa = as_float_matrix(X, "X", self.graph.dim)
        Ya = Xa if Y is None else as_float_matrix(Y, "Y", Xa.shape[1])
        return self.graph_distance.shortest_path(Xa, Ya)

    def __repr__(self) -> str:
        d = self.graph_distance
        return (
            f"GeodesicKernel(eps={self.eps:g}, method={d.method!r}, sigma_sp={d.sigma_sp:g}, "
            f"sigma_se={d.sigma_se:g}, amplitude={self.variance:g}, normalize={d.normalize}, "
            f"attach={d.attach}, "
            f"n_nodes={self.graph.n_nodes})"
        )
