"""Prediction from the whitened state of :class:`~geoq.gp.SparseOnlineGP`.

The state is the upper Cholesky factor ``R`` [m, m] of ``K_BV`` and the whitened
posterior ``u ~ N(mu, S)`` with ``f_BV = R^T u``. With ``V = R^{-T} K_BX`` [m, N]::

    mean = V^T mu
    var  = (diag K_XX - |V|^2) + diag(V^T S V)

(prior residual + whitened posterior term, both non-negative for a PD kernel),
clipped at 0. :func:`predict_chunked` computes it by a triangular solve per chunk
of test points; :func:`predict_factored` by one GEMM per chunk after an O(m^3)
set-up, for many test points per BV. Repairs are counted in the GP's
:class:`~geoq.gp.diagnostics.Counters`.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy.linalg import lapack

from geoq._typing import FloatArray
from geoq.gp.diagnostics import Counters
from geoq.gp.numerics import VAR_ROUNDING
from geoq.kernels.base import Kernel

__all__ = [
    "FACTOR_ROUTE_MIN",
    "PREDICT_CHUNK",
    "predict_chunked",
    "predict_factored",
    "rescale_features",
    "solve_upper_transposed",
]

#: Test points per kernel evaluation (bounds the [chunk, m] kernel matrix).
PREDICT_CHUNK = 4096
#: ``predict`` on at least this many points per BV uses the factored route (one GEMM).
FACTOR_ROUTE_MIN = 8


def predict_chunked(
    kernel: Kernel,
    X: FloatArray,
    R: FloatArray,
    S: FloatArray,
    mu: FloatArray,
    bv: FloatArray,
    mean: FloatArray,
    std: FloatArray | None,
    repaired: bool,
    counts: Counters,
) -> None:
    """Mean into ``mean`` [N] (and std into ``std`` [N]) by a triangular solve per chunk.

    ``repaired``: the online updates scaled features onto ``|v|^2 = k(x, x)``
    (negative novelty), so test points get the same repair (:func:`rescale_features`).
    """
    for lo in range(0, X.shape[0], PREDICT_CHUNK):
        Xc = X[lo : lo + PREDICT_CHUNK]
        K = np.asarray(kernel.to_basis(Xc, bv), dtype=np.float64)  # [n_c, m]
        V = solve_upper_transposed(R, K.T)  # [m, n_c]
        prior = np.asarray(kernel.diag(Xc), dtype=np.float64)  # [n_c]
        vv = np.einsum("ij,ij->j", V, V)  # [n_c]
        if repaired:
            vv = rescale_features(V, vv, prior, counts)
        mean[lo : lo + len(Xc)] = V.T @ mu
        if std is not None:
            var = (prior - vv) + np.einsum("ij,ij->j", S @ V, V)
            _store_std(var, prior, std[lo : lo + len(Xc)], counts)


def solve_upper_transposed(R: FloatArray, B: FloatArray) -> FloatArray:
    """``R^{-T} B`` for an upper triangular ``R`` [m, m] and ``B`` [m, n]: LAPACK's
    ``dtrtrs`` on the lower triangular ``R^T``, the bits of
    ``scipy.linalg.solve_triangular(R, B, trans="T")`` without its wrapper (a third of
    the solve's time at an agent step's 21 x 200). ``R`` may be a strided view."""
    V, info = lapack.dtrtrs(R.T, B, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError(
            f"the factor of K_BV is singular (zero pivot {info}): refit or rebuild the GP"
        )
    return np.asarray(V)


def rescale_features(
    V: FloatArray, vv: FloatArray, prior: FloatArray, counts: Counters
) -> FloatArray:
    """The update's negative-novelty repair applied to test points, in place.

    An indefinite kernel can give ``|v|^2 > k(x, x)`` (negative novelty); the
    online updates then scaled ``v`` onto ``|v|^2 = k(x, x)``, so the posterior
    they built is that of the repaired feature map, and predictions use the same
    map (unrepaired, a test point with ``|v|`` ~ 1e3 turned a bounded posterior
    into predictions of ~1e4-1e8: Q-function MSE 3650 vs 37 repaired, median over
    seeds). After :meth:`~geoq.gp.SparseOnlineGP.refit` the posterior is the DTC one
    of the raw features and they are used unchanged. Columns of ``V`` [m, n] are
    rescaled where ``vv`` [n] exceeds ``prior`` [n]; returns the new ``|v|^2`` [n].
    """
    over = vv > prior * (1.0 + VAR_ROUNDING)
    if not np.any(over):
        return vv
    counts.predict_rescaled += int(np.count_nonzero(over))
    V[:, over] *= np.sqrt(prior[over] / vv[over])
    out = vv.copy()
    out[over] = prior[over]
    return out


def _store_std(var: FloatArray, prior: FloatArray, out: FloatArray, counts: Counters) -> None:
    counts.predict_clipped += int(np.count_nonzero(var < -VAR_ROUNDING * prior))
    out[:] = np.sqrt(np.maximum(var, 0.0))


def predict_factored(
    kernel: Kernel,
    X: FloatArray,
    R: FloatArray,
    S: FloatArray,
    mu: FloatArray,
    bv: FloatArray,
    mean: FloatArray,
    std: FloatArray | None,
    counts: Counters,
) -> None:
    """Many test points: one GEMM per chunk instead of a triangular solve and a GEMM.

    ``var = k(x,x) - v^T (I - S) v`` with ``v = R^{-T} k_x``; with the eigen-
    decomposition ``I - S = U diag(lam) U^T`` [m, m] (``lam >= 0`` for a PD kernel)
    and ``G = R^{-1} U sqrt|lam|``: ``var = k(x,x) - sum_j sign(lam_j) (k_x^T G)_j^2``.
    Same quantities as :func:`predict_chunked`, O(m^3) set-up, then ``K G`` only.
    """
    m = R.shape[0]
    Rinv = scipy.linalg.solve_triangular(R, np.eye(m), check_finite=False)  # [m, m]
    alpha = Rinv @ mu  # [m]
    if std is not None:
        W = np.eye(m) - S
        lam, U = scipy.linalg.eigh(0.5 * (W + W.T), check_finite=False)  # [m], [m, m]
        keep = lam != 0.0
        G = Rinv @ (U[:, keep] * np.sqrt(np.abs(lam[keep])))  # [m, m']
        sign = np.sign(lam[keep])  # [m']
    for lo in range(0, X.shape[0], PREDICT_CHUNK):
        Xc = X[lo : lo + PREDICT_CHUNK]
        K = np.asarray(kernel.to_basis(Xc, bv), dtype=np.float64)  # [n_c, m]
        mean[lo : lo + len(Xc)] = K @ alpha
        if std is not None:
            H = K @ G  # [n_c, m']
            prior = np.asarray(kernel.diag(Xc), dtype=np.float64)  # [n_c]
            _store_std(prior - (H * H) @ sign, prior, std[lo : lo + len(Xc)], counts)
