"""Compiled per-point rows of the geodesic kernel: JC12 eq. 4 and JC12 eq. 5 for one input.

The GP streams one point at a time; these functions do, in one call each, what the
numpy expressions of :mod:`geoq.kernels.graph_distance` do for a single row, with the same
floating-point operations in the same order (only IEEE +, -, *, /, sqrt and
comparisons, which round identically here and in numpy). The two sums of JC12 eq. 5
(the normalising weight sum and the attach cost) are defined here,
:func:`row_sum` and :func:`row_dot`, and the numpy path calls them too
(:func:`row_sums`, :func:`row_dots`): both paths give the same bits by
construction, whatever order numpy sums in. ``exp`` and the JC12 eq. 5 product
``W @ P`` (BLAS) stay numpy calls in the caller. JC12 eq. 3's ``r^2 = SP^2 / sigma_sp``
is computed by :func:`geodesic_r2` alone, for both paths (the batch path through
:func:`squares_over`). Also the node-identity test (:func:`rows_equal`).
"""

from __future__ import annotations

import numba
import numpy as np

from geoq._geometry import wrapped_r2
from geoq._typing import FloatArray

__all__ = [
    "geodesic_r2",
    "interpolated_row_exponent",
    "interpolated_row_prepare",
    "interpolated_row_weights",
    "nearest_row_exponent",
    "row_dot",
    "row_dots",
    "row_sum",
    "row_sums",
    "rows_equal",
    "squares_over",
]


@numba.njit(cache=True, nogil=True)
def geodesic_r2(sp: float, sigma_sp: float) -> float:
    """JC12 eq. 3: ``r^2 = SP^2 / sigma_sp``, so that ``k_sp = A exp(-r^2 / 2)``.

    The one definition: :func:`squares_over` (the batch path) and the per-point rows
    call it. Two correctly rounded operations, the same bits as numpy's
    ``SP * SP / sigma_sp``; overflow gives ``inf`` without a warning.
    """
    return sp * sp / sigma_sp


@numba.njit(cache=True, nogil=True)
def squares_over(X: FloatArray, s: float) -> FloatArray:
    """:func:`geodesic_r2` of every entry of ``X`` [N, M] with ``sigma_sp = s`` -> [N, M]."""
    N, M = X.shape
    out = np.empty((N, M))
    for i in range(N):
        for j in range(M):
            out[i, j] = geodesic_r2(X[i, j], s)
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
    """JC12 eq. 4 for one point: ``out[j] = -0.5 r^2(x, x_j)`` (:func:`geodesic_r2`), ``j < n``.

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
        out[j] = -0.5 * geodesic_r2(c + row[j], sigma_sp)
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
    """JC12 eq. 5 for one point, first stage: ``r2`` [n] and the exponents of the weights.

    Returns the nearest node ``a`` (lowest index among ties) if ``x`` is not on it,
    ``-2 - a`` if it is (``r2[a] == 0``), ``-1`` if ``BV[:n]`` is not the node set or
    ``r2[a] / two_sigma_se`` overflows (the general path's far-point branch applies).
    Off the nodes, with ``z = r2 / two_sigma_se``: ``log_rel = z[a] - z`` and
    ``arg`` = ``log_rel`` (``normalize``) or ``-z``; the weights are ``exp(arg)``.
    """
    a = _row_r2_on_nodes(x, X, n, BV, period, r2)
    if a < 0:
        return a
    if r2[a] == 0.0:
        return -2 - a
    zmin = r2[a] / two_sigma_se
    if not np.isfinite(zmin):  # far from every node: the general path handles the overflow
        return -1
    for j in range(n):
        z = r2[j] / two_sigma_se
        lr = zmin - z
        log_rel[j] = lr
        arg[j] = lr if normalize else -z
    return a


@numba.njit(cache=True, nogil=True)
def row_sum(a: FloatArray, n: int) -> float:  # pragma: no cover - compiled
    """``sum_{k<n} a[k]``, left to right: the one definition of a JC12 eq. 5 weight sum."""
    acc = 0.0
    for k in range(n):
        acc += a[k]
    return acc


@numba.njit(cache=True, nogil=True)
def row_dot(a: FloatArray, b: FloatArray, n: int) -> float:  # pragma: no cover - compiled
    """``sum_{k<n} a[k] b[k]``, left to right: the one definition of the JC12 eq. 5 attach cost."""
    acc = 0.0
    for k in range(n):
        acc += a[k] * b[k]
    return acc


@numba.njit(cache=True, nogil=True)
def row_sums(A: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """:func:`row_sum` of every row of ``A`` [N, n] -> [N] (the batch path's sums)."""
    out = np.empty(A.shape[0])
    for i in range(A.shape[0]):
        out[i] = row_sum(A[i], A.shape[1])
    return out


@numba.njit(cache=True, nogil=True)
def row_dots(A: FloatArray, B: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """:func:`row_dot` of every row pair of ``A``, ``B`` [N, n] -> [N]."""
    out = np.empty(A.shape[0])
    for i in range(A.shape[0]):
        out[i] = row_dot(A[i], B[i], A.shape[1])
    return out


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
    """JC12 eq. 5 weights ``W`` [1, n] (``exp(arg)`` on entry), in place: weights with
    ``log_rel < -negligible_log`` set to 0, then divided by their sum if ``normalize``.

    Returns the attach cost ``sum_k W[0, k] w(r2[k])`` (``w`` = ``r2`` or ``sqrt(r2)``)
    by :func:`row_dot`, or 0 without ``attach``.
    """
    w = W[0]
    for j in range(n):
        if log_rel[j] < -negligible_log:
            w[j] = 0.0
    if normalize:
        s = row_sum(w, n)
        for j in range(n):
            w[j] = w[j] / s
    if not attach:
        return 0.0
    if squared:
        return row_dot(w, r2, n)
    c = np.empty(n)
    for j in range(n):
        c[j] = np.sqrt(r2[j])
    return row_dot(w, c, n)


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
    """JC12 eq. 5 for one point, last stage: ``out[j] = -0.5 r^2`` of ``SP[0, j] + cost``
    (:func:`geodesic_r2`).

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
        out[j] = -0.5 * geodesic_r2(out[j] + cost, sigma_sp)
