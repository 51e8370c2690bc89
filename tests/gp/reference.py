"""Plain-numpy reference of the sparse online GP step (tests and benchmarks only).

Written for clarity, not speed (GPflow's ``reference.py`` style): the addition
and the deletion are separate steps with explicit ``np.outer``, ``np.delete`` and
an explicitly grown ``Q``. It follows Csató & Opper (2002) line by line
and is the oracle of the compiled, fused step in :mod:`geoq.gp._step`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from geoq.gp.numerics import CONFIG

__all__ = ["ReferenceOnlineGP", "dtc_posterior", "exact_posterior"]

KernelFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass
class ReferenceOnlineGP:
    """State ``alpha [m]``, ``C [m, m]``, ``Q [m, m]``, ``BV [m, d]``; same conventions."""

    kern: KernelFn
    kxx: float
    noise: float
    max_bv: int
    tol: float
    dim: int
    alpha: np.ndarray = field(init=False)
    C: np.ndarray = field(init=False)
    Q: np.ndarray = field(init=False)
    BV: np.ndarray = field(init=False)
    last_deleted: int = -1

    def __post_init__(self) -> None:
        self.alpha = np.zeros(0)
        self.C = np.zeros((0, 0))
        self.Q = np.zeros((0, 0))
        self.BV = np.zeros((0, self.dim))

    def update(self, x: np.ndarray, y: float) -> None:
        self.last_deleted = -1
        k = self.kern(self.BV, x[None, :])[:, 0]  # [m]
        m_pred = k @ self.alpha
        s2 = max(self.kxx + k @ self.C @ k, 0.0)
        q = (y - m_pred) / (self.noise + s2)
        r = -1.0 / (self.noise + s2)
        e_hat = self.Q @ k
        gamma = self.kxx - k @ e_hat
        floor = CONFIG.novelty_floor * self.kxx
        novel = gamma > 0 and gamma >= self.tol * self.kxx and gamma >= floor
        if not novel:
            g = min(max(gamma, 0.0), s2)
            eta = 1.0 / (1.0 + g * r)
            s = self.C @ k + e_hat
            self.alpha = self.alpha + q * eta * s
            self.C = self.C + r * eta * np.outer(s, s)
            return
        m = len(self.alpha)
        s = np.append(self.C @ k, 1.0)
        self.alpha = np.append(self.alpha, 0.0) + q * s
        Cext = np.zeros((m + 1, m + 1))
        Cext[:m, :m] = self.C
        self.C = Cext + r * np.outer(s, s)
        Qext = np.zeros((m + 1, m + 1))
        Qext[:m, :m] = self.Q
        u = np.append(e_hat, -1.0)
        self.Q = Qext + np.outer(u, u) / gamma
        self.BV = np.vstack([self.BV, x])
        if m + 1 > self.max_bv:
            scores = self.alpha**2 / (np.diag(self.Q) + np.diag(self.C))
            self.delete(int(np.argmin(scores)))

    def delete(self, i: int) -> None:
        a_s, c_s, q_s = self.alpha[i], self.C[i, i], self.Q[i, i]
        Qs = np.delete(self.Q[:, i], i)
        Cs = np.delete(self.C[:, i], i)
        alpha = np.delete(self.alpha, i)
        C = np.delete(np.delete(self.C, i, 0), i, 1)
        Q = np.delete(np.delete(self.Q, i, 0), i, 1)
        self.alpha = alpha - a_s * (Qs + Cs) / (q_s + c_s)
        self.C = C + np.outer(Qs, Qs) / q_s - np.outer(Qs + Cs, Qs + Cs) / (q_s + c_s)
        self.Q = Q - np.outer(Qs, Qs) / q_s
        self.BV = np.delete(self.BV, i, 0)
        self.last_deleted = i

    def predict(self, Xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        K = self.kern(Xs, self.BV)
        var = self.kxx + np.einsum("ij,jk,ik->i", K, self.C, K)
        return K @ self.alpha, np.sqrt(np.maximum(var, 0.0))


def exact_posterior(
    K: np.ndarray, Ks: np.ndarray, kss: np.ndarray, y: np.ndarray, noise: float
) -> tuple[np.ndarray, np.ndarray]:
    """Exact GP mean and std by ``numpy.linalg.solve`` (no Cholesky anywhere)."""
    A = K + noise * np.eye(K.shape[0])
    mean = Ks @ np.linalg.solve(A, y)
    var = kss - np.einsum("ij,ji->i", Ks, np.linalg.solve(A, Ks.T))
    return mean, np.sqrt(np.maximum(var, 0.0))


def dtc_posterior(
    Kbb: np.ndarray, Kbx: np.ndarray, y: np.ndarray, noise: float
) -> tuple[np.ndarray, np.ndarray]:
    """DTC (projected process) ``alpha, C`` straight from the textbook formula.

    ``Sigma = (K_BB + K_BX K_XB / sigma0^2)^{-1}``; ``alpha = Sigma K_BX y / sigma0^2``;
    ``C = -K_BB^{-1} + Sigma`` (RW06 eq. 8.26-8.27, in our signs).
    """
    Sigma = np.linalg.inv(Kbb + Kbx @ Kbx.T / noise)
    alpha = Sigma @ Kbx @ y / noise
    C = -np.linalg.inv(Kbb) + Sigma
    return alpha, C
