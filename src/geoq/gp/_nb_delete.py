"""Compiled (numba) KL-optimal deletion of a basis vector, and the exact score refresh.

The deletion (TR eq. 3.23-3.26; see :mod:`geoq.gp._step` for the citation keys)
works on the state of :func:`geoq.gp._step._step`: the upper Cholesky factor ``R``
of ``K_BV`` and the whitened posterior ``u ~ N(mu, S)`` (``S`` stored as its lower
triangle). :func:`delete_cholesky` removes the row/column from ``R`` by Givens
rotations; :func:`delete_whitened` applies the same rotations to ``(mu, S)`` and
conditions on the deleted coordinate. :func:`refresh_scores` recomputes the
deletion scores' ingredients ``alpha = R^{-1} mu`` and ``diag(Q + C)`` exactly
(the step keeps them by O(m) updates between refreshes).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoq._typing import FloatArray, IntArray
from geoq.gp._nb_linalg import dot
from geoq.gp.diagnostics import _SCORECLIP

__all__ = ["delete_cholesky", "delete_whitened", "refresh_scores"]

#: Whitened posterior variance (``S <= I``) below which a coordinate counts as pinned
#: by the data: the deletion then drops it instead of conditioning on it (counted as
#: ``score_clipped``), since ``S[:, i] / S[i, i]`` would be rounding noise.
_PINNED = 1e-13


@njit(cache=True)
def delete_cholesky(  # pragma: no cover - compiled
    R: FloatArray, i: int, m: int, x: FloatArray, cth: FloatArray, sth: FloatArray
) -> None:
    """Remove row/column ``i`` of ``K = R^T R`` (``R`` [m, m] upper) in place.

    Rows above ``i`` lose column ``i``; the trailing block ``T`` satisfies
    ``T'^T T' = T^T T + x x^T`` with ``x = R[i, i+1:]`` (a rank-one Cholesky *update*,
    always stable), and moves up-left by one. In ``L = R^T`` terms the sweep is a
    sequence of Givens rotations of the column pairs ``(j, i)``, ``j = i+1 .. m-1``,
    with cosines ``cth[j]`` and sines ``sth[j]``; the caller applies the same
    rotations to the whitened posterior. ``x`` [m] is scratch.
    """
    n = m - 1 - i
    for a in range(i):  # shift left by one (via x: an overlapping copy would not vectorise)
        src = R[a, i + 1 : m]
        dst = R[a, i : m - 1]
        tmp = x[:n]
        for b in range(n):
            tmp[b] = src[b]
        for b in range(n):
            dst[b] = tmp[b]
    for b in range(i + 1, m):
        x[b] = R[i, b]
    for j in range(i + 1, m):
        d = R[j, j]
        xj = x[j]
        rr = np.sqrt(d * d + xj * xj)
        c = d / rr
        sn = xj / rr
        cth[j] = c
        sth[j] = sn
        R[j - 1, j - 1] = rr
        rj = R[j, j + 1 : m]
        rd = R[j - 1, j : m - 1]
        xb = x[j + 1 : m]
        for b in range(rj.shape[0]):
            t = rj[b]
            nv = c * t + sn * xb[b]
            xb[b] = c * xb[b] - sn * t
            rd[b] = nv


@njit(cache=True)
def _catch_up(
    S: FloatArray, i: int, r: int, k0: int, x: float, cth: FloatArray, sth: FloatArray
) -> float:  # pragma: no cover - compiled
    """Carry ``x <- c_k x - s_k S[r, k]`` for ``k = k0 .. r-1`` (one row, serial)."""
    sr = S[r, k0:r]
    cv = cth[k0:r]
    sv = sth[k0:r]
    for k in range(sr.shape[0]):
        x = cv[k] * x - sv[k] * sr[k]
    return x


@njit(cache=True)
def _col_carry(
    S: FloatArray, r: int, j0: int, y: float, cth: FloatArray, sth: FloatArray
) -> float:  # pragma: no cover - compiled
    """Column rotations of row ``r`` for ``j = j0 .. r``: ``S[r, j] <- c_j t + s_j y``,
    ``y <- c_j y - s_j t`` with ``t = S[r, j]`` (one row, serial); returns ``y``."""
    sr = S[r, j0 : r + 1]
    cv = cth[j0 : r + 1]
    sv = sth[j0 : r + 1]
    for j in range(sr.shape[0]):
        t = sr[j]
        sr[j] = cv[j] * t + sv[j] * y
        y = cv[j] * y - sv[j] * t
    return y


@njit(cache=True)
def delete_whitened(  # pragma: no cover - compiled
    S: FloatArray,
    mu: FloatArray,
    sig: FloatArray,
    x: FloatArray,
    i: int,
    m: int,
    cth: FloatArray,
    sth: FloatArray,
    counters: IntArray,
) -> None:
    """Csató–Opper deletion of whitened coordinate ``i`` after the Givens rotations.

    ``S`` is stored as its lower triangle (the upper one is not read or kept).
    ``S <- G^T S G`` and ``mu <- G^T mu`` with the rotations of
    :func:`delete_cholesky`: in the rotated coordinates BV ``i`` is the *last* in
    Cholesky order and no other BV depends on coordinate ``i``. The KL-optimal
    downdates (TR eq. 3.23-3.25), written in these coordinates, are conditioning
    on ``u_i = 0``: with ``sig = (G^T S G)[:, i]`` and ``vs = sig[i]``::

        mu <- mu_rest - sig mu_i / vs,    S <- S_rest - sig sig^T / vs

    Pass 1, rows ``r > i`` in order: the row rotations ``A = G^T S`` keep row ``i``
    of ``A`` as a carry vector ``x`` [cap] (row ``r`` of ``A`` is
    ``c_r S[r] + s_r x``, then ``x <- c_r x - s_r S[r]``). Only the lower part
    ``A[r, :r+1]`` is formed; the entry ``x[r]`` it needs involves the upper
    elements ``S[k, r] = S[r, k]``, ``k < r``, and is brought up to date from row
    ``r`` itself just before (a serial recurrence). Then the column rotations
    ``A G`` of the lower triangle (a carry recurrence along the row). Both serial
    recurrences run four rows in lockstep (independent chains). The arithmetic is
    that of the full-storage two-sided rotation. Pass 2: the conditioning and the
    compaction of row/column ``i``. ``sig``, ``x`` [cap] are scratch.
    """
    for j in range(i + 1, m):
        t = mu[j]
        mu[j] = cth[j] * t + sth[j] * mu[i]
        mu[i] = cth[j] * mu[i] - sth[j] * t
    xi = S[i, : i + 1]
    for b in range(i + 1):
        x[b] = xi[b]
    r0 = i + 1
    while r0 < m:
        nb = min(4, m - r0)
        # catch-up of x[r] for the rows of the block (original rows, read before any is rotated)
        c0 = S[r0, i]
        c1 = S[r0 + 1, i] if nb > 1 else 0.0
        c2 = S[r0 + 2, i] if nb > 2 else 0.0
        c3 = S[r0 + 3, i] if nb > 3 else 0.0
        if nb == 4:
            s0 = S[r0, i + 1 : r0]
            s1 = S[r0 + 1, i + 1 : r0]
            s2 = S[r0 + 2, i + 1 : r0]
            s3 = S[r0 + 3, i + 1 : r0]
            cv = cth[i + 1 : r0]
            sv = sth[i + 1 : r0]
            for k in range(s0.shape[0]):
                c = cv[k]
                sn = sv[k]
                c0 = c * c0 - sn * s0[k]
                c1 = c * c1 - sn * s1[k]
                c2 = c * c2 - sn * s2[k]
                c3 = c * c3 - sn * s3[k]
            c1 = _catch_up(S, i, r0 + 1, r0, c1, cth, sth)
            c2 = _catch_up(S, i, r0 + 2, r0, c2, cth, sth)
            c3 = _catch_up(S, i, r0 + 3, r0, c3, cth, sth)
        else:
            c0 = _catch_up(S, i, r0, i + 1, c0, cth, sth)
            if nb > 1:
                c1 = _catch_up(S, i, r0 + 1, i + 1, c1, cth, sth)
            if nb > 2:
                c2 = _catch_up(S, i, r0 + 2, i + 1, c2, cth, sth)
        # row rotations: A[r, :r+1] = c_r S[r, :r+1] + s_r x, x <- c_r x - s_r S[r]
        for q in range(nb):
            r = r0 + q
            x[r] = c0 if q == 0 else (c1 if q == 1 else (c2 if q == 2 else c3))
            c = cth[r]
            sn = sth[r]
            sr = S[r, : r + 1]
            xr = x[: r + 1]
            for b in range(sr.shape[0]):
                t = sr[b]
                sr[b] = c * t + sn * xr[b]
                xr[b] = c * xr[b] - sn * t
        # column rotations of the lower triangle: S[r, j] for i < j <= r
        y0 = S[r0, i]
        if nb == 4:
            y1 = S[r0 + 1, i]
            y2 = S[r0 + 2, i]
            y3 = S[r0 + 3, i]
            a0 = S[r0, i + 1 : r0 + 1]
            a1 = S[r0 + 1, i + 1 : r0 + 1]
            a2 = S[r0 + 2, i + 1 : r0 + 1]
            a3 = S[r0 + 3, i + 1 : r0 + 1]
            cv = cth[i + 1 : r0 + 1]
            sv = sth[i + 1 : r0 + 1]
            for j in range(a0.shape[0]):
                c = cv[j]
                sn = sv[j]
                t0 = a0[j]
                t1 = a1[j]
                t2 = a2[j]
                t3 = a3[j]
                a0[j] = c * t0 + sn * y0
                a1[j] = c * t1 + sn * y1
                a2[j] = c * t2 + sn * y2
                a3[j] = c * t3 + sn * y3
                y0 = c * y0 - sn * t0
                y1 = c * y1 - sn * t1
                y2 = c * y2 - sn * t2
                y3 = c * y3 - sn * t3
            _col_carry(S, r0 + 1, r0 + 1, y1, cth, sth)
            _col_carry(S, r0 + 2, r0 + 1, y2, cth, sth)
            _col_carry(S, r0 + 3, r0 + 1, y3, cth, sth)
        else:
            for q in range(nb):
                _col_carry(S, r0 + q, i + 1, S[r0 + q, i], cth, sth)
        r0 += nb
    # sig = row i of A G: columns < i as they are, columns > i by the carry recurrence.
    for b in range(i):
        sig[b] = x[b]
    xc = x[i]
    for j in range(i + 1, m):
        t = x[j]
        sig[j] = cth[j] * t + sth[j] * xc
        xc = cth[j] * xc - sth[j] * t
    sig[i] = xc
    vs = xc
    if vs > _PINNED:
        iv = 1.0 / vs
        fm = mu[i] * iv
    else:  # degenerate: coordinate i is pinned to rounding level; its regression
        # coefficients sig / vs would be rounding noise: drop it without conditioning
        counters[_SCORECLIP] += 1
        iv = 0.0
        fm = 0.0
    for a in range(m):
        if a != i:
            mu[a] -= sig[a] * fm
    for j in range(i + 1, m):
        mu[j - 1] = mu[j]
    # Pass 2: conditioning of the lower triangle, compacted in place (row a > i moves
    # to a - 1 after row a - 1 has been consumed; column j > i moves to j - 1).
    for a in range(i):
        sa = sig[a] * iv
        sr = S[a, : a + 1]
        for b in range(a + 1):
            sr[b] -= sa * sig[b]
    for a in range(i + 1, m):
        sa = sig[a] * iv
        src = S[a, :i]
        dst = S[a - 1, :i]
        for b in range(i):
            dst[b] = src[b] - sa * sig[b]
        src = S[a, i + 1 : a + 1]
        dst = S[a - 1, i:a]
        sg = sig[i + 1 : a + 1]
        for b in range(src.shape[0]):
            dst[b] = src[b] - sa * sg[b]


@njit(cache=True, fastmath=True)
def refresh_scores(  # pragma: no cover - compiled
    R: FloatArray,
    mu: FloatArray,
    S: FloatArray,
    m: int,
    alpha: FloatArray,
    mdiag: FloatArray,
    Z: FloatArray,
    W: FloatArray,
) -> float:
    """Recompute ``alpha = R^{-1} mu`` and ``mdiag = diag(R^{-1} S R^{-T})`` exactly, in place.

    ``Z = R^{-1}`` (upper, by row-oriented back substitution on ``I``) and the
    upper triangle of ``W = Z S`` are formed in the scratch buffers ``Z``, ``W`` [cap, cap]
    (``m^3 / 2`` multiply-adds, single-threaded). Returns the drift
    ``max|mdiag_old - mdiag_new| / max|mdiag_new|`` (0 if ``mdiag_new == 0``).
    """
    for a in range(m - 1, -1, -1):  # row a of Z: (e_a - sum_{j>a} R[a, j] Z[j, :]) / R[a, a]
        za = Z[a, :m]
        for b in range(m):
            za[b] = 0.0
        za[a] = 1.0
        for j in range(a + 1, m):
            raj = R[a, j]
            zj = Z[j, j:m]
            zaj = Z[a, j:m]
            for b in range(zj.shape[0]):
                zaj[b] -= raj * zj[b]
        inv = 1.0 / R[a, a]
        zaa = Z[a, a:m]
        for b in range(zaa.shape[0]):
            zaa[b] *= inv
    drift = 0.0
    scale = 0.0
    for a in range(m):  # only W[a, a:] = Z[a, :] S[:, a:] is needed (Z is upper)
        wa = W[a, a:m]
        for b in range(wa.shape[0]):
            wa[b] = 0.0
        acc = 0.0
        for j in range(a, m):
            zaj = Z[a, j]
            acc += zaj * mu[j]
            sj = S[j, a:m]
            for b in range(sj.shape[0]):
                wa[b] += zaj * sj[b]
        alpha[a] = acc
        d = dot(wa, Z[a, a:m], 0, m - a)
        drift = max(drift, abs(mdiag[a] - d))
        scale = max(scale, abs(d))
        mdiag[a] = d
    return drift / scale if scale > 0.0 else 0.0
