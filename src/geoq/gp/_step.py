"""Compiled (numba) per-point step of the sparse online GP, used by every update path.

One function, :func:`_step`, performs the whole Csató–Opper step for one
observation in place on preallocated ``[cap]`` / ``[cap, cap]`` buffers
(``cap = max_bv + 1``): predictive moments, novelty, either the projected
(non-novel) update or the full (novel) update, and -- when the budget is
exceeded -- the KL-optimal deletion of the lowest-scoring basis vector.

``Q = K_BV^{-1}`` is never formed: the state keeps the upper Cholesky factor
``R`` (``K_BV = R^T R``) and ``diag(Q)``. Novelty is then the next Cholesky pivot
``gamma = k(x,x) - |R^{-T} k|^2`` (accurate even when ``K_BV`` is badly
conditioned, where ``k^T Q k`` from an explicit inverse loses every digit);
``e_hat = Q k`` and the deleted column of ``Q`` come from two triangular solves;
adding a BV appends a column to ``R``, deleting one is a rank-one Cholesky
update of the trailing block. ``diag(Q)`` (needed for all the deletion scores)
follows the rank-one updates of ``Q`` in O(m) and is refreshed exactly by the
caller from time to time.

Inside the step the whitened covariance ``S`` is kept as its lower triangle
(matvec, rank-one updates and the deletion read and write only ``b <= a``; half
the memory traffic, no transpose pass per point). :func:`se_stream` mirrors it
onto the upper triangle once at the end of its loop, and the per-point stream of
other kernels (:func:`online_step_lower`) leaves it to its caller
(:func:`mirror_lower` once per batch and before any other reader), so callers
always see a full, exactly symmetric ``S``.

The addition and the deletion share passes: the post-addition ``mu``, ``alpha``
and ``diag(Q + C)`` are formed in O(m), the deleted index is chosen, then one
pass over the lower triangle applies the rank-one addition and forms the
matvec the deletion needs; the deletion itself is one pass of Givens rotations
over the rows below the deleted one and one pass of conditioning and compaction.

Equation references are to Csató & Opper, "Sparse on-line Gaussian processes",
Neural Computation 14 (2002) -- "CO" -- and the corrected Aston technical report
NCRG/2001/014 -- "TR" (section 3, eqs. 3.9-3.13 for the update, 3.17-3.19 for the
projection, 3.23-3.26 for the deletion).

Sign convention (see :mod:`geoq.gp.sparse_online`): ``mean = k^T alpha``,
``var = k(x, x) + k^T C k``; ``C`` is negative (semi-)definite for a PD kernel.

Symmetry of ``S`` (hence ``C``) is exact: only one triangle is computed.
Only the dot products use fast-math (reassociation).

Inner loops run over 1-D views with ``range(n)`` indices (``row = M[a, lo:hi]``,
``for b in range(row.shape[0])``): with ``M[a, b]`` and ``b`` from ``range(lo, hi)``
numba cannot prove the index non-negative, keeps its wraparound code, and LLVM
vectorises the loop with gathers (measured 3-6x slower for the triangular solves).

:func:`se_stream` is the whole-stream loop for the squared-exponential kernel:
it computes ``k_x`` inside numba (per-dimension length-scales, optional
periods) and calls the step for each row until the basis set has
changed ``stop_changes`` times (the caller then refreshes ``diag(Q)``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoq._typing import FloatArray, IntArray
from geoq.gp.diagnostics import (
    _ADDED,
    _DELETED,
    _NEGNOV,
    _NOISEFLOOR,
    _NOVCLIP,
    _PROJECTED,
    _SCORECLIP,
    _SEEN,
    _VARCLIP,
    COUNTER_NAMES,
)
from geoq.gp.numerics import VAR_ROUNDING

__all__ = [
    "COUNTER_NAMES",
    "N_WORK",
    "mirror_lower",
    "online_step_lower",
    "refresh_scores",
    "se_kernel_vector",
    "se_stream",
]

#: Whitened posterior variance (``S <= I``) below which a coordinate counts as pinned
#: by the data: the deletion then drops it instead of conditioning on it (counted as
#: ``score_clipped``), since ``S[:, i] / S[i, i]`` would be rounding noise.
_PINNED = 1e-13

#: Number of ``[cap]`` work vectors :func:`_step` needs.
N_WORK = 8


@njit(cache=True, fastmath=True)
def _dot(a: FloatArray, b: FloatArray, lo: int, hi: int) -> float:  # pragma: no cover
    """``sum_{j=lo}^{hi-1} a[j] b[j]`` (fast-math: a reassociated, vectorised reduction)."""
    av = a[lo:hi]
    bv = b[lo:hi]
    acc = 0.0
    for j in range(av.shape[0]):
        acc += av[j] * bv[j]
    return acc


@njit(cache=True, fastmath=True)
def _dot_row(M: FloatArray, row: int, b: FloatArray, lo: int, hi: int) -> float:  # pragma: no cover
    """``sum_{j=lo}^{hi-1} M[row, j] b[j]``."""
    mv = M[row, lo:hi]
    bv = b[lo:hi]
    acc = 0.0
    for j in range(mv.shape[0]):
        acc += mv[j] * bv[j]
    return acc


@njit(cache=True)
def _forward(
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
def _backward(R: FloatArray, rhs: FloatArray, m: int, out: FloatArray) -> None:  # pragma: no cover
    """Solve ``R out = rhs`` (``R`` [m, m] upper) by row-oriented back substitution."""
    for a in range(m - 1, -1, -1):
        out[a] = (rhs[a] - _dot_row(R, a, out, a + 1, m)) / R[a, a]


@njit(cache=True, fastmath=True)
def _backward2(  # pragma: no cover - compiled
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


@njit(cache=True)
def _delete_cholesky(  # pragma: no cover - compiled
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


@njit(cache=True, fastmath=True)
def _symv_row(
    row: FloatArray, v: FloatArray, va: float, g: FloatArray
) -> float:  # pragma: no cover
    """``g += row * va`` and return ``row . v`` (one row of a lower-stored symmetric matvec)."""
    acc = 0.0
    for b in range(row.shape[0]):
        rb = row[b]
        acc += rb * v[b]
        g[b] += rb * va
    return acc


@njit(cache=True)
def _symv_lower(
    S: FloatArray, v: FloatArray, lo: int, m: int, out: FloatArray
) -> None:  # pragma: no cover
    """``out = S[:m, :m] v`` from the lower triangle of ``S``, for ``v`` zero before ``lo``."""
    for a in range(m):
        out[a] = 0.0
    for a in range(lo, m):
        va = v[a]
        acc = _symv_row(S[a, lo:a], v[lo:a], va, out[lo:a])
        if lo > 0:
            sa = S[a, :lo]
            oa = out[:lo]
            for b in range(lo):
                oa[b] += sa[b] * va
        out[a] += acc + S[a, a] * va


@njit(cache=True)
def _rank_one_lower(S: FloatArray, g: FloatArray, r: float, a: int) -> None:  # pragma: no cover
    """``S[a, :a+1] += (g[a] g[:a+1]) r`` (row ``a`` of a lower-stored rank-one update)."""
    ga = g[a]
    sr = S[a, : a + 1]
    gb = g[: a + 1]
    for b in range(sr.shape[0]):
        sr[b] += (ga * gb[b]) * r


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
def _delete_whitened(  # pragma: no cover - compiled
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
    :func:`_delete_cholesky`: in the rotated coordinates BV ``i`` is the *last* in
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


@njit(cache=True)
def _step(  # pragma: no cover - compiled
    k: FloatArray,
    kxx: float,
    y: float,
    x: FloatArray,
    noise: float,
    tol: float,
    floor: float,
    noise_floor: float,
    max_bv: int,
    BV: FloatArray,
    mu: FloatArray,
    S: FloatArray,
    R: FloatArray,
    alpha: FloatArray,
    mdiag: FloatArray,
    m: int,
    work: FloatArray,
    T: FloatArray,
    counters: IntArray,
) -> tuple[int, int, int]:
    """One Csató–Opper step for ``(x, y)``, in place, on the lower triangle of ``S``.

    State (leading ``m`` block of each buffer; ``cap = max_bv + 1``):
    ``BV`` [cap, d]; ``R`` [cap, cap] upper with ``K_BV = R^T R``; the whitened
    posterior ``u ~ N(mu, S)`` with ``f_BV = R^T u`` (``mu`` [cap], ``S`` [cap, cap],
    ``0 <= S <= I``; only ``S[a, b]``, ``b <= a``, is read or written); and, for
    the deletion scores only, ``alpha = R^{-1} mu`` [cap] and
    ``mdiag = diag(Q + C) = diag(R^{-1} S R^{-T})`` [cap], both following the
    rank-one updates of Csató–Opper in O(m). ``T`` [cap, cap] and ``work``
    [N_WORK, cap] are scratch; ``counters`` int64 [len(COUNTER_NAMES)].

    Parameters
    ----------
    k : [cap] ``k(BV_j, x)`` in its first ``m`` entries.  kxx : ``k(x, x)``.
    noise : observation-noise variance ``sigma0^2``.
    tol, floor : novelty is accepted iff ``gamma > 0``, ``gamma >= tol * kxx`` and
        ``gamma >= floor * kxx``.
    noise_floor : the noise variance used is ``max(noise, noise_floor * kxx)``
        (counted when it bites): with a noise far below the rounding level of ``S``
        the rank-one downdates would amplify rounding errors without bound.

    Returns
    -------
    (m_new, added, deleted) : new basis size; 1 if ``x`` was appended to the basis
    set, else 0; the index of the deleted basis vector (after the append) or -1.
    """
    v = work[0]
    g = work[1]
    e = work[2]
    s = work[3]
    z = work[4]
    w = work[5]
    cth = work[6]
    sth = work[7]
    counters[_SEEN] += 1
    if noise < noise_floor * kxx:
        noise = noise_floor * kxx
        counters[_NOISEFLOOR] += 1

    # Predictive moments (CO eq. 6 / TR eq. 3.5) in whitened form: v = L^{-1} k,
    # mean = v^T mu, var = gamma + v^T S v with the novelty (TR eq. 3.16)
    # gamma = k(x,x) - k^T Q k = k(x,x) - |v|^2, the Cholesky pivot x would get.
    _forward(R, k, 0, m, v)
    vv = _dot(v, v, 0, m)
    gamma = kxx - vv
    if gamma < 0.0:
        counters[_NEGNOV] += 1
        if gamma < -VAR_ROUNDING * kxx:
            # Indefinite kernel: k is not a covariance column of K_BV and |v| can be
            # huge (seen: 1e3), so the update would amplify rounding until S is no
            # longer PSD and blows up. Repair: scale v onto |v|^2 = k(x, x) (gamma = 0),
            # the largest projection a PD kernel allows; the update stays exact Bayes.
            counters[_NOVCLIP] += 1
            sc = np.sqrt(kxx / vv)
            for a in range(m):
                v[a] *= sc
        gamma = 0.0
    _symv_lower(S, v, 0, m, g)  # g = S v [m]
    mean = _dot(mu, v, 0, m)
    vsv = _dot(v, g, 0, m)
    if vsv < 0.0:
        vsv = 0.0
    s2 = gamma + vsv  # var of the latent f(x) = k(x,x) + k^T C k
    if s2 < -VAR_ROUNDING * kxx:
        counters[_VARCLIP] += 1
    if s2 < 0.0:
        s2 = 0.0

    if not (gamma > 0.0 and gamma >= tol * kxx and gamma >= floor * kxx):
        # Projection (TR eq. 3.17-3.19): alpha += q eta s, C += r eta s s^T with
        # s = C k + e_hat = R^{-1} S v and q eta = (y - mean) / (sigma0^2 + v^T S v):
        # the Bayes update of u for the projected likelihood y ~ N(v^T u, sigma0^2).
        den = noise + vsv
        qe = (y - mean) / den
        re = -1.0 / den
        _backward(R, g, m, s)
        for a in range(m):
            mu[a] += qe * g[a]
            alpha[a] += qe * s[a]
            mdiag[a] += (s[a] * s[a]) * re
            _rank_one_lower(S, g, re, a)
        counters[_PROJECTED] += 1
        return m, 0, -1

    # Full update (TR eq. 3.9-3.13), x appended as BV number m: R gains the column
    # [v; sqrt(gamma)], u gains an independent N(0, 1) coordinate, then the exact
    # observation y ~ N([v; sqrt(gamma)]^T u, sigma0^2). In C-form terms
    # alpha += q s, C += r s s^T, Q += u u^T / gamma with s = [C k; 1], u = [e_hat; -1].
    counters[_ADDED] += 1
    den = noise + s2
    q = (y - mean) / den
    r = -1.0 / den
    sg = np.sqrt(gamma)
    for a in range(m):
        z[a] = g[a] - v[a]
    _backward2(R, v, z, m, e, s)  # e_hat = Q k = R^{-1} v; s = C k = R^{-1} (S - I) v
    for a in range(m):
        R[a, m] = v[a]
        R[m, a] = 0.0
        S[m, a] = 0.0
    R[m, m] = sg
    S[m, m] = 1.0
    mu[m] = 0.0
    g[m] = sg
    s[m] = 1.0
    e[m] = -1.0
    alpha[m] = 0.0
    mdiag[m] = 0.0
    BV[m, :] = x
    m1 = m + 1
    ig = 1.0 / gamma
    for a in range(m1):
        mu[a] += q * g[a]
        alpha[a] += q * s[a]
        mdiag[a] += (e[a] * e[a]) * ig + (s[a] * s[a]) * r
    if m1 <= max_bv:
        for a in range(m1):
            _rank_one_lower(S, g, r, a)
        return m1, 1, -1

    # Budget exceeded: delete the BV with the lowest score alpha_i^2 / (Q_ii + C_ii)
    # (TR eq. 3.26). With w = (Q + C) e_i = R^{-1} S R^{-T} e_i and a* = alpha_i the
    # downdates (TR eq. 3.23-3.25) give alpha <- alpha - a* w / w_i and
    # Q + C <- (Q + C) - w w^T / w_i; the whitened posterior is rotated so that BV i
    # is last in Cholesky order, then conditioned on its coordinate being 0.
    best = -1
    best_score = np.inf
    for a in range(m1):
        if mdiag[a] <= 0.0:
            continue
        score = alpha[a] * alpha[a] / mdiag[a]
        if score < best_score:
            best_score = score
            best = a
    if best < 0:  # no positive diag(Q + C): drifted scores; delete the newest point
        counters[_SCORECLIP] += 1
        best = m
    i = best
    for a in range(m1):
        w[a] = 0.0
    w[i] = 1.0
    _forward(R, w, i, m1, z)  # z = R^{-T} e_i
    # One pass over the lower triangle: the rank-one update of the addition, and
    # e = S z with the updated rows (z is zero before i).
    for a in range(m1):
        e[a] = 0.0
    for a in range(m1):
        _rank_one_lower(S, g, r, a)
        if a >= i:
            za = z[a]
            acc = _symv_row(S[a, i:a], z[i:a], za, e[i:a])
            sa = S[a, :i]
            ea = e[:i]
            for b in range(i):
                ea[b] += sa[b] * za
            e[a] += acc + S[a, a] * za
    _backward(R, e, m1, w)  # w = column i of Q + C
    wi = w[i]
    f = alpha[i] / wi if wi > 0.0 else 0.0
    iw = 1.0 / wi if wi > 0.0 else 0.0
    for a in range(m1):
        if a == i:
            continue
        a2 = a if a < i else a - 1
        alpha[a2] = alpha[a] - f * w[a]
        mdiag[a2] = mdiag[a] - (w[a] * w[a]) * iw
    _delete_cholesky(R, i, m1, z, cth, sth)
    _delete_whitened(S, mu, T[0], T[1], i, m1, cth, sth, counters)
    for a in range(i + 1, m1):
        BV[a - 1, :] = BV[a, :]
    counters[_DELETED] += 1
    return m, 1, i


@njit(cache=True)
def online_step_lower(  # pragma: no cover - compiled
    k: FloatArray,
    scale: float,
    kxx: float,
    y: float,
    x: FloatArray,
    noise: float,
    tol: float,
    floor: float,
    noise_floor: float,
    max_bv: int,
    BV: FloatArray,
    mu: FloatArray,
    S: FloatArray,
    R: FloatArray,
    alpha: FloatArray,
    mdiag: FloatArray,
    m: int,
    work: FloatArray,
    T: FloatArray,
    counters: IntArray,
) -> tuple[int, int, int]:
    """:func:`_step` for a stream of points: ``S`` stays lower-triangular (no mirror).

    ``k[:m]`` is first multiplied by ``scale`` in place (``scale = 1`` leaves it
    unchanged bit for bit). If ``k[:m]`` or ``kxx`` is not finite the state is left
    untouched and ``(m, -1, -1)`` is returned. The caller mirrors ``S`` with
    :func:`mirror_lower` before anything else reads it.
    """
    finite = np.isfinite(kxx)
    for j in range(m):
        kj = k[j] * scale
        k[j] = kj
        if not np.isfinite(kj):
            finite = False
    if not finite:
        return m, -1, -1
    return _step(
        k, kxx, y, x, noise, tol, floor, noise_floor, max_bv,
        BV, mu, S, R, alpha, mdiag, m, work, T, counters,
    )  # fmt: skip


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
        d = _dot(wa, Z[a, a:m], 0, m - a)
        drift = max(drift, abs(mdiag[a] - d))
        scale = max(scale, abs(d))
        mdiag[a] = d
    return drift / scale if scale > 0.0 else 0.0


@njit(cache=True)
def se_kernel_vector(  # pragma: no cover - compiled
    x: FloatArray,
    BV: FloatArray,
    m: int,
    inv_ls: FloatArray,
    period: FloatArray,
    variance: float,
    out: FloatArray,
) -> None:
    """``out[j] = variance * exp(-0.5 * sum_k (wrap(x_k - BV_jk) * inv_ls_k)^2)``, j < m.

    ``period[k] > 0`` wraps dimension ``k`` onto the circle (nearest image).
    """
    d = x.shape[0]
    for j in range(m):
        r2 = 0.0
        for c in range(d):
            diff = x[c] - BV[j, c]
            p = period[c]
            if p > 0.0:
                diff -= p * np.round(diff / p)
            diff *= inv_ls[c]
            r2 += diff * diff
        out[j] = variance * np.exp(-0.5 * r2)


@njit(cache=True)
def se_stream(  # pragma: no cover - compiled
    X: FloatArray,
    y: FloatArray,
    start: int,
    inv_ls: FloatArray,
    period: FloatArray,
    variance: float,
    noise: float,
    tol: float,
    floor: float,
    noise_floor: float,
    max_bv: int,
    BV: FloatArray,
    mu: FloatArray,
    S: FloatArray,
    R: FloatArray,
    alpha: FloatArray,
    mdiag: FloatArray,
    m: int,
    kbuf: FloatArray,
    work: FloatArray,
    T: FloatArray,
    counters: IntArray,
    stop_changes: int,
) -> tuple[int, int, int]:
    """Stream rows ``start, start+1, ...`` of ``X`` [N, d], ``y`` [N] through :func:`_step`.

    Stops after the row at which the basis set has changed ``stop_changes``
    times (an addition or a deletion each count one), or at the end.

    Returns
    -------
    (next_row, m, changes) : the first unprocessed row, the basis size, and the
    number of basis-set changes made.
    """
    changes = 0
    n = X.shape[0]
    t = start
    while t < n:
        se_kernel_vector(X[t], BV, m, inv_ls, period, variance, kbuf)
        m, added, deleted = _step(
            kbuf, variance, y[t], X[t], noise, tol, floor, noise_floor, max_bv,
            BV, mu, S, R, alpha, mdiag, m, work, T, counters,
        )  # fmt: skip
        t += 1
        changes += added + (1 if deleted >= 0 else 0)
        if changes >= stop_changes:
            break
    mirror_lower(S, m)  # the steps keep the lower triangle only
    return t, m, changes
