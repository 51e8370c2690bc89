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
Neural Computation 14 (2002) -- ``CO02 eq. N`` -- and the corrected Aston technical
report NCRG/2001/014 -- ``TR eq. 3.N`` (section 3: eqs. 3.9-3.13 for the update,
3.17-3.19 for the projection, 3.23-3.26 for the deletion); ``JC12 eq. N`` is the
paper geoq reproduces. ``docs/equations.md`` maps each equation to its function.

Sign convention (see :mod:`geoq.gp.sparse_online`): ``mean = k^T alpha``,
``var = k(x, x) + k^T C k``; ``C`` is negative (semi-)definite for a PD kernel.

Symmetry of ``S`` (hence ``C``) is exact: only one triangle is computed. The
dense building blocks (solves, symv, rank-one) are in :mod:`geoq.gp._nb_linalg`,
the deletion and the exact score refresh in :mod:`geoq.gp._nb_delete`.

:func:`se_stream` is the whole-stream loop for the squared-exponential kernel:
it computes ``k_x`` inside numba (per-dimension length-scales, optional
periods) and calls the step for each row until the basis set has
changed ``stop_changes`` times (the caller then refreshes ``diag(Q)``).
"""

from __future__ import annotations

from typing import TypeAlias

import numpy as np
from numba import njit

from geoq._geometry import wrap
from geoq._typing import FloatArray, IntArray
from geoq.gp._nb_delete import delete_cholesky, delete_whitened
from geoq.gp._nb_linalg import (
    backward,
    backward2,
    dot,
    forward,
    mirror_lower,
    rank_one_lower,
    symv_lower,
    symv_row,
)
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
)
from geoq.gp.numerics import VAR_ROUNDING

__all__ = [
    "N_WORK",
    "GPBuffers",
    "SEParameters",
    "Scratch",
    "StepSettings",
    "online_step_lower",
    "se_kernel_vector",
    "se_stream",
]

#: Number of ``[cap]`` work vectors :func:`_step` needs.
N_WORK = 8

#: The sparse GP's state buffers ``(BV, mu, S, R, alpha, mdiag)`` (see :func:`_step`).
GPBuffers: TypeAlias = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]
#: Scratch of a step ``(work, T, counters)``.
Scratch: TypeAlias = tuple[FloatArray, FloatArray, IntArray]
#: A step's settings ``(noise, tol, floor, noise_floor, max_bv)``.
StepSettings: TypeAlias = tuple[float, float, float, float, int]
#: The squared exponential of :func:`se_kernel_vector`: ``(inv_ls [d], period [d], variance)``.
SEParameters: TypeAlias = tuple[FloatArray, FloatArray, float]


@njit(cache=True)
def _step(  # pragma: no cover - compiled
    k: FloatArray,
    kxx: float,
    y: float,
    x: FloatArray,
    settings: StepSettings,
    state: GPBuffers,
    m: int,
    scratch: Scratch,
) -> tuple[int, int, int]:
    """One Csató–Opper step for ``(x, y)``, in place, on the lower triangle of ``S``.

    ``state`` = ``(BV, mu, S, R, alpha, mdiag)`` (:data:`GPBuffers`, the leading ``m``
    block of each buffer; ``cap = max_bv + 1``): ``BV`` [cap, d]; ``R`` [cap, cap]
    upper with ``K_BV = R^T R``; the whitened posterior ``u ~ N(mu, S)`` with
    ``f_BV = R^T u`` (``mu`` [cap], ``S`` [cap, cap], ``0 <= S <= I``; only
    ``S[a, b]``, ``b <= a``, is read or written); and, for the deletion scores only,
    ``alpha = R^{-1} mu`` [cap] and ``mdiag = diag(Q + C) = diag(R^{-1} S R^{-T})``
    [cap], both following the rank-one updates of Csató–Opper in O(m).
    ``scratch`` = ``(work, T, counters)`` (:data:`Scratch`): ``work`` [N_WORK, cap] and
    ``T`` [cap, cap] are scratch, ``counters`` int64 [len(COUNTER_NAMES)] the counts.

    Parameters
    ----------
    k : [cap] ``k(BV_j, x)`` in its first ``m`` entries.  kxx : ``k(x, x)``.
    settings : ``(noise, tol, floor, noise_floor, max_bv)`` (:data:`StepSettings`):
        ``noise`` the observation-noise variance ``sigma0^2``; novelty is accepted iff
        ``gamma > 0``, ``gamma >= tol * kxx`` and ``gamma >= floor * kxx``; the noise
        variance used is ``max(noise, noise_floor * kxx)`` (counted when it bites: with
        a noise far below the rounding level of ``S`` the rank-one downdates would
        amplify rounding errors without bound); ``max_bv`` the budget.

    Returns
    -------
    (m_new, added, deleted) : new basis size; 1 if ``x`` was appended to the basis
    set, else 0; the index of the deleted basis vector (after the append) or -1.
    """
    noise, tol, floor, noise_floor, max_bv = settings
    BV, mu, S, R, alpha, mdiag = state
    work, T, counters = scratch
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

    # Predictive moments (CO02 eq. 6 / TR eq. 3.5) in whitened form: v = L^{-1} k,
    # mean = v^T mu, var = gamma + v^T S v with the novelty (TR eq. 3.16)
    # gamma = k(x,x) - k^T Q k = k(x,x) - |v|^2, the Cholesky pivot x would get.
    forward(R, k, 0, m, v)
    vv = dot(v, v, 0, m)
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
    symv_lower(S, v, 0, m, g)  # g = S v [m]
    mean = dot(mu, v, 0, m)
    vsv = dot(v, g, 0, m)
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
        backward(R, g, m, s)
        for a in range(m):
            mu[a] += qe * g[a]
            alpha[a] += qe * s[a]
            mdiag[a] += (s[a] * s[a]) * re
            rank_one_lower(S, g, re, a)
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
    backward2(R, v, z, m, e, s)  # e_hat = Q k = R^{-1} v; s = C k = R^{-1} (S - I) v
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
            rank_one_lower(S, g, r, a)
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
    # No finite score (no positive diag(Q + C), or alpha_i^2 overflowed: a diverged
    # posterior or huge targets over a tiny noise): delete the newest point, counted.
    # Ranking by log-scores instead was tried: on diverged geodesic posteriors it
    # deleted old BVs and turned the quick reproduction's predictions into NaN.
    if best < 0:
        counters[_SCORECLIP] += 1
        best = m
    i = best
    for a in range(m1):
        w[a] = 0.0
    w[i] = 1.0
    forward(R, w, i, m1, z)  # z = R^{-T} e_i
    # One pass over the lower triangle: the rank-one update of the addition, and
    # e = S z with the updated rows (z is zero before i).
    for a in range(m1):
        e[a] = 0.0
    for a in range(m1):
        rank_one_lower(S, g, r, a)
        if a >= i:
            za = z[a]
            acc = symv_row(S[a, i:a], z[i:a], za, e[i:a])
            sa = S[a, :i]
            ea = e[:i]
            for b in range(i):
                ea[b] += sa[b] * za
            e[a] += acc + S[a, a] * za
    backward(R, e, m1, w)  # w = column i of Q + C
    wi = w[i]
    f = alpha[i] / wi if wi > 0.0 else 0.0
    iw = 1.0 / wi if wi > 0.0 else 0.0
    for a in range(m1):
        if a == i:
            continue
        a2 = a if a < i else a - 1
        alpha[a2] = alpha[a] - f * w[a]
        mdiag[a2] = mdiag[a] - (w[a] * w[a]) * iw
    delete_cholesky(R, i, m1, z, cth, sth)
    delete_whitened(S, mu, T[0], T[1], i, m1, cth, sth, counters)
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
    settings: StepSettings,
    state: GPBuffers,
    m: int,
    scratch: Scratch,
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
    return _step(k, kxx, y, x, settings, state, m, scratch)


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
            diff = wrap(x[c] - BV[j, c], period[c])
            diff *= inv_ls[c]
            r2 += diff * diff
        out[j] = variance * np.exp(-0.5 * r2)


@njit(cache=True)
def se_stream(  # pragma: no cover - compiled
    X: FloatArray,
    y: FloatArray,
    start: int,
    se: SEParameters,
    settings: StepSettings,
    state: GPBuffers,
    m: int,
    kbuf: FloatArray,
    scratch: Scratch,
    stop_changes: int,
) -> tuple[int, int, int]:
    """Stream rows ``start, start+1, ...`` of ``X`` [N, d], ``y`` [N] through :func:`_step`,
    ``k_x`` from the squared exponential ``se = (inv_ls, period, variance)``.

    Stops after the row at which the basis set has changed ``stop_changes``
    times (an addition or a deletion each count one), or at the end.

    Returns
    -------
    (next_row, m, changes) : the first unprocessed row, the basis size, and the
    number of basis-set changes made.
    """
    inv_ls, period, variance = se
    BV, S = state[0], state[2]
    changes = 0
    n = X.shape[0]
    t = start
    while t < n:
        se_kernel_vector(X[t], BV, m, inv_ls, period, variance, kbuf)
        m, added, deleted = _step(kbuf, variance, y[t], X[t], settings, state, m, scratch)
        t += 1
        changes += added + (1 if deleted >= 0 else 0)
        if changes >= stop_changes:
            break
    mirror_lower(S, m)  # the steps keep the lower triangle only
    return t, m, changes
