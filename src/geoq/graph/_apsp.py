"""Compiled inner loops of the incremental all-pairs shortest paths (numba): adding a node
and an edge (deleting a node: :mod:`geoq.graph._apsp_delete`).

All functions work in place on the top-left ``[n, n]`` block of a preallocated
``[cap, cap]`` distance buffer ``P`` (``inf`` = unreachable). They are pure
loops over float64 arrays; the bookkeeping lives in :mod:`geoq.graph.mdp_graph`,
the wrap-aware distances in :mod:`geoq._geometry`.
"""

from __future__ import annotations

import numba
import numpy as np

from geoq._typing import FloatArray, IntArray

__all__ = [
    "add_linked_node",
    "add_node_paths",
    "dense_components",
    "dense_reachable",
    "distances_via_neighbours",
    "insert_edge",
    "relax_through_node",
]


@numba.njit(cache=True, nogil=True)
def distances_via_neighbours(
    P: FloatArray, n: int, nbr: IntArray, w: FloatArray, d: FloatArray, via: IntArray
) -> None:
    """Distances from a new node ``v`` to the ``n`` existing nodes.

    ``d[j] = min_k (w[k] + P[nbr[k], j])`` (a shortest path from ``v`` leaves by
    one edge to a neighbour and never comes back), ``via[j]`` = the minimising
    ``k`` (``-1`` if ``j`` is unreachable). ``nbr`` [deg], ``w`` [deg] edge weights.
    """
    for j in range(n):
        d[j] = np.inf
        via[j] = -1
    for k in range(nbr.shape[0]):
        row = P[nbr[k]]
        wk = w[k]
        for j in range(n):
            s = wk + row[j]
            if s < d[j]:
                d[j] = s
                via[j] = k


@numba.njit(cache=True, nogil=True)
def relax_through_node(
    P: FloatArray, n: int, d: FloatArray, via: IntArray, shortcut: np.ndarray
) -> int:
    """``P[a, b] = min(P[a, b], d[a] + d[b])`` for the ``n`` old nodes; returns rows touched.

    ``shortcut[k1, k2]`` [deg, deg] is True when ``w[k1] + w[k2] < P[nbr[k1], nbr[k2]]``.
    A pair (a, b) whose best entry/exit neighbours (``via``) are not a shortcut
    pair cannot improve: ``d[a] + d[b] >= P[a, i] + P[i, k] + P[k, b] >= P[a, b]``,
    so rows whose ``via`` neighbour takes part in no shortcut are skipped.
    """
    deg = shortcut.shape[0]
    useful = np.zeros(deg, dtype=np.bool_)
    for k1 in range(deg):
        for k2 in range(deg):
            if shortcut[k1, k2]:
                useful[k1] = True
    touched = 0
    for a in range(n):
        ka = via[a]
        if ka < 0 or not useful[ka]:
            continue
        touched += 1
        da = d[a]
        row = P[a]
        for b in range(n):
            s = da + d[b]
            if s < row[b]:
                row[b] = s
                # Row b may be skipped: d[a] + d[b] can undercut an equal-length path
                # P[a, b] by an ulp (other summation order), so keep P exactly symmetric.
                P[b, a] = s
    return touched


@numba.njit(cache=True, nogil=True)
def add_node_paths(
    P: FloatArray, W: FloatArray, n: int, nbr: IntArray, w: FloatArray, d: FloatArray, via: IntArray
) -> int:
    """Append node ``v = n`` linked to ``nbr`` [deg] by weights ``w`` [deg]; update ``W`` and ``P``.

    :func:`distances_via_neighbours`, then :func:`relax_through_node` when some
    neighbour pair is a shortcut (``w[k1] + w[k2] < P[nbr[k1], nbr[k2]]``), then
    row and column ``v`` of ``P``. Returns the rows touched by the relaxation.
    """
    v = n
    deg = nbr.shape[0]
    for j in range(n + 1):
        W[v, j] = np.inf
        W[j, v] = np.inf
    for k in range(deg):
        W[v, nbr[k]] = w[k]
        W[nbr[k], v] = w[k]
    distances_via_neighbours(P, n, nbr, w, d, via)
    touched = 0
    if deg >= 2:
        shortcut = np.zeros((deg, deg), dtype=np.bool_)
        anything = False
        for k1 in range(deg):
            row = P[nbr[k1]]
            for k2 in range(deg):
                if w[k1] + w[k2] < row[nbr[k2]]:
                    shortcut[k1, k2] = True
                    anything = True
        if anything:
            touched = relax_through_node(P, n, d, via, shortcut)
    for j in range(n):
        P[v, j] = d[j]
        P[j, v] = d[j]
    P[v, v] = 0.0
    return touched


