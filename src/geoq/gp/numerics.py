"""The one numerics policy of geoq: jitter, Cholesky, eigenvalue repair.

Every place that factorises a kernel matrix goes through :func:`safe_cholesky`
(GPyTorch's ``psd_safe_cholesky`` policy): try a plain Cholesky; on failure add
``jitter * mean(diag)`` to the diagonal, multiplying the jitter by ``growth`` at
each try and emitting a :class:`NumericalWarning` naming the jitter used; after
``max_tries`` raise :class:`NotPSDError` naming the jitter reached and what to
do. The constants live in one frozen :class:`NumericsConfig`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from geoq._typing import FloatArray

__all__ = [
    "CONFIG",
    "VAR_ROUNDING",
    "NotPSDError",
    "NumericalWarning",
    "NumericsConfig",
    "cholesky_cannot_succeed",
    "clip_eigenvalues",
    "is_positive_definite",
    "project_whitened_covariance",
    "robust_cholesky",
    "safe_cholesky",
]


class NumericalWarning(RuntimeWarning):
    """A numerical repair happened (jitter added, eigenvalues clipped, variance clipped)."""


class NotPSDError(np.linalg.LinAlgError):
    """A matrix that must be positive definite is not, even after the maximal jitter."""


@dataclass(frozen=True)
class NumericsConfig:
    """Numerical constants shared by every GP in geoq."""

    jitter: float = 1e-10
    """First jitter tried by :func:`safe_cholesky`, relative to the mean diagonal."""
    growth: float = 10.0
    """Factor by which the jitter grows at each failed try."""
    max_tries: int = 7
    """Number of jittered tries before :class:`NotPSDError` (1e-10 ... 1e-4 by default)."""
    novelty_floor: float = 1e-10
    """A point whose novelty ``gamma < novelty_floor * k(x, x)`` never becomes a basis
    vector, whatever ``tol`` is: adding it would make ``K_BV`` numerically singular."""
    noise_floor: float = 1e-12
    """Smallest noise variance the online update uses, relative to ``k(x, x)``: a noise
    below the rounding level of the posterior would let the rank-one downdates amplify
    rounding errors without bound (seen with noise 1e-20 and contradictory duplicates)."""
    eig_floor: float = 1e-10
    """Eigenvalue clipping floor, relative to the largest eigenvalue."""


#: The configuration used unless a caller passes its own.
CONFIG = NumericsConfig()

#: A negative (predictive or whitened) variance above ``-VAR_ROUNDING * k(x, x)`` is
#: rounding noise: it is clipped to 0 silently; below that it is clipped *and* counted.
#: A module constant, not a :class:`NumericsConfig` field: the compiled step reads it.
VAR_ROUNDING = 1e-9


def safe_cholesky(
    K: FloatArray,
    *,
    config: NumericsConfig = CONFIG,
    what: str = "kernel matrix",
    spectrum: FloatArray | None = None,
) -> tuple[FloatArray, float]:
    """Lower Cholesky factor of a symmetric matrix, with escalating jitter.

    Parameters
    ----------
    K : [n, n] symmetric matrix.
    spectrum : [n] the eigenvalues of ``K`` (exactly symmetric), if the caller has them:
        a try that cannot succeed (:func:`cholesky_cannot_succeed`) is skipped. The
        result is the same, without the cost of the failing factorisations.

    Returns
    -------
    L : [n, n] lower triangular with ``L @ L.T == K + jitter * I``.
    jitter : the absolute jitter added to the diagonal (0.0 if none was needed).
    """
    K = np.asarray(K, dtype=np.float64)
    if K.ndim != 2 or K.shape[0] != K.shape[1]:
        raise ValueError(f"{what} has shape {K.shape}; expected a square matrix")
    if K.shape[0] == 0:
        return np.zeros((0, 0)), 0.0
    if not np.all(np.isfinite(K)):
        raise NotPSDError(f"{what} contains NaN or inf; check the kernel hyper-parameters")

    def hopeless(shift: float) -> bool:
        return spectrum is not None and cholesky_cannot_succeed(spectrum, K, shift)

    if not hopeless(0.0):
        try:
            return scipy.linalg.cholesky(K, lower=True, check_finite=False), 0.0
        except np.linalg.LinAlgError:
            pass
    scale = float(np.mean(np.abs(np.diag(K)))) or 1.0
    jitter = config.jitter * scale
    for _ in range(config.max_tries):
        if hopeless(jitter):
            jitter *= config.growth
            continue
        try:
            L = scipy.linalg.cholesky(
                K + jitter * np.eye(K.shape[0]), lower=True, check_finite=False
            )
        except np.linalg.LinAlgError:
            jitter *= config.growth
            continue
        warnings.warn(
            f"{what} was not positive definite; added jitter {jitter:.3g} to its diagonal",
            NumericalWarning,
            stacklevel=2,
        )
        return L, jitter
    raise NotPSDError(
        f"{what} ({K.shape[0]}x{K.shape[0]}) is not positive definite even with jitter "
        f"{jitter / config.growth:.3g} on the diagonal. Increase the observation noise, "
        "shorten the basis set (smaller max_bv or larger tol), or use a positive-definite "
        "kernel."
    )


#: LAPACK driver of every full symmetric eigendecomposition here: divide and conquer
#: (``syevd``), 1.4x faster than scipy's default (``syevr``) at ``m = 200``
#: (``docs/design-notes.md``); both are backward stable.
_EIGH_DRIVER = "evd"


def _eigh(A: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Eigenvalues ``[n]`` (ascending) and eigenvectors ``[n, n]`` of the symmetric ``A``."""
    return scipy.linalg.eigh(A, driver=_EIGH_DRIVER, check_finite=False)


