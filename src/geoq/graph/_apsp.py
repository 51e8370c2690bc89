"""Compiled inner loops of the incremental all-pairs shortest paths (numba).

All functions work in place on the top-left ``[n, n]`` block of a preallocated
``[cap, cap]`` distance buffer ``P`` (``inf`` = unreachable). They are pure
loops over float64 arrays; the bookkeeping lives in :mod:`geoq.graph.mdp_graph`.
"""

from __future__ import annotations

import functools

import numba
import numpy as np

from geoq._typing import FloatArray, IntArray

__all__ = [
    "add_linked_node",
    "add_node_paths",
    "affected_sources",
    "delete_node_paths",
    "distances_via_neighbours",
    "drop_index",
    "einsum_row_dot",
    "insert_edge",
    "interpolated_row_exponent",
    "interpolated_row_prepare",
    "interpolated_row_weights",
    "nearest_row_exponent",
    "relax_through_node",
    "rows_equal",
    "squared_distances_row",
    "squares_over",
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


@numba.njit(cache=True, nogil=True)
def _wrapped_r2(x: FloatArray, Y: FloatArray, j: int, period: FloatArray) -> float:
    """``|x - Y_j|^2`` [scalar]; dimension ``k`` wraps if ``period[k] > 0``."""
    s = 0.0
    for k in range(x.shape[0]):
        diff = x[k] - Y[j, k]
        p = period[k]
        if p > 0.0:
            diff = diff - p * np.rint(diff / p)
        s += diff * diff
    return s


@numba.njit(cache=True, nogil=True)
def wrapped_squared_distances(X: FloatArray, Y: FloatArray, period: FloatArray) -> FloatArray:
    """``[N, d] x [M, d] -> [N, M]`` squared distances; dimension ``k`` wraps if ``period[k] > 0``.

    The wrapped difference is ``diff - p * round(diff / p)`` (round half to even),
    the convention of :class:`geoq.kernels.stationary.Euclidean`.
    """
    N, M = X.shape[0], Y.shape[0]
    out = np.empty((N, M))
    for i in range(N):
        for j in range(M):
            out[i, j] = _wrapped_r2(X[i], Y, j, period)
    return out


@numba.njit(cache=True, nogil=True)
def squares_over(X: FloatArray, s: float) -> FloatArray:
    """``X * X / s`` [N, M] elementwise, without floating-point warnings (overflow -> inf).

    Bit-identical to numpy's ``X * X / s`` (two correctly rounded operations).
    """
    N, M = X.shape
    out = np.empty((N, M))
    for i in range(N):
        for j in range(M):
            x = X[i, j]
            out[i, j] = x * x / s
    return out


@numba.njit(cache=True, nogil=True)
def rows_equal(A: FloatArray, B: FloatArray, n: int) -> bool:
    """``np.array_equal(A, B[:n])`` for 2-D float arrays (NaN never equals)."""
    if A.shape[0] != n or A.shape[1] != B.shape[1]:
        return False
    for i in range(n):
        for j in range(A.shape[1]):
            if A[i, j] != B[i, j]:
                return False
    return True


# -- the geodesic kernel's per-point row (eqs. 4 and 5) ---------------------------------
# The GP streams one point at a time; these kernels do, in one call each, what the
# numpy expressions of :mod:`geoq.kernels.geodesic` do for a single row, with the same
# floating-point operations in the same order (only IEEE +, -, *, /, sqrt and
# comparisons, which round identically here and in numpy). ``exp``, the eq. 5
# product ``W @ P`` (BLAS) and the attach cost (``einsum``) stay numpy calls in the
# caller, so the bits cannot depend on a different libm or summation order.


@numba.njit(cache=True, nogil=True)
def _row_r2_on_nodes(
    x: FloatArray, X: FloatArray, n: int, BV: FloatArray, period: FloatArray, r2: FloatArray
) -> int:
    """``r2[j]`` = wrapped ``|x - X_j|^2`` (as :func:`wrapped_squared_distances`), ``j < n``.

    Returns the lowest index of the minimum (``np.argmin``), or -1 if the first
    ``n`` rows of ``BV`` are not the nodes ``X[:n]`` (the GP's basis is out of sync).
    """
    if not rows_equal(BV[:n], X, n):
        return -1
    best = 0
    for j in range(n):
        s = _wrapped_r2(x, X, j, period)
        r2[j] = s
        if s < r2[best]:
            best = j
    return best


@numba.njit(cache=True, nogil=True)
def nearest_row_exponent(
    x: FloatArray,
    X: FloatArray,
    n: int,
    BV: FloatArray,
    period: FloatArray,
    squared: bool,
    P: FloatArray,
    sigma_sp: float,
    r2: FloatArray,
    out: FloatArray,
) -> bool:
    """Eq. 4 for one point: ``out[j] = -0.5 SP(x, x_j)^2 / sigma_sp``, ``j < n``.

    ``SP = w(x - x_a) + P[a, j]`` with ``a`` the nearest node (lowest index among
    ties), ``w`` = ``r2`` (``squared``) or ``sqrt(r2)``. False (nothing written) if
    ``BV[:n]`` is not the node set. ``r2`` [>= n] is scratch.
    """
    a = _row_r2_on_nodes(x, X, n, BV, period, r2)
    if a < 0:
        return False
    c = r2[a] if squared else np.sqrt(r2[a])
    row = P[a]
    for j in range(n):
        sp = c + row[j]
        out[j] = -0.5 * (sp * sp / sigma_sp)
    return True


@numba.njit(cache=True, nogil=True)
def interpolated_row_prepare(
    x: FloatArray,
    X: FloatArray,
    n: int,
    BV: FloatArray,
    period: FloatArray,
    two_sigma_se: float,
    normalize: bool,
    r2: FloatArray,
    log_rel: FloatArray,
    arg: FloatArray,
) -> int:
    """Eq. 5 for one point, first stage: ``r2`` [n] and the exponents of the weights.

    Returns the nearest node ``a`` (lowest index among ties) if ``x`` is not on it,
    ``-2 - a`` if it is (``r2[a] == 0``), ``-1`` if ``BV[:n]`` is not the node set.
    Off the nodes, with ``z = r2 / two_sigma_se``: ``log_rel = z[a] - z`` and
    ``arg`` = ``log_rel`` (``normalize``) or ``-z``; the weights are ``exp(arg)``.
    """
    a = _row_r2_on_nodes(x, X, n, BV, period, r2)
    if a < 0:
        return a
    if r2[a] == 0.0:
        return -2 - a
    zmin = r2[a] / two_sigma_se
    for j in range(n):
        z = r2[j] / two_sigma_se
        lr = zmin - z
        log_rel[j] = lr
        arg[j] = lr if normalize else -z
    return a


@numba.njit(cache=True, nogil=True)
def _block_sum(a: FloatArray, lo: int, n: int) -> float:
    """numpy's sum of ``a[lo:lo + n]`` for ``n <= 128``: eight accumulators (sequential below 8)."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    i = lo + 8
    end = lo + n - (n % 8)
    while i < end:
        r0 += a[i]
        r1 += a[i + 1]
        r2 += a[i + 2]
        r3 += a[i + 3]
        r4 += a[i + 4]
        r5 += a[i + 5]
        r6 += a[i + 6]
        r7 += a[i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < lo + n:
        res += a[i]
        i += 1
    return res


@numba.njit(cache=True, nogil=True)
def _pairwise_sum(a: FloatArray, lo: int, n: int) -> float:
    """``a[lo:lo + n].sum()`` exactly as numpy sums a contiguous float64 row.

    numpy's pairwise summation: blocks of at most 128 by :func:`_block_sum`, larger
    ranges split at ``n2 = n // 2`` rounded down to a multiple of 8 and the halves
    added. The recursion is unrolled onto an explicit stack (a self-recursive
    function loaded from numba's cache was seen to crash).
    """
    if n <= 128:
        return _block_sum(a, lo, n)
    los = np.empty(64, dtype=np.int64)
    ns = np.empty(64, dtype=np.int64)
    stage = np.empty(64, dtype=np.int64)  # 0 = new, 1 = left half pending, 2 = right pending
    left = np.empty(64)
    depth = 0
    los[0] = lo
    ns[0] = n
    stage[0] = 0
    while True:
        c = ns[depth]
        if c > 128:  # split: descend into the left half
            h = c // 2
            h -= h % 8
            stage[depth] = 1
            los[depth + 1] = los[depth]
            ns[depth + 1] = h
            stage[depth + 1] = 0
            depth += 1
            continue
        res = _block_sum(a, los[depth], c)
        while True:  # climb until a node still needs its right half
            depth -= 1
            if depth < 0:
                return res
            if stage[depth] == 1:
                left[depth] = res
                stage[depth] = 2
                h = ns[depth] // 2
                h -= h % 8
                los[depth + 1] = los[depth] + h
                ns[depth + 1] = ns[depth] - h
                stage[depth + 1] = 0
                depth += 1
                break
            res = left[depth] + res


#: :func:`einsum_row_dot` reproduces numpy's einsum for rows up to this length (numpy's
#: iterator buffer: longer rows are summed in chunks).
EINSUM_ROW_MAX = 8192


@numba.njit(cache=True, nogil=True)
def einsum_row_dot(a: FloatArray, b: FloatArray, n: int) -> float:
    """``np.einsum("nk,nk->n", a[None, :n], b[None, :n])[0]`` with numpy's summation order.

    numpy's contiguous sum-of-products kernel on two-lane vectors: lanes ``l = 0, 1``
    accumulate, per block of eight, ``a0 b0 + (a1 b1 + (a2 b2 + (a3 b3 + acc)))``
    (unfused), then pairs, then ``acc_0 + acc_1``. Checked against ``np.einsum`` by
    ``tests/kernels/test_geodesic_row.py``; ``n <= EINSUM_ROW_MAX``.
    """
    acc0 = 0.0
    acc1 = 0.0
    i = 0
    while n - i >= 8:
        p6 = a[i + 6] * b[i + 6]
        p7 = a[i + 7] * b[i + 7]
        acc0 = p6 + acc0
        acc1 = p7 + acc1
        p4 = a[i + 4] * b[i + 4]
        p5 = a[i + 5] * b[i + 5]
        acc0 = p4 + acc0
        acc1 = p5 + acc1
        p2 = a[i + 2] * b[i + 2]
        p3 = a[i + 3] * b[i + 3]
        acc0 = p2 + acc0
        acc1 = p3 + acc1
        p0 = a[i] * b[i]
        p1 = a[i + 1] * b[i + 1]
        acc0 = p0 + acc0
        acc1 = p1 + acc1
        i += 8
    while i < n:
        acc0 = a[i] * b[i] + acc0
        if i + 1 < n:
            acc1 = a[i + 1] * b[i + 1] + acc1
        else:
            acc1 = 0.0 * 0.0 + acc1
        i += 2
    return 0.0 + (acc0 + acc1)


@functools.cache
def numpy_summation_reproduced() -> bool:
    """Whether :func:`_pairwise_sum` and :func:`einsum_row_dot` give numpy's bits here.

    They copy numpy's summation order, an implementation detail of the installed
    numpy build; the fused per-point geodesic row that relies on them is used only
    when this check (lengths 1-300 and a few long rows, several offsets) passes, so
    a numpy with another order costs speed, never reproducibility.
    """
    rng = np.random.default_rng(20121)
    buf = rng.random(EINSUM_ROW_MAX + 8) * 10.0 ** rng.integers(-6, 6, EINSUM_ROW_MAX + 8)
    other = rng.standard_normal(EINSUM_ROW_MAX + 8)
    for n in (*range(1, 301), 511, 1029, 4097, EINSUM_ROW_MAX):
        for off in (0, 1, 3):
            a, b = buf[off : off + n], other[off : off + n]
            if _pairwise_sum(a, 0, n) != a[None, :].sum(axis=1, keepdims=True)[0, 0]:
                return False
            if einsum_row_dot(a, b, n) != np.einsum("nk,nk->n", a[None, :], b[None, :])[0]:
                return False
    return True


@numba.njit(cache=True, nogil=True)
def interpolated_row_weights(
    W: FloatArray,
    log_rel: FloatArray,
    r2: FloatArray,
    n: int,
    negligible_log: float,
    normalize: bool,
    attach: bool,
    squared: bool,
) -> float:
    """Eq. 5 weights ``W`` [1, n] (``exp(arg)`` on entry), in place: weights with
    ``log_rel < -negligible_log`` set to 0, then divided by their sum if ``normalize``.

    Returns the attach cost ``sum_k W[0, k] w(r2[k])`` (``w`` = ``r2`` or ``sqrt(r2)``)
    summed as ``np.einsum`` does, or 0 without ``attach``; ``n <= EINSUM_ROW_MAX``.
    """
    w = W[0]
    for j in range(n):
        if log_rel[j] < -negligible_log:
            w[j] = 0.0
    if normalize:
        s = _pairwise_sum(w, 0, n)
        for j in range(n):
            w[j] = w[j] / s
    if not attach:
        return 0.0
    if squared:
        return einsum_row_dot(w, r2, n)
    c = np.empty(n)
    for j in range(n):
        c[j] = np.sqrt(r2[j])
    return einsum_row_dot(w, c, n)


@numba.njit(cache=True, nogil=True)
def interpolated_row_exponent(
    SP: FloatArray,
    W: FloatArray,
    P: FloatArray,
    n: int,
    unreachable: bool,
    cost: float,
    sigma_sp: float,
    out: FloatArray,
) -> None:
    """Eq. 5 for one point, last stage: ``out[j] = -0.5 (SP[0, j] + cost)^2 / sigma_sp``.

    ``SP = W @ P_finite`` [1, n]. With ``unreachable``, ``SP[0, j] = inf`` wherever a
    positive weight ``W[0, k]`` meets ``P[k, j] = inf`` (``0 * inf := 0``).
    """
    sp = SP[0]
    w = W[0]
    for j in range(n):
        out[j] = sp[j]
    if unreachable:
        for k in range(n):
            if w[k] > 0.0:
                row = P[k]
                for j in range(n):
                    if row[j] == np.inf:
                        out[j] = np.inf
    for j in range(n):
        v = out[j] + cost
        out[j] = -0.5 * (v * v / sigma_sp)


# -- adding a node (eq. 2) ---------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def squared_distances_row(
    x: FloatArray, X: FloatArray, n: int, period: FloatArray, r2: FloatArray, neg: FloatArray
) -> None:
    """``r2[j]`` = wrapped ``|x - X_j|^2`` (as :func:`wrapped_squared_distances`) and
    ``neg[j] = -r2[j]``, ``j < n``."""
    for j in range(n):
        s = _wrapped_r2(x, X, j, period)
        r2[j] = s
        neg[j] = -s


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
    """Append node ``n`` linked to every ``j`` with ``e[j] = exp(-r2[j]) > eps`` (eq. 2)
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
