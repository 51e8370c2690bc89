"""Compiled inner loops of the incremental all-pairs shortest paths (numba).

All functions work in place on the top-left ``[n, n]`` block of a preallocated
``[cap, cap]`` distance buffer ``P`` (``inf`` = unreachable). They are pure
loops over float64 arrays; the bookkeeping lives in :mod:`geoq.graph.mdp_graph`.
"""

from __future__ import annotations

import numba
import numpy as np

from geoq._typing import FloatArray, IntArray

__all__ = ["affected_sources", "distances_via_neighbours", "insert_edge", "relax_through_node"]

#: Relative slack of the "was node v on a shortest path?" test of a deletion. Paths
#: summed in different orders differ by a few ulps; a larger slack only recomputes
#: a few more sources (always safe), a smaller one could miss an affected source.
DELETE_RTOL = 1e-10


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
def affected_sources(P: FloatArray, n: int, v: int, rtol: float) -> np.ndarray:
    """Sources ``a != v`` with a shortest path through ``v`` to some ``b != a, v``.

    ``P[a, v] + P[v, b] <= P[a, b] (1 + rtol)`` -> True. Rows of unaffected sources
    stay exact when ``v`` is deleted; affected ones must be recomputed. [n] bool.
    """
    out = np.zeros(n, dtype=np.bool_)
    pv = P[v]
    for a in range(n):
        if a == v:
            continue
        pav = P[a, v]
        if pav == np.inf:
            continue
        row = P[a]
        for b in range(n):
            if b == v or b == a:
                continue
            if pav + pv[b] <= row[b] * (1.0 + rtol):
                out[a] = True
                break
    return out