#: Safety factor of :func:`cholesky_cannot_succeed` over the rounding-error bounds.
_CERTAIN = 100.0


def cholesky_cannot_succeed(spectrum: FloatArray, K: FloatArray, shift: float) -> bool:
    """Whether the Cholesky factorisation of ``K + shift I`` [n, n] certainly fails, judged
    from the computed eigenvalues ``spectrum`` [n] of the symmetric ``K``.

    A factorisation that succeeds returns ``L`` with ``L L^T = A + E`` (``A = K + shift I``),
    ``|E| <= gamma_{n+1} |L| |L^T|`` (Higham, *Accuracy and Stability*, Thm. 10.3), so
    ``lambda_min(A) >= -gamma_{n+1} tr(L L^T)``; a backward-stable eigensolver's values are
    within ``O(n u ||A||)`` of the true ones. Both bounds together, times :data:`_CERTAIN`,
    are the margin: ``True`` only if the smallest eigenvalue of ``A`` lies below minus
    that margin, where no factorisation can succeed (a skipped try changes nothing).
    """
    n = K.shape[0]
    u = np.finfo(np.float64).eps
    w_min, w_abs = float(np.min(spectrum)), float(np.max(np.abs(spectrum)))
    size = abs(float(np.trace(K))) + n * (w_abs + 2.0 * abs(shift))
    return w_min + shift < -_CERTAIN * (n + 1) * u * size


def clip_eigenvalues(
    K: FloatArray,
    *,
    config: NumericsConfig = CONFIG,
    eigh: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, int]:
    """Nearest (in Frobenius norm) positive-definite matrix by eigenvalue clipping.

    Eigenvalues below ``config.eig_floor * max(|eigenvalue|)`` are raised to
    that floor. Used to repair indefinite Gram matrices of kernels that are not
    positive definite (e.g. a Gaussian of a graph distance). ``eigh``: the
    eigendecomposition ``(w, V)`` of ``0.5 (K + K^T)``, if the caller has it.

    Returns
    -------
    K_pd : [n, n] symmetric positive-definite matrix.
    n_clipped : number of eigenvalues that were raised.
    """
    K = np.asarray(K, dtype=np.float64)
    sym = 0.5 * (K + K.T)
    if sym.shape[0] == 0:
        return sym, 0
    w, V = _eigh(sym) if eigh is None else eigh
    floor = config.eig_floor * max(float(np.max(np.abs(w))), np.finfo(np.float64).tiny)
    low = w < floor
    n_clipped = int(np.count_nonzero(low))
    if n_clipped == 0:
        return sym, 0
    w = np.where(low, floor, w)
    K_pd = (V * w) @ V.T
    return 0.5 * (K_pd + K_pd.T), n_clipped


def is_positive_definite(A: FloatArray, shift: float) -> bool:
    """Whether ``A + shift I`` [m, m] (symmetric) has a Cholesky factor."""
    try:
        scipy.linalg.cholesky(A + shift * np.eye(A.shape[0]), check_finite=False)
    except np.linalg.LinAlgError:
        return False
    return True


def robust_cholesky(
    K: FloatArray, what: str, config: NumericsConfig = CONFIG
) -> tuple[FloatArray, int, int]:
    """Cholesky factor of a symmetric matrix under the single jitter policy, never raising.

    Tries :func:`safe_cholesky` (silencing its per-call warning: the caller counts
    and reports repairs); if the matrix is not PD even with the maximal jitter,
    clips its eigenvalues (:func:`clip_eigenvalues`) and factorises the repaired
    matrix. When the plain factorisation of an exactly symmetric ``K`` fails, its
    eigendecomposition (which the clipping needs) is made first, and the jittered
    tries it proves hopeless are skipped: an indefinite Gram (the geodesic kernel's)
    is clipped without ``max_tries`` failing factorisations, with the same result.

    Returns
    -------
    L : [n, n] lower triangular.
    jitter_events : 1 if jitter was added, else 0.
    eig_clips : number of eigenvalues clipped.
    """
    K = np.asarray(K, dtype=np.float64)
    eigh = None
    if K.ndim == 2 and K.size and np.all(np.isfinite(K)) and np.array_equal(K, K.T):
        try:
            return scipy.linalg.cholesky(K, lower=True, check_finite=False), 0, 0
        except np.linalg.LinAlgError:  # safe_cholesky's first try: not PD
            eigh = _eigh(0.5 * (K + K.T))  # clip's input
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        try:
            L, jitter = safe_cholesky(
                K, config=config, what=what, spectrum=None if eigh is None else eigh[0]
            )
            return L, int(jitter > 0.0), 0
        except NotPSDError:
            K_pd, n_clipped = clip_eigenvalues(K, config=config, eigh=eigh)
            L, jitter = safe_cholesky(K_pd, config=config, what=what)
            return L, int(jitter > 0.0), n_clipped


