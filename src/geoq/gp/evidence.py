"""Type-II maximum likelihood (evidence maximisation) of squared-exponential hyper-parameters.

The paper (§3) sets the kernel's hyper-parameters by maximising the evidence of
the exact GP; we do the same on a random subsample of at most ``max_points``
points. With ``K_y = variance * K_l + noise * I`` and ``alpha = K_y^{-1} y``
(Rasmussen & Williams 2006, eqs. 5.8 and 5.9)::

    log p(y | X, theta) = -y^T alpha / 2 - log|K_y| / 2 - N log(2 pi) / 2
    d log p / d theta_j = tr((alpha alpha^T - K_y^{-1}) dK_y/dtheta_j) / 2

The parameters are optimised in log space, ``theta = log(lengthscale_1..d,
variance, noise)``, by L-BFGS-B with the analytic gradient above, within
bounds that keep ``K_y`` well conditioned.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import as_float_matrix, as_float_vector, check_positive
from geoq.gp.numerics import CONFIG, NumericsConfig, safe_cholesky
from geoq.kernels.base import Kernel
from geoq.kernels.stationary import SquaredExponential

__all__ = ["EvidenceFit", "fit_squared_exponential", "log_marginal_likelihood"]

#: Bounds of the log-parameters (length-scales, variance, noise).
_LOG_LENGTHSCALE_BOUNDS = (np.log(1e-3), np.log(1e3))
_LOG_VARIANCE_BOUNDS = (np.log(1e-4), np.log(1e4))
_LOG_NOISE_BOUNDS = (np.log(1e-6), np.log(1e2))


@dataclass(frozen=True)
class EvidenceFit:
    """Result of :func:`fit_squared_exponential`.

    Attributes
    ----------
    kernel : the fitted :class:`SquaredExponential` (``.lengthscale``, ``.variance``).
    noise : fitted observation-noise variance ``sigma0^2``.
    log_evidence : ``log p(y | X)`` at the optimum, on the ``n_used`` points.
    n_used : number of points the evidence was computed on.
    converged : whether L-BFGS-B reported convergence.
    message : the optimiser's message.
    """

    kernel: SquaredExponential
    noise: float
    log_evidence: float
    n_used: int
    converged: bool
    message: str


def log_marginal_likelihood(
    kernel: Kernel, noise: float, X: ArrayLike, y: ArrayLike, *, config: NumericsConfig = CONFIG
) -> float:
    """``log p(y | X)`` of the exact GP with ``kernel`` and noise variance ``noise`` (eq. 5.8).

    ``X`` is [N, d], ``y`` is [N].
    """
    noise = check_positive(noise, "noise")
    Xa = as_float_matrix(X, "X", kernel.input_dim)
    ya = as_float_vector(y, "y", Xa.shape[0])
    K = kernel(Xa)
    K[np.diag_indices_from(K)] += noise
    L, _ = safe_cholesky(K, config=config, what="K + noise I")
    alpha = scipy.linalg.cho_solve((L, True), ya, check_finite=False)
    n = ya.shape[0]
    return float(-0.5 * ya @ alpha - np.sum(np.log(np.diag(L))) - 0.5 * n * np.log(2.0 * np.pi))


def _negative_evidence_and_gradient(
    theta: FloatArray, X: FloatArray, y: FloatArray, ard: bool
) -> tuple[float, FloatArray]:
    """``-log p(y | X, theta)`` and its gradient with respect to ``theta`` (log space)."""
    d = X.shape[1]
    n_ls = d if ard else 1
    lengthscale = np.exp(theta[:n_ls])
    variance, noise = np.exp(theta[n_ls]), np.exp(theta[n_ls + 1])
    Z = X / lengthscale  # [N, d]
    sq = np.sum(Z * Z, axis=1)
    r2 = np.maximum(sq[:, None] + sq[None, :] - 2.0 * Z @ Z.T, 0.0)
    K_l = np.exp(-0.5 * r2)
    K_y = variance * K_l
    K_y[np.diag_indices_from(K_y)] += noise
    try:
        L = scipy.linalg.cholesky(K_y, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return np.inf, np.zeros_like(theta)
    alpha = scipy.linalg.cho_solve((L, True), y, check_finite=False)
    n = y.shape[0]
    log_ev = -0.5 * y @ alpha - np.sum(np.log(np.diag(L))) - 0.5 * n * np.log(2.0 * np.pi)
    K_inv = scipy.linalg.cho_solve((L, True), np.eye(n), check_finite=False)
    W = np.outer(alpha, alpha) - K_inv  # [N, N]; d log p = tr(W dK) / 2
    grad = np.empty_like(theta)
    VK = variance * K_l
    if ard:
        for k in range(d):
            diff2 = (Z[:, k][:, None] - Z[:, k][None, :]) ** 2
            grad[k] = 0.5 * np.sum(W * VK * diff2)
    else:
        grad[0] = 0.5 * np.sum(W * VK * r2)
    grad[n_ls] = 0.5 * np.sum(W * VK)
    grad[n_ls + 1] = 0.5 * noise * np.trace(W)
    return float(-log_ev), -grad


def fit_squared_exponential(
    X: ArrayLike,
    y: ArrayLike,
    *,
    lengthscale0: float | ArrayLike = 1.0,
    variance0: float | None = None,
    noise0: float = 0.1,
    ard: bool = True,
    max_points: int = 500,
    rng: np.random.Generator | None = None,
) -> EvidenceFit:
    """Maximise the exact-GP evidence over SE length-scale(s), variance and noise.

    Parameters
    ----------
    X : [N, d] inputs; y : [N] targets.
    lengthscale0, variance0, noise0 : starting point (``variance0`` defaults to ``var(y)``).
    ard : one length-scale per input dimension (True) or a shared one.
    max_points : the evidence is computed on a random subsample of this many points
        (drawn with ``rng``) when ``N`` is larger; the cost is ``O(max_points^3)``.
    rng : generator for the subsample; required when ``N > max_points``.
    """
    Xa = as_float_matrix(X, "X")
    ya = as_float_vector(y, "y", Xa.shape[0])
    if Xa.shape[0] < 2:
        raise ValueError(f"evidence maximisation needs at least 2 points, got {Xa.shape[0]}")
    if int(max_points) < 2:
        raise ValueError(f"max_points must be >= 2, got {max_points!r}")
    noise0 = check_positive(noise0, "noise0")
    if Xa.shape[0] > max_points:
        if rng is None:
            raise ValueError(
                f"{Xa.shape[0]} points exceed max_points={max_points}: pass rng= to subsample"
            )
        idx = np.sort(rng.choice(Xa.shape[0], size=int(max_points), replace=False))
        Xa, ya = Xa[idx], ya[idx]
    d = Xa.shape[1]
    n_ls = d if ard else 1
    ls0 = np.broadcast_to(np.asarray(lengthscale0, dtype=np.float64), (n_ls,))
    if not np.all(np.isfinite(ls0)) or np.any(ls0 <= 0):
        raise ValueError(f"lengthscale0 must be finite and > 0, got {lengthscale0!r}")
    var0 = float(np.var(ya)) if variance0 is None else check_positive(variance0, "variance0")
    var0 = max(var0, 1e-3)
    theta0 = np.concatenate([np.log(ls0), [np.log(var0), np.log(noise0)]])
    bounds = [_LOG_LENGTHSCALE_BOUNDS] * n_ls + [_LOG_VARIANCE_BOUNDS, _LOG_NOISE_BOUNDS]
    theta0 = np.clip(theta0, [b[0] for b in bounds], [b[1] for b in bounds])
    res = scipy.optimize.minimize(
        _negative_evidence_and_gradient,
        theta0,
        args=(Xa, ya, ard),
        jac=True,
        method="L-BFGS-B",
        bounds=bounds,
    )
    theta = res.x
    lengthscale = np.exp(theta[:n_ls])
    kernel = SquaredExponential(
        lengthscale=lengthscale if ard else float(lengthscale[0]),
        variance=float(np.exp(theta[n_ls])),
    )
    noise = float(np.exp(theta[n_ls + 1]))
    return EvidenceFit(
        kernel=kernel,
        noise=noise,
        log_evidence=log_marginal_likelihood(kernel, noise, Xa, ya),
        n_used=int(Xa.shape[0]),
        converged=bool(res.success),
        message=str(res.message),
    )
