"""The exact (full) GP by Cholesky: the oracle for the sparse online GP.

With ``K = k(X, X)`` [N, N], ``L L^T = K + sigma0^2 I`` (:func:`~geoq.gp.numerics.safe_cholesky`)
and ``alpha = L^{-T} L^{-1} y`` (Rasmussen & Williams 2006, Algorithm 2.1)::

    mean(x*) = k*^T alpha                         # line 4
    var(x*)  = k(x*, x*) - ||L^{-1} k*||^2        # lines 5-6 (latent f, noise excluded)
    log p(y | X) = -y^T alpha / 2 - sum(log diag L) - N log(2 pi) / 2      # line 7

In the sign convention of :mod:`geoq.gp.sparse_online` this is
``alpha = (K + sigma0^2 I)^{-1} y`` and ``C = -(K + sigma0^2 I)^{-1}``.
"""

from __future__ import annotations

from typing import Literal, overload

import numpy as np
import scipy.linalg

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import as_float_matrix, as_float_vector, check_positive
from geoq.gp.numerics import CONFIG, NumericsConfig, safe_cholesky
from geoq.kernels.base import Kernel

__all__ = ["ExactGP"]


class ExactGP:
    """Full GP regression with Gaussian noise of variance ``noise`` (``sigma0^2``).

    Fitted attributes: ``X_train_`` [N, d], ``L_`` [N, N], ``alpha_`` [N].
    """

    def __init__(self, kernel: Kernel, noise: float, *, config: NumericsConfig = CONFIG) -> None:
        if not isinstance(kernel, Kernel):
            raise ValueError(f"kernel must be a geoq Kernel, got {type(kernel).__name__}")
        self.kernel = kernel
        self.noise = check_positive(noise, "noise")
        self.config = config
        self.X_train_: FloatArray | None = None
        self.y_train_: FloatArray | None = None
        self.L_: FloatArray | None = None
        self.alpha_: FloatArray | None = None

    def fit(self, X: ArrayLike, y: ArrayLike) -> ExactGP:
        """Condition on ``X`` [N, d], ``y`` [N]; returns ``self``."""
        Xa = as_float_matrix(X, "X", self.kernel.input_dim)
        ya = as_float_vector(y, "y", Xa.shape[0])
        K = self.kernel(Xa)  # [N, N]
        K[np.diag_indices_from(K)] += self.noise
        L, _ = safe_cholesky(K, config=self.config, what="K + noise I")  # line 2
        self.X_train_, self.y_train_, self.L_ = Xa, ya, L
        self.alpha_ = scipy.linalg.cho_solve((L, True), ya, check_finite=False)  # line 3
        return self

    def _fitted(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        if self.X_train_ is None or self.L_ is None or self.alpha_ is None or self.y_train_ is None:
            raise RuntimeError("ExactGP is not fitted; call fit(X, y) first")
        return self.X_train_, self.y_train_, self.L_, self.alpha_

    @overload
    def predict(self, X: ArrayLike, return_std: Literal[False] = ...) -> FloatArray: ...
    @overload
    def predict(self, X: ArrayLike, return_std: Literal[True]) -> tuple[FloatArray, FloatArray]: ...
    def predict(
        self, X: ArrayLike, return_std: bool = False
    ) -> FloatArray | tuple[FloatArray, FloatArray]:
        """Posterior mean ``[M]`` (and std ``[M]`` of the latent f, never negative)."""
        Xt, _, L, alpha = self._fitted()
        Xs = as_float_matrix(X, "X", Xt.shape[1])
        Ks = self.kernel(Xs, Xt)  # [M, N]
        mean = Ks @ alpha  # line 4
        if not return_std:
            return mean
        V = scipy.linalg.solve_triangular(L, Ks.T, lower=True, check_finite=False)  # line 5
        var = self.kernel.diag(Xs) - np.einsum("ij,ij->j", V, V)  # line 6
        return mean, np.sqrt(np.maximum(var, 0.0))

    def log_marginal_likelihood(self) -> float:
        """``log p(y | X)`` of the fitted data (R&W Algorithm 2.1, line 7)."""
        _, y, L, alpha = self._fitted()
        n = y.shape[0]
        return float(-0.5 * y @ alpha - np.sum(np.log(np.diag(L))) - 0.5 * n * np.log(2.0 * np.pi))

    def __repr__(self) -> str:
        return f"ExactGP(kernel={self.kernel!r}, noise={self.noise:g})"