@numba.njit(cache=True, nogil=True)
def insert_edge(P: FloatArray, n: int, p: int, s: int, w: float) -> None:
    """Add an edge ``p -- s`` of weight ``w`` between existing nodes; update ``P`` exactly.

    ``P[a, b] = min(P[a, b], P[a, p] + w + P[s, b], P[a, s] + w + P[p, b])``.
    """
    if not w < P[p, s]:
        return
    dp = P[p, :n].copy()
    ds = P[s, :n].copy()
    for a in range(n):
        pa = dp[a]
        sa = ds[a]
        if pa == np.inf and sa == np.inf:
            continue
        row = P[a]
        for b in range(n):
            # (x + y) + w with x + y commutative: the (b, a) entry gets the same bits
            c = min((pa + ds[b]) + w, (sa + dp[b]) + w)
            if c < row[b]:
                row[b] = c


@numba.njit(cache=True, nogil=True)
def add_linked_node(
    P: FloatArray,
    W: FloatArray,
    n: int,
    e: FloatArray,
    eps: float,
    r2: FloatArray,
    squared: bool,
    prev: int,
    d: FloatArray,
    via: IntArray,
    nbr: IntArray,
    wn: FloatArray,
) -> int:
    """Append node ``n`` linked to every ``j`` with ``e[j] = exp(-r2[j]) > eps`` (JC12 eq. 2)
    and to ``prev`` (if ``>= 0``), by weights ``r2`` (``squared``) or ``sqrt(r2)``;
    :func:`add_node_paths` on the neighbours in increasing order. ``nbr``, ``wn``
    [>= n] are scratch. Returns the rows touched by the relaxation.
    """
    deg = 0
    for j in range(n):
        if e[j] > eps or j == prev:
            nbr[deg] = j
            wn[deg] = r2[j] if squared else np.sqrt(r2[j])
            deg += 1
    return add_node_paths(P, W, n, nbr[:deg], wn[:deg], d, via)


@numba.njit(cache=True, nogil=True)
def _label_component(W: FloatArray, n: int, start: int, label: IntArray, c: int) -> None:
    """``label[j] = c`` for every unlabelled (``-1``) node ``j`` connected to ``start`` in
    the graph of the finite entries of ``W[:n, :n]`` (breadth-first search, O(n^2))."""
    queue = np.empty(n, dtype=np.int64)
    label[start] = c
    queue[0] = start
    head, tail = 0, 1
    while head < tail:
        i = queue[head]
        head += 1
        row = W[i]
        for j in range(n):
            if label[j] < 0 and np.isfinite(row[j]):
                label[j] = c
                queue[tail] = j
                tail += 1


@numba.njit(cache=True, nogil=True)
def dense_components(W: FloatArray, n: int, label: IntArray) -> int:
    """Connected components of the graph whose edges are the finite entries of ``W[:n, :n]``
    (symmetric): ``label[:n]`` 0, 1, ... in order of each component's first node (scipy's
    ``connected_components`` numbering); returns their number. A breadth-first search over
    the dense rows, O(n^2): for a few hundred nodes a fraction of the sparse conversion
    scipy needs first."""
    label[:n] = -1
    c = 0
    for s in range(n):
        if label[s] < 0:
            _label_component(W, n, s, label, c)
            c += 1
    return c


@numba.njit(cache=True, nogil=True)
def dense_reachable(W: FloatArray, n: int, start: int, out: np.ndarray) -> None:
    """``out[:n]``: whether each node is connected to ``start`` (itself included) in the
    graph of the finite entries of ``W[:n, :n]`` (breadth-first search, O(n^2))."""
    label = np.full(n, -1, dtype=np.int64)
    _label_component(W, n, start, label, 0)
    for i in range(n):
        out[i] = label[i] == 0