def project_whitened_covariance(
    S: FloatArray, *, many_above_one: bool = False
) -> tuple[FloatArray, int]:
    """``S`` [m, m] with its spectrum projected onto ``[0, 1]``, and the number of
    eigenvalues projected.

    Any GP posterior conditioned on data satisfies ``0 <= Sigma_BV <= K_BV``, i.e.
    ``0 <= S <= I`` in whitened coordinates. Re-anchoring a sparse GP keeps the old
    posterior of ``f_BV`` under the *new* prior, and when a graph kernel's new ``K_BV``
    is nearly singular that posterior is far wider than the prior in some directions
    (``docs/design-notes.md``). The projection is the nearest valid ``S`` in the
    Frobenius norm; eigenvalues within ``VAR_ROUNDING`` of ``[0, 1]`` are left alone.

    Cholesky checks first (far cheaper than an eigendecomposition). When only ``S <= I``
    fails (a re-anchoring's usual case) only the eigenpairs above 1 are computed
    (:func:`_clip_above_one`: one tridiagonalisation, a few eigenvectors); the full
    eigendecomposition is the fallback, and the first choice with ``many_above_one``
    (the caller expects many eigenvalues above 1: with more than about ``m / 8`` of them
    the partial eigendecomposition costs 2-4x the full one, ``docs/design-notes.md``).
    Both give the same projection to rounding.
    """
    S = 0.5 * (S + S.T)
    # S <= I first: after a graph kernel's re-anchoring that is the bound S breaks.
    below_one = is_positive_definite(-S, 1.0 + VAR_ROUNDING)
    above_zero = is_positive_definite(S, VAR_ROUNDING)
    if below_one and above_zero:
        return S, 0
    if above_zero and not many_above_one:
        clipped = _clip_above_one(S)
        if clipped is not None:
            return clipped
    w, U = _eigh(S)
    bad = (w < -VAR_ROUNDING) | (w > 1.0 + VAR_ROUNDING)
    if not np.any(bad):
        return S, 0
    S = (U * np.clip(w, 0.0, 1.0)) @ U.T
    return 0.5 * (S + S.T), int(np.count_nonzero(bad))


#: :func:`_clip_above_one` checks its result with two Cholesky factorisations when its
#: rounding bound ``m * eps * max(eigenvalue)`` may exceed this fraction of ``VAR_ROUNDING``.
_CLIP_CHECK_FRACTION = 0.1


def _clip_above_one(S: FloatArray) -> tuple[FloatArray, int] | None:
    """``S - U (w - 1) U^T`` [m, m] for the eigenpairs ``(w, U)`` of the symmetric ``S``
    with ``w > 1``, when ``S >= -VAR_ROUNDING`` is known: the Frobenius projection onto
    ``0 <= S <= I`` up to rounding, at a fraction of a full eigendecomposition.

    The subtraction's error is of order ``m eps max(w)``: a result that bound does not
    put far inside ``[-VAR_ROUNDING, 1 + VAR_ROUNDING]`` is checked (two Cholesky
    factorisations) and ``None`` is returned when the check fails (the caller falls
    back to the full eigendecomposition). ``S`` itself when no eigenvalue lies above
    ``1 + VAR_ROUNDING`` (it failed its Cholesky check by rounding only).
    """
    w, U = scipy.linalg.eigh(S, subset_by_value=(1.0, np.inf), check_finite=False)
    n_bad = int(np.count_nonzero(w > 1.0 + VAR_ROUNDING))
    if n_bad == 0:
        return S, 0
    out = S - (U * (w - 1.0)) @ U.T
    out = 0.5 * (out + out.T)
    bound = S.shape[0] * np.finfo(np.float64).eps * float(np.max(w))
    if bound > _CLIP_CHECK_FRACTION * VAR_ROUNDING and not (
        is_positive_definite(-out, 1.0 + VAR_ROUNDING) and is_positive_definite(out, VAR_ROUNDING)
    ):
        return None
    return out, n_bad
