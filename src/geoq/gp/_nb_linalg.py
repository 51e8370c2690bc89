"""Compiled (numba) dense linear algebra of the online step: dots, triangular solves, symv.

Small building blocks of :mod:`geoq.gp._step` and :mod:`geoq.gp._nb_delete`, on the
leading ``m`` block of preallocated ``[cap]`` / ``[cap, cap]`` buffers. A symmetric
matrix is stored as its lower triangle (``S[a, b]``, ``b <= a``): :func:`symv_lower`
and :func:`rank_one_lower` read and write only that triangle, and
:func:`mirror_lower` copies it onto the upper one before anyone else reads ``S``.

Only the dot products use fast-math (reassociation). Inner loops run over 1-D
views with ``range(n)`` indices (``row = M[a, lo:hi]``, ``for b in range(row.shape[0])``):
with ``M[a, b]`` and ``b`` from ``range(lo, hi)`` numba cannot prove the index
non-negative, keeps its wraparound code, and LLVM vectorises the loop with
gathers (several times slower for the triangular solves; see ``benchmarks/``).
"""

from __future__ import annotations

from numba import njit

from geoq._typing import FloatArray

__all__ = [
    "backward",
    "backward2",
    "dot",
    "dot_row",
    "forward",
    "mirror_lower",
    "rank_one_lower",
    "symv_lower",
    "symv_row",
]


@njit(cache=True, fastmath=True)
def dot(a: FloatArray, b: FloatArray, lo: int, hi: int) -> float:  # pragma: no cover
    """``sum_{j=lo}^{hi-1} a[j] b[j]`` (fast-math: a reassociated, vectorised reduction)."""
    av = a[lo:hi]
    bv = b[lo:hi]
    acc = 0.0
    for j in range(av.shape[0]):
        acc += av[j] * bv[j]
    return acc


@njit(cache=True, fastmath=True)
def dot_row(M: FloatArray, row: int, b: FloatArray, lo: int, hi: int) -> float:  # pragma: no cover
    """``sum_{j=lo}^{hi-1} M[row, j] b[j]``."""
    mv = M[row, lo:hi]
    bv = b[lo:hi]
    acc = 0.0
    for j in range(mv.shape[0]):
        acc += mv[j] * bv[j]
    return acc


@njit(cache=True)
def forward(
    R: FloatArray, rhs: FloatArray, first: int, m: int, out: FloatArray
) -> None:  # pragma: no cover
    """Solve ``R^T out = rhs`` (``R`` [m, m] upper, ``R^T = L``) for ``rhs`` zero before ``first``.

    Column-oriented on ``L`` = row-oriented on ``R``: each step is a contiguous axpy.
    """
    for a in range(first):
        out[a] = 0.0
    for a in range(first, m):
        out[a] = rhs[a]
    for j in range(first, m):
        out[j] /= R[j, j]
        oj = out[j]
        rj = R[j, j + 1 : m]
        oa = out[j + 1 : m]
        for a in range(rj.shape[0]):
            oa[a] -= rj[a] * oj


@njit(cache=True)
def backward(R: FloatArray, rhs: FloatArray, m: int, out: FloatArray) -> None:  # pragma: no cover
    """Solve ``R out = rhs`` (``R`` [m, m] upper) by row-oriented back substitution."""
    for a in range(m - 1, -1, -1):
        out[a] = (rhs[a] - dot_row(R, a, out, a + 1, m)) / R[a, a]


@njit(cache=True, fastmath=True)
def backward2(  # pragma: no cover - compiled
    R: FloatArray, rhs1: FloatArray, rhs2: FloatArray, m: int, out1: FloatArray, out2: FloatArray
) -> None:
    """Two back substitutions ``R out1 = rhs1``, ``R out2 = rhs2`` in one pass over ``R``."""
    for a in range(m - 1, -1, -1):
        acc1 = 0.0
        acc2 = 0.0
        ra = R[a, a + 1 : m]
        p1 = out1[a + 1 : m]
        p2 = out2[a + 1 : m]
        for j in range(ra.shape[0]):
            r = ra[j]
            acc1 += r * p1[j]
            acc2 += r * p2[j]
        out1[a] = (rhs1[a] - acc1) / R[a, a]
        out2[a] = (rhs2[a] - acc2) / R[a, a]


@njit(cache=True, fastmath=True)
def symv_row(row: FloatArray, v: FloatArray, va: float, g: FloatArray) -> float:  # pragma: no cover
    """``g += row * va`` and return ``row . v`` (one row of a lower-stored symmetric matvec)."""
    acc = 0.0
    for b in range(row.shape[0]):
        rb = row[b]
        acc += rb * v[b]
        g[b] += rb * va
    return acc


@njit(cache=True)
def symv_lower(
    S: FloatArray, v: FloatArray, lo: int, m: int, out: FloatArray
) -> None:  # pragma: no cover
    """``out = S[:m, :m] v`` from the lower triangle of ``S``, for ``v`` zero before ``lo``."""
    for a in range(m):
        out[a] = 0.0
    for a in range(lo, m):
        va = v[a]
        acc = symv_row(S[a, lo:a], v[lo:a], va, out[lo:a])
        if lo > 0:
            sa = S[a, :lo]
            oa = out[:lo]
            for b in range(lo):
                oa[b] += sa[b] * va
        out[a] += acc + S[a, a] * va


@njit(cache=True)
def rank_one_lower(S: FloatArray, g: FloatArray, r: float, a: int) -> None:  # pragma: no cover
    """``S[a, :a+1] += (g[a] g[:a+1]) r`` (row ``a`` of a lower-stored rank-one update)."""
    ga = g[a]
    sr = S[a, : a + 1]
    gb = g[: a + 1]
    for b in range(sr.shape[0]):
        sr[b] += (ga * gb[b]) * r


@njit(cache=True)
def mirror_lower(S: FloatArray, n: int) -> None:  # pragma: no cover - compiled
    """Copy the lower triangle of ``S[:n, :n]`` onto its upper triangle (tiled transpose)."""
    bs = 32
    for a0 in range(0, n, bs):
        a1 = min(a0 + bs, n)
        for b0 in range(0, a0 + 1, bs):
            b1 = min(b0 + bs, n)
            for a in range(a0, a1):
                for b in range(b0, min(b1, a)):
                    S[b, a] = S[a, b]
