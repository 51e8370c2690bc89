"""New factors of ``K_BV`` for :class:`~geoq.gp.SparseOnlineGP`: the resync and the refit.

The GP's state is the upper Cholesky factor ``R`` [m, m] of ``K_BV`` and the
whitened posterior ``u ~ N(mu, S)`` with ``f_BV = R^T u``. Three pure functions
give it a new factor:

* :func:`factor_gram`: ``R`` of the kernel's current ``K_BV`` under the jitter policy
  of :mod:`geoq.gp.numerics`, reusing the factor of the last matrix factorised when
  ``K_BV`` is the same bit for bit (:class:`FactorMemo`).
* :func:`reanchor`: the whitened posterior moved onto a new factor so that the
  posterior of ``f_BV`` (mean ``R^T mu``, covariance ``R^T S R``) is unchanged (the
  resync of a basis-tracking kernel, whose ``K_BV`` changes as its graph grows).
* :func:`projected_system`: the projected-process (DTC) system of inputs on a fixed
  basis set, :class:`ProjectedSystem`, whose :meth:`~ProjectedSystem.posterior` of
  any targets is the refit (TR eq. 3.17-3.19 applied to every point at once);
  fitted-Q solves it for many targets.

Repairs are returned as counts; the GP adds them to its counters.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.linalg

from geoq._typing import FloatArray
from geoq.gp.numerics import NumericsConfig, project_whitened_covariance, robust_cholesky
from geoq.kernels.base import Kernel

__all__ = [
    "FactorMemo",
    "ProjectedSystem",
    "factor_gram",
    "projected_system",
    "reanchor",
]


#: Within one batch of updates, ``K_BV`` within ``MEMO_ULPS * eps * max|K|`` of the last
#: matrix factorised (max-abs) counts as that matrix (:meth:`FactorMemo.same_input`;
#: across batches bit for bit only, so that a GP saved between two calls and loaded
#: again, without its memo, continues with the same numbers): below the backward error
#: of the Cholesky factorisation itself (``gamma_{m+1} |R^T| |R|``, Higham Thm. 10.3),
#: so the kept factor is as good a factor of it as a new one. What it catches: a graph
#: kernel whose graph came back after a point was added and deleted again, its
#: shortest paths summed in another order (the geodesic kernel of a ``pd_novelty`` fit
#: at budget 200: 251 of 305 such ``K_BV`` within 3 ulps of the memo's, every other one
#: at least 0.28 away, ``docs/design-notes.md``).
MEMO_ULPS = 64.0


@dataclass(frozen=True)
class FactorMemo:
    """The last ``K_BV`` a GP factorised and what :func:`robust_cholesky` made of it."""

    K: FloatArray  # [m, m] the symmetrised K_BV
    config: NumericsConfig
    R: FloatArray  # [m, m] upper factor (read-only)
    jitter_events: int
    eig_clips: int
    batch: int | None = None  # the batch of updates it was made in (None: none)

    def same_input(self, K: FloatArray, config: NumericsConfig, batch: int | None = None) -> bool:
        """Whether ``K`` is :attr:`K` under ``config``: bit for bit (signed zeros
        included), or, within the batch of updates the memo was made in (``batch``),
        within :data:`MEMO_ULPS` rounding units of its largest entry."""
        if config != self.config or K.shape != self.K.shape:
            return False
        if np.array_equal(K.view(np.uint64), self.K.view(np.uint64)):
            return True
        if batch is None or batch != self.batch or K.size == 0:
            return False
        scale = float(np.max(np.abs(self.K)))
        gap = float(np.max(np.abs(K - self.K)))
        return gap <= MEMO_ULPS * float(np.finfo(np.float64).eps) * scale


def factor_gram(
    kernel: Kernel,
    basis: FloatArray,
    config: NumericsConfig,
    memo: FactorMemo | None,
    batch: int | None = None,
) -> tuple[FloatArray, int, int, FactorMemo | None]:
    """Upper Cholesky factor ``R`` [m, m] of ``K_BV = kernel.basis_gram(basis)`` [m, m].

    Returns ``(R, jitter_events, eig_clips, memo)``; ``R`` is read-only (the caller
    copies it into its state). The factor is a function of ``K_BV`` and ``config``
    alone, so the one of the last ``K_BV`` factorised is kept in the returned memo:
    when a resync finds the same matrix (the GP added a point and deleted it again, and
    the kernel's ``K_BV`` came back with the graph, bit for bit or within rounding:
    :meth:`FactorMemo.same_input`; with an indefinite ``K_BV`` each factorisation costs
    an eigendecomposition), the stored factor and its repair counts are reused.
    ``batch``: the caller's batch of updates (a resync inside one), else None.
    """
    m = basis.shape[0]
    K = np.asarray(kernel.basis_gram(basis), dtype=np.float64)  # [m, m]
    if K.shape != (m, m) or not np.all(np.isfinite(K)):
        raise ValueError(f"kernel.basis_gram returned shape {K.shape} or non-finite values")
    K = 0.5 * (K + K.T)
    if memo is not None and memo.same_input(K, config, batch):
        return memo.R, memo.jitter_events, memo.eig_clips, memo
    L, jit, clips = robust_cholesky(K, "K_BV", config)
    R = np.ascontiguousarray(L.T)
    R.flags.writeable = False
    return R, jit, clips, FactorMemo(K, config, R, jit, clips, batch)


def reanchor(
    R_old: FloatArray,
    R_new: FloatArray,
    mu: FloatArray,
    S: FloatArray,
    *,
    many_above_one: bool = False,
) -> tuple[FloatArray, FloatArray, int]:
    """The whitened posterior ``(mu [m], S [m, m])`` on factor ``R_old`` moved onto ``R_new``.

    ``T = L_new^{-1} L_old`` (``L = R^T``) maps old whitened coordinates to new ones:
    ``mu' = T mu``, ``S' = T S T^T``, then projected onto ``0 <= S' <= I``. Returns
    ``(mu', S', projected)``, ``projected`` the number of eigenvalues projected.

    When ``R_new`` is ``R_old`` bit for bit (the GP added a point and deleted it again,
    and the kernel's ``K_BV`` came back with its graph: about half the re-anchorings of
    a ``resistance`` fit at its budget) the triangular solve gives ``T = I`` exactly and
    the products give back ``mu`` and ``S``: both are skipped (finite entries only, where
    ``0 * x = 0``), the projection is not.

    ``many_above_one``: the caller expects many eigenvalues of ``S'`` above 1
    (:func:`project_whitened_covariance`).
    """
    if np.array_equal(R_old, R_new) and np.isfinite(mu).all() and np.isfinite(S).all():
        S_new, projected = project_whitened_covariance(S, many_above_one=many_above_one)
        return mu.copy(), S_new, projected
    Tm = scipy.linalg.solve_triangular(
        R_new, np.ascontiguousarray(R_old.T), trans="T", check_finite=False
    )  # [m, m]
    S_new, projected = project_whitened_covariance(Tm @ S @ Tm.T, many_above_one=many_above_one)
    return Tm @ mu, S_new, projected


@dataclass(frozen=True)
class ProjectedSystem:
    """The projected-process (DTC) system of inputs ``X`` on a fixed basis: a refit
    without its targets, for many target vectors on the same inputs (fitted-Q).

    With ``K_BV = R^T R``, ``V = R^{-T} K_BX`` and ``B = sigma0^2 I + V V^T``, the
    posterior of targets ``y`` is ``mu = B^{-1} V y``, ``S = sigma0^2 B^{-1}``
    (:meth:`posterior`) and its mean weights ``alpha = R^{-1} mu``
    (:meth:`mean_weights`: ``mean(x) = k(x, BV) alpha``).

    Attributes
    ----------
    basis : the basis vectors ``[m, d]`` it was formed on (a copy).
    R : upper Cholesky factor of ``K_BV`` ``[m, m]`` (read-only).
    V : whitened features ``[m, N]``.
    B_inv : ``B^{-1}`` ``[m, m]``.
    noise : ``sigma0^2``.
    config : the numerics (jitter policy) ``B`` was factorised under.
    jitter_events, eig_clips : repairs made factorising ``B``.
    """

    basis: FloatArray
    R: FloatArray
    V: FloatArray
    B_inv: FloatArray
    noise: float
    config: NumericsConfig
    jitter_events: int
    eig_clips: int

    @property
    def n_inputs(self) -> int:
        """``N``, the number of inputs."""
        return int(self.V.shape[1])

    def posterior(self, y: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The whitened posterior ``(mu [m], S [m, m])`` of targets ``y`` ``[N]``."""
        mu = self.B_inv @ (self.V @ y)
        S = self.noise * self.B_inv
        return mu, 0.5 * (S + S.T)

    @cached_property
    def _weights_map(self) -> FloatArray:
        """``R^{-1} B^{-1}`` ``[m, m]`` (formed on first use)."""
        return scipy.linalg.solve_triangular(self.R, self.B_inv, check_finite=False)

    def mean_weights(self, y: FloatArray) -> FloatArray:
        """``alpha = R^{-1} B^{-1} V y`` ``[m]`` of targets ``y`` ``[N]``: two
        mat-vecs (``[m, N]``, then ``[m, m]``) once the first call formed ``R^{-1} B^{-1}``."""
        return self._weights_map @ (self.V @ y)

    def head(self, n: int) -> ProjectedSystem:
        """The system of the first ``n`` inputs (no kernel evaluation, no solve with ``R``)."""
        if not 0 <= n <= self.n_inputs:
            raise ValueError(f"head({n}) of a system of {self.n_inputs} inputs")
        return _system(self.basis, self.R, self.V[:, :n], self.noise, self.config)


def projected_system(
    kernel: Kernel,
    X: FloatArray,
    basis: FloatArray,
    R: FloatArray,
    noise: float,
    config: NumericsConfig,
) -> ProjectedSystem:
    """The :class:`ProjectedSystem` of ``X`` ``[N, d]`` on ``basis`` ``[m, d]`` with the
    factor ``R`` of its ``K_BV``."""
    Kbx = np.asarray(kernel.to_basis(X, basis), dtype=np.float64).T  # [m, N]
    V = scipy.linalg.solve_triangular(R, Kbx, trans="T", check_finite=False)  # [m, N]
    return _system(np.array(basis, dtype=np.float64), R, V, noise, config)


def _system(
    basis: FloatArray, R: FloatArray, V: FloatArray, noise: float, config: NumericsConfig
) -> ProjectedSystem:
    m = R.shape[0]
    B = noise * np.eye(m) + V @ V.T  # [m, m], eigenvalues >= sigma0^2
    LB, jit, clips = robust_cholesky(B, "DTC system matrix", config)
    B_inv = scipy.linalg.cho_solve((LB, True), np.eye(m), check_finite=False)
    return ProjectedSystem(basis, R, V, B_inv, noise, config, jit, clips)
