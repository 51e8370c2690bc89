"""Compiled per-point rows of the geodesic kernel: JC12 eq. 4 and eq. 5 for one input.

The GP streams one point at a time; these functions do, in one call each, what the
numpy expressions of :mod:`geoq.kernels.geodesic` do for a single row, with the same
floating-point operations in the same order (only IEEE +, -, *, /, sqrt and
comparisons, which round identically here and in numpy). ``exp``, the eq. 5
product ``W @ P`` (BLAS) and the attach cost (``einsum``) stay numpy calls in the
caller. Also the eq. 3 square ``SP^2 / sigma_sp`` (:func:`squares_over`) and the
node-identity test (:func:`rows_equal`).
"""

from __future__ import annotations

import functools

import numba
import numpy as np

from geoq._geometry import wrapped_r2
from geoq._typing import FloatArray

__all__ = [
    "EINSUM_ROW_MAX",
    "einsum_row_dot",
    "interpolated_row_exponent",
    "interpolated_row_prepare",
    "interpolated_row_weights",
    "nearest_row_exponent",
    "numpy_summation_reproduced",
    "rows_equal",
    "squares_over",
]


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
        s = wrapped_r2(x, X, j, period)
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
