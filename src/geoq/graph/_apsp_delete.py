"""Compiled inner loops of the incremental all-pairs shortest paths (numba): deleting a node.

Like :mod:`geoq.graph._apsp`, in place on the top-left ``[n, n]`` block of a
preallocated ``[cap, cap]`` distance buffer ``P`` (``inf`` = unreachable): the sources
whose shortest paths went through the deleted node are found and only their rows are
recomputed (a Dijkstra restricted to them), then the node's row and column dropped.
"""

from __future__ import annotations

import numba
import numpy as np

from geoq._typing import FloatArray, IntArray

__all__ = ["DELETE_RTOL", "affected_sources", "delete_node_paths", "drop_index"]

#: Relative slack of the "was node v on a shortest path?" test of a deletion. Paths
#: summed in different orders differ by a few ulps; a larger slack only recomputes
#: a few more sources (always safe), a smaller one could miss an affected source.
DELETE_RTOL = 1e-10


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


#: ``delete_node_paths`` solves each source on the dense weights (no adjacency
#: lists, no heap) when the graph has at least this many edge entries per
#: ``n^2`` (measured on the geodesic-GP fit and ``benchmarks/bench_graph.py``).
DENSE_DELETE_FILL = 0.15


@numba.njit(cache=True, nogil=True)
def delete_node_paths(
    P: FloatArray, W: FloatArray, n: int, v: int, rtol: float, dense: int = -1
) -> int:
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

    ``dense``: 1 = the restricted Dijkstra scans the dense rows of ``W`` (O(|T_a| n)
    seeds, O(|T_a|^2) selection, no heap), 0 = adjacency lists and a binary heap,
    -1 = dense when at least ``DENSE_DELETE_FILL`` of ``W`` is edges. Both compute
    ``min`` over the same sums ``d(u) + w(u, b)``: the results are bit-identical.
    """
    pv = P[v, :n].copy()
    in_t = np.zeros(n, dtype=np.bool_)
    members = np.empty(n, dtype=np.int64)
    d = np.empty(n)
    use_dense = dense == 1
    if dense < 0:
        nnz = 0
        for i in range(n):
            row = W[i]
            for j in range(n):
                if row[j] < np.inf:
                    nnz += 1
        use_dense = nnz >= DENSE_DELETE_FILL * n * n
    if use_dense:
        indptr = np.zeros(1, dtype=np.int64)
        indices = np.empty(0, dtype=np.int64)
        data = np.empty(0)
        rowmask = np.empty(n)
    else:
        indptr, indices, data = _csr_without(W, n, v)
        rowmask = np.empty(0)
    nnz_v = indptr[-1]
    done = np.zeros(n, dtype=np.bool_)
    hkeys = np.empty(nnz_v + n + 1)
    hvals = np.empty(nnz_v + n + 1, dtype=np.int64)
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
        if use_dense:
            _restricted_dijkstra_dense(W, n, v, row, in_t, members, m, d, rowmask)
        else:
            _restricted_dijkstra_heap(
                indptr, indices, data, row, in_t, done, members, m, d, hkeys, hvals
            )
        for k in range(m):
            b = members[k]
            db = d[b]
            if b < a:  # row b was recomputed already and holds its new P[b, a]
                if P[b, a] < db:
                    db = P[b, a]
                P[b, a] = db
            row[b] = db
            in_t[b] = False
    return updated


@numba.njit(cache=True, nogil=True)
def _csr_without(W: FloatArray, n: int, v: int) -> tuple[IntArray, IntArray, FloatArray]:
    """CSR adjacency ``(indptr, indices, data)`` of ``W[:n, :n]`` without node ``v``."""
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
    return indptr, indices, data


@numba.njit(cache=True, nogil=True)
def _restricted_dijkstra_heap(
    indptr: IntArray,
    indices: IntArray,
    data: FloatArray,
    row: FloatArray,
    in_t: np.ndarray,
    done: np.ndarray,
    members: IntArray,
    m: int,
    d: FloatArray,
    hkeys: FloatArray,
    hvals: IntArray,
) -> None:
    """``d[members[:m]]`` = distances from the source of ``row`` within ``T`` (adjacency lists)."""
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
        done[members[k]] = False


@numba.njit(cache=True, nogil=True)
def _restricted_dijkstra_dense(
    W: FloatArray,
    n: int,
    v: int,
    row: FloatArray,
    in_t: np.ndarray,
    members: IntArray,
    m: int,
    d: FloatArray,
    rowmask: FloatArray,
) -> None:
    """As :func:`_restricted_dijkstra_heap` on the dense weights; permutes ``members[:m]``.

    ``W[b, u] = inf`` where there is no edge, so scanning every ``u`` adds only
    ``inf`` candidates; ``rowmask`` hides ``T`` and ``v`` (the final distances
    outside ``T`` are the seeds' only sources).
    """
    for u in range(n):
        rowmask[u] = np.inf if in_t[u] else row[u]
    rowmask[v] = np.inf
    key = np.inf
    kbest = -1
    for k in range(m):
        b = members[k]
        d[b] = _min_of_sums(rowmask, W[b], n)
        if d[b] < key:
            key = d[b]
            kbest = k
    left = m  # members[:left] are not final; each pass finalises the smallest
    while kbest >= 0:
        b = members[kbest]
        left -= 1
        members[kbest] = members[left]
        members[left] = b
        Wb = W[b]
        key_next = np.inf
        kbest = -1
        for k in range(left):
            c = members[k]
            nd = key + Wb[c]
            dc = d[c]
            if nd < dc:
                dc = nd
                d[c] = nd
            if dc < key_next:
                key_next = dc
                kbest = k
        key = key_next


@numba.njit(cache=True, nogil=True)
def _min_of_sums(x: FloatArray, y: FloatArray, n: int) -> float:
    """``min_u x[u] + y[u]``; four running minima (the minimum of exact sums is order-free)."""
    b0 = b1 = b2 = b3 = np.inf
    u = 0
    while u + 4 <= n:
        c0 = x[u] + y[u]
        c1 = x[u + 1] + y[u + 1]
        c2 = x[u + 2] + y[u + 2]
        c3 = x[u + 3] + y[u + 3]
        if c0 < b0:
            b0 = c0
        if c1 < b1:
            b1 = c1
        if c2 < b2:
            b2 = c2
        if c3 < b3:
            b3 = c3
        u += 4
    while u < n:
        c0 = x[u] + y[u]
        if c0 < b0:
            b0 = c0
        u += 1
    return min(min(b0, b1), min(b2, b3))


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


# -- adding a node (JC12 eq. 2) ---------------------------------------------------------------
