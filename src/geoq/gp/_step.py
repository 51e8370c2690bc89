"""Compiled (numba) per-point step of the sparse online GP, used by every update path.

One function, :func:`online_step`, performs the whole Csató–Opper step for one
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

The addition and the deletion are fused: the post-addition diagonal, ``alpha``
and the deleted column are formed in O(m), then one pass over ``C`` applies the
rank-one addition and the rank-two deletion downdate while compacting the
deleted row and column away (order is preserved).

Equation references are to Csató & Opper, "Sparse on-line Gaussian processes",
Neural Computation 14 (2002) -- "CO" -- and the corrected Aston technical report
NCRG/2001/014 -- "TR" (section 3, eqs. 3.9-3.13 for the update, 3.17-3.19 for the
projection, 3.23-3.26 for the deletion).

Sign convention (see :mod:`geoq.gp.sparse_online`): ``mean = k^T alpha``,
``var = k(x, x) + k^T C k``; ``C`` is negative (semi-)definite for a PD kernel.

Symmetry of ``C`` is exact: every update adds symmetric terms written as
``(s[a] * s[b]) * r`` (IEEE products commute), so a symmetric matrix stays bit
for bit symmetric. Only the dot products use fast-math (reassociation).

Inner loops run over 1-D views with ``range(n)`` indices (``row = M[a, lo:hi]``,
``for b in range(row.shape[0])``): with ``M[a, b]`` and ``b`` from ``range(lo, hi)``
numba cannot prove the index non-negative, keeps its wraparound code, and LLVM
vectorises the loop with gathers (measured 3-6x slower for the triangular solves).

:func:`se_stream` is the whole-stream loop for the squared-exponential kernel:
it computes ``k_x`` inside numba (per-dimension length-scales, optional
periods) and calls :func:`online_step` for each row until the basis set has
changed ``stop_changes`` times (the caller then refreshes ``diag(Q)``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from geoq._typing import FloatArray, IntArray

__all__ = [
    "COUNTER_NAMES",
    "N_WORK",
    "online_step",
    "refresh_scores",
    "se_kernel_vector",
    "se_stream",
]

#: Indices into the int64 counter array shared by Python and numba.
COUNTER_NAMES: tuple[str, ...] = (
    "n_seen",
    "n_added",
    "n_projected",
    "n_deleted",
    "negative_novelty",
    "variance_clipped",
    "novelty_clipped",
    "score_clipped",
    "noise_floored",
)
_SEEN, _ADDED, _PROJECTED, _DELETED, _NEGNOV, _VARCLIP, _NOVCLIP, _SCORECLIP, _NOISEFLOOR = range(9)

#: A negative predictive variance above ``-_VAR_ROUNDING * k(x, x)`` is rounding noise:
#: it is clipped to 0 silently; below that it is clipped *and* counted.
_VAR_ROUNDING = 1e-9

#: Whitened posterior variance (``S <= I``) below which a coordinate counts as pinned
#: by the data: the deletion then drops it instead of conditioning on it (counted as
#: ``score_clipped``), since ``S[:, i] / S[i, i]`` would be rounding noise.
_PINNED = 1e-13

#: Number of ``[cap]`` work vectors :func:`online_step` needs.
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


@njit(cache=True)
def _rotate_rows(  # pragma: no cover - compiled
    A: FloatArray, i: int, m: int, ncol: int, cth: FloatArray, sth: FloatArray
) -> None:
    """``A <- G^T A`` on rows ``(j, i)``, ``j = i+1 .. m-1``: contiguous, vectorised."""
    ai = A[i, :ncol]
    for j in range(i + 1, m):
        c = cth[j]
        sn = sth[j]
        aj = A[j, :ncol]
        for b in range(ncol):
            t = aj[b]
            xi = ai[b]
            aj[b] = c * t + sn * xi
            ai[b] = c * xi - sn * t


@njit(cache=True)
def _delete_whitened(  # pragma: no cover - compiled
    S: FloatArray,
    mu: FloatArray,
    sig: FloatArray,
    i: int,
    m: int,
    cth: FloatArray,
    sth: FloatArray,
    counters: IntArray,
) -> None:
    """Csató–Opper deletion of whitened coordinate ``i`` after the Givens rotations.

    ``S <- G^T S G`` and ``mu <- G^T mu`` with the rotations of
    :func:`_delete_cholesky`: in the rotated coordinates BV ``i`` is the *last* in
    Cholesky order and no other BV depends on coordinate ``i``. The KL-optimal
    downdates (TR eq. 3.23-3.25), written in these coordinates, are conditioning
    on ``u_i = 0``: with ``sig = (G^T S G)[:, i]`` and ``vs = sig[i]``::

        mu <- mu_rest - sig mu_i / vs,    S <- S_rest - sig sig^T / vs

    Two passes over ``S``: the row rotations ``A = G^T S`` (rows ``>= i``), then,
    row by row, the column rotations ``A G`` of the *lower* triangle only (a carry
    recurrence along the row), fused with the conditioning and the compaction of
    row/column ``i``; the upper triangle is then mirrored, so ``S`` stays exactly
    symmetric. ``sig`` [cap] is scratch.
    """
    for j in range(i + 1, m):
        t = mu[j]
        mu[j] = cth[j] * t + sth[j] * mu[i]
        mu[i] = cth[j] * mu[i] - sth[j] * t
    _rotate_rows(S, i, m, m, cth, sth)  # A = G^T S: rows >= i change
    # sig = row i of A G: columns < i as they are, columns > i by the carry recurrence.
    for b in range(i):
        sig[b] = S[i, b]
    x = S[i, i]
    for j in range(i + 1, m):
        t = S[i, j]
        sig[j] = cth[j] * t + sth[j] * x
        x = cth[j] * x - sth[j] * t
    sig[i] = x
    vs = x
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
    # Lower triangle of the result, compacted in place (row a > i moves to a - 1 after
    # row a - 1 has been consumed).
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
        x = S[a, i]
        for j in range(i + 1, a + 1):  # columns > a are not needed (upper triangle)
            t = S[a, j]
            S[a - 1, j - 1] = (cth[j] * t + sth[j] * x) - sa * sig[j]
            x = cth[j] * x - sth[j] * t
    _mirror_lower(S, m - 1)


@njit(cache=True)
def _mirror_lower(S: FloatArray, n: int) -> None:  # pragma: no cover - compiled
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
def online_step(  # pragma: no cover - compiled
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
    """One Csató–Opper step for the observation ``(x, y)``, in place.

    State (leading ``m`` block of each buffer; ``cap = max_bv + 1``):
    ``BV`` [cap, d]; ``R`` [cap, cap] upper with ``K_BV = R^T R``; the whitened
    posterior ``u ~ N(mu, S)`` with ``f_BV = R^T u`` (``mu`` [cap], ``S`` [cap, cap],
    ``0 <= S <= I``); and, for the deletion scores only, ``alpha = R^{-1} mu`` [cap]
    and ``mdiag = diag(Q + C) = diag(R^{-1} S R^{-T})`` [cap], both following the
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
        if gamma < -_VAR_ROUNDING * kxx:
            # Indefinite kernel: k is not a covariance column of K_BV and |v| can be
            # huge (seen: 1e3), so the update would amplify rounding until S is no
            # longer PSD and blows up. Repair: scale v onto |v|^2 = k(x, x) (gamma = 0),
            # the largest projection a PD kernel allows; the update stays exact Bayes.
            counters[_NOVCLIP] += 1
            sc = np.sqrt(kxx / vv)
            for a in range(m):
                v[a] *= sc
        gamma = 0.0
    for a in range(m):
        g[a] = _dot_row(S, a, v, 0, m)  # g = S v [m]
    mean = _dot(mu, v, 0, m)
    vsv = _dot(v, g, 0, m)
    if vsv < 0.0:
        vsv = 0.0
    s2 = gamma + vsv  # var of the latent f(x) = k(x,x) + k^T C k
    if s2 < -_VAR_ROUNDING * kxx:
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
            ga = g[a]
            sr = S[a, :m]
            for b in range(m):
                sr[b] += (ga * g[b]) * re
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
        S[a, m] = 0.0
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
        ga = g[a]
        sr = S[a, :m1]
        for b in range(m1):
            sr[b] += (ga * g[b]) * r
    if m1 <= max_bv:
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
    for a in range(m1):
        e[a] = _dot_row(S, a, z, i, m1)  # e = S z
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
    _delete_whitened(S, mu, T[0], i, m1, cth, sth, counters)
    for a in range(i + 1, m1):
        BV[a - 1, :] = BV[a, :]
    counters[_DELETED] += 1
    return m, 1, i


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
    """Stream rows ``start, start+1, ...`` of ``X`` [N, d], ``y`` [N] through :func:`online_step`.

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
        m, added, deleted = online_step(
            kbuf, variance, y[t], X[t], noise, tol, floor, noise_floor, max_bv,
            BV, mu, S, R, alpha, mdiag, m, work, T, counters,
        )  # fmt: skip
        t += 1
        changes += added + (1 if deleted >= 0 else 0)
        if changes >= stop_changes:
            break
    return t, m, changes
