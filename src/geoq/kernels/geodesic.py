"""The geodesic (shortest-path) kernel of the paper, JC12 eqs. (3)-(5).

``k_sp(x, x') = amplitude * exp(-SP(x, x')^2 / (2 sigma_sp))`` (JC12 eq. 3; note
``sigma_sp`` is *not* squared, the paper's convention), built as tinygp-style
``GaussianOfDistance(GraphDistance(...))`` with ``r^2 = SP^2 / sigma_sp``.

The distance ``SP`` (between nodes, JC12 eq. 4 ``method="nearest"``, JC12 eq. 5
``method="interpolated"``, the ``attach`` and ``normalize`` options, identical
points, disconnected components) is defined in :mod:`geoq.kernels.graph_distance`.
``SP`` is not a Euclidean distance, so ``k_sp`` is in general *not* positive
definite (Feragen et al., CVPR 2015); see :mod:`geoq.kernels.graph_pd` for a
positive-definite kernel on the same graph.

Usage with the sparse online GP: the GP calls ``basis_added``/``basis_removed``/
``basis_cleared`` and the graph follows its basis set. For temporal edges call
:meth:`GeodesicKernel.start_rollout` before streaming each roll-out.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import as_float_matrix
from geoq.graph.mdp_graph import EdgeWeight, MDPGraph
from geoq.kernels._graph_paths import pendant_distances, split_unreachable, weighted_paths
from geoq.kernels.base import GaussianOfDistance, Kernel, RowExponent
from geoq.kernels.graph_distance import (
    NEGLIGIBLE_WEIGHT,
    BasisGraphDistance,
    GraphDistance,
    Method,
)

# The distances and their path arithmetic live in geoq.kernels.graph_distance and
# geoq.kernels._graph_paths; they stay importable from here.
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
        (off = the paper; needed for the sparse GP to grow, see
        :mod:`geoq.kernels.graph_distance`).
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
        """``SP(x*, x_j)`` [N, n_bv] by JC12 eq. 4 or 5 (rows of ``P`` for points on nodes)."""
        Xa = as_float_matrix(X, "X", self.graph.dim)
        return self.graph_distance.shortest_path_to_nodes(Xa)

    def shortest_path(self, X: ArrayLike, Y: ArrayLike | None = None) -> FloatArray:
        """``SP(x, y)`` [N, M] between arbitrary points (see :mod:`geoq.kernels.graph_distance`)."""
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
