"""Shortest-path arithmetic shared by the graph distances (JC12 eqs. 4 and 5).

``weighted_paths`` is the ``W P`` (or ``W P W'^T``) of JC12 eq. 5 with the
convention ``0 * inf = 0``; ``pendant_distances`` hangs off-node points as leaves
on their nearest nodes (JC12 eq. 4, and the resistance kernel's construction in
:mod:`geoq.kernels.graph_pd`). The distances that use them are in
:mod:`geoq.kernels.graph_distance` and :mod:`geoq.kernels.graph_pd`.
"""

from __future__ import annotations

import numpy as np

from geoq._typing import FloatArray
from geoq.graph.mdp_graph import MDPGraph

__all__ = [
    "empty_graph_distances",
    "pendant_distances",
    "split_unreachable",
    "weighted_paths",
    "weighted_paths_split",
    "zero_identical",
]


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
    return weighted_paths_split(A, Pf, Ui, B, True)


def weighted_paths_split(
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
        return empty_graph_distances(graph, X, Y)
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
    return zero_identical(graph, D, X, Y)


def empty_graph_distances(graph: MDPGraph, X: FloatArray, Y: FloatArray | None) -> FloatArray:
    """Distances on a graph with no nodes: [N, 0] to the nodes, else ``inf`` (0 if identical)."""
    if Y is None:
        return np.zeros((X.shape[0], 0))
    return zero_identical(graph, np.full((X.shape[0], Y.shape[0]), np.inf), X, Y)


def zero_identical(graph: MDPGraph, D: FloatArray, X: FloatArray, Y: FloatArray) -> FloatArray:
    """Set ``D = 0`` where a row of ``X`` and a row of ``Y`` are the same point."""
    if X is Y:
        np.fill_diagonal(D, 0.0)
    D[graph.squared_distances(X, Y) == 0.0] = 0.0
    return D
