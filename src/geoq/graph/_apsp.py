"""Compiled inner loops of the incremental all-pairs shortest paths (numba).

All functions work in place on the top-left ``[n, n]`` block of a preallocated
``[cap, cap]`` distance buffer ``P`` (``inf`` = unreachable). They are pure
loops over float64 arrays; the bookkeeping lives in :mod:`geoq.graph.mdp_graph`.
"""

from __future__ import annotations

import numba
import numpy as np

from geoq._typing import FloatArray, IntArray

__all__ = [
    "affected_sources",
    "delete_node_paths",
    "distances_via_neighbours",
    "drop_index",
    "insert_edge",
    "relax_through_node",
    "wrapped_squared_distances",
]

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
                # Row b may be skipped: d[a] + d[b] can undercut an equal-length path
                # P[a, b] by an ulp (other summation order), so keep P exactly symmetric.
                P[b, a] = s
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


@numba.njit(cache=True, nogil=True)
def _heap_push(keys: FloatArray, vals: IntArray, size: int, key: float, val: int) -> int:
    """Push ``(key, val)`` on the binary min-heap ``keys[:size]``; returns the new size."""
    i = size
    keys[i] = key
    vals[i] = val
    while i > 0:
        parent = (i - 1) >> 1
        if keys[parent] <= keys[i]:
            break
        keys[i], keys[parent] = keys[parent], keys[i]
        vals[i], vals[parent] = vals[parent], vals[i]
        i = parent
    return size + 1


@numba.njit(cache=True, nogil=True)
def _heap_pop(keys: FloatArray, vals: IntArray, size: int) -> int:
    """Remove the root of the min-heap ``keys[:size]`` (read it first); returns the new size."""
    size -= 1
    keys[0] = keys[size]
    vals[0] = vals[size]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            break
        child = left
        if left + 1 < size and keys[left + 1] < keys[left]:
            child = left + 1
        if keys[i] <= keys[child]:
            break
        keys[i], keys[child] = keys[child], keys[i]
        vals[i], vals[child] = vals[child], vals[i]
        i = child
    return size


@numba.njit(cache=True, nogil=True)
def delete_node_paths(P: FloatArray, W: FloatArray, n: int, v: int, rtol: float) -> int:
    """Update ``P`` [n, n] in place for the deletion of node ``v``; returns the sources updated.

    Row and column ``v`` are left as they are (the caller drops them). For each
    source ``a`` only the targets ``T_a = {b : P[a, v] + P[v, b] <= P[a, b] (1 + rtol)}``
    can change (every other target keeps a shortest path that avoids ``v``). They
    are recomputed by a Dijkstra restricted to ``T_a``, seeded from the unchanged
    distances: ``d(b) = min_{u ~ b, u not in T_a} P[a, u] + w(u, b)``. The work is
    the betweenness of ``v`` times the degree instead of a full Dijkstra per
    affected source. ``b in T_a`` iff ``a in T_b`` (``P`` is exactly symmetric and
    the test sums the same two numbers), so both entries of a pair are recomputed
    and the smaller one is written to both: ``P`` stays exactly symmetric.
    ``W`` [n, n] holds the edge weights (``inf`` = no edge).
    """
    # CSR adjacency of the graph without v
    indptr = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        c = 0
        if i != v:
            row = W[i]
            for j in range(n):
                if j != v and row[j] < np.inf:
                    c += 1
        indptr[i + 1] = indptr[i] + c
    nnz = indptr[n]
    indices = np.empty(nnz, dtype=np.int64)
    data = np.empty(nnz)
    for i in range(n):
        if i == v:
            continue
        row = W[i]
        e = indptr[i]
        for j in range(n):
            if j != v and row[j] < np.inf:
                indices[e] = j
                data[e] = row[j]
                e += 1
    in_t = np.zeros(n, dtype=np.bool_)
    done = np.zeros(n, dtype=np.bool_)
    members = np.empty(n, dtype=np.int64)
    d = np.empty(n)
    hkeys = np.empty(nnz + n + 1)
    hvals = np.empty(nnz + n + 1, dtype=np.int64)
    pv = P[v].copy()
    updated = 0
    for a in range(n):
        pav = pv[a]
        if a == v or pav == np.inf:
            continue
        row = P[a]
        m = 0
        for b in range(n):
            pvb = pv[b]
            if b == v or b == a or pvb == np.inf:
                continue
            if pav + pvb <= row[b] * (1.0 + rtol):
                in_t[b] = True
                members[m] = b
                m += 1
        if m == 0:
            continue
        updated += 1
        size = 0
        for k in range(m):  # seeds: last edge from outside T_a (distances there are final)
            b = members[k]
            best = np.inf
            for e in range(indptr[b], indptr[b + 1]):
                u = indices[e]
                if not in_t[u]:
                    c = row[u] + data[e]
                    if c < best:
                        best = c
            d[b] = best
            if best < np.inf:
                size = _heap_push(hkeys, hvals, size, best, b)
        while size > 0:
            key = hkeys[0]
            b = hvals[0]
            size = _heap_pop(hkeys, hvals, size)
            if done[b] or key > d[b]:
                continue
            done[b] = True
            for e in range(indptr[b], indptr[b + 1]):
                c = indices[e]
                if in_t[c] and not done[c]:
                    nd = key + data[e]
                    if nd < d[c]:
                        d[c] = nd
                        size = _heap_push(hkeys, hvals, size, nd, c)
        for k in range(m):
            b = members[k]
            db = d[b]
            if b < a:  # row b was recomputed already and holds its new P[b, a]
                if P[b, a] < db:
                    db = P[b, a]
                P[b, a] = db
            row[b] = db
            in_t[b] = False
            done[b] = False
    return updated


@numba.njit(cache=True, nogil=True)
def drop_index(M: FloatArray, n: int, v: int, fill: float) -> None:
    """Drop row and column ``v`` of ``M[:n, :n]`` in place; the freed last row/column = ``fill``."""
    for i in range(n - 1):
        row = M[i]
        if i < v:
            for j in range(v, n - 1):
                row[j] = row[j + 1]
        else:
            src = M[i + 1]
            for j in range(v):
                row[j] = src[j]
            for j in range(v, n - 1):
                row[j] = src[j + 1]
        row[n - 1] = fill
    last = M[n - 1]
    for j in range(n):
        last[j] = fill


@numba.njit(cache=True, nogil=True)
def wrapped_squared_distances(X: FloatArray, Y: FloatArray, period: FloatArray) -> FloatArray:
    """``[N, d] x [M, d] -> [N, M]`` squared distances; dimension ``k`` wraps if ``period[k] > 0``.

    The wrapped difference is ``diff - p * round(diff / p)`` (round half to even),
    the convention of :class:`geoq.kernels.stationary.Euclidean`.
    """
    N, M, d = X.shape[0], Y.shape[0], X.shape[1]
    out = np.empty((N, M))
    for i in range(N):
        for j in range(M):
            s = 0.0
            for k in range(d):
                diff = X[i, k] - Y[j, k]
                p = period[k]
                if p > 0.0:
                    diff = diff - p * np.rint(diff / p)
                s += diff * diff
            out[i, j] = s
    return out
