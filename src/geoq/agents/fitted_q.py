"""Fitted Q-iteration on the sparse GP's basis (the agent's training phase).

Between stretches of online learning the agent re-solves for the whole value
function at once: every stored transition ``(s, a, r, s', done)`` gets the
bootstrapped target (Ernst et al. 2005, fitted Q-iteration; Riedmiller 2005)::

    y = r + gamma * (1 - done) * max_{a'} Q(s', a')

and the posterior is the projected-process (DTC) posterior of the targets on
the GP's *current* basis-vector set and kernel, exactly what
:meth:`geoq.gp.SparseOnlineGP.refit` computes. Because the basis set and the
kernel are fixed during a phase, the posterior mean at every input is linear in
the targets: with ``K_BV = R^T R``, ``V = R^{-T} K_BX`` [m, N],
``K' = K_{X',B}`` [N K, m] at the next states paired with the ``K``
candidate actions, and ``B = sigma0^2 I + V V^T``::

    mu = B^{-1} V y,        Q(s'_i, a'_k) = (K' R^{-1} mu)_{ik}

so with ``M = R^{-1} B^{-1} V`` [m, N] formed once per phase a sweep is two
matrix-vector products (``K'`` is never whitened: that would cost O(N K m^2)),
and most sweeps use only each transition's few best candidates (see
``n_active``): hundreds of sweeps cost about one refit. Sweeps stop when no target
moves by more than ``tol`` (in target units) or after ``max_sweeps``.

Targets are in *standardised* units ``z = (y - y_mean) / y_scale``; the
rewards are standardised with the same affine map, so
``z = (r - y_mean) / y_scale + gamma (1 - done) (max Q'_z + y_mean / y_scale)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from geoq._typing import FloatArray, IntArray

__all__ = ["FittedQResult", "fitted_q_sweeps"]


@dataclass(frozen=True)
class FittedQResult:
    """Outcome of :func:`fitted_q_sweeps`.

    Attributes
    ----------
    targets : final bootstrapped targets ``[N]``, in return units.
    sweeps : number of sweeps run.
    max_change : largest change of a target in the last sweep (return units).
    """

    targets: FloatArray
    sweeps: int
    max_change: float


def fitted_q_sweeps(
    V: FloatArray,
    K_next: FloatArray,
    R: FloatArray,
    noise: float,
    rewards: FloatArray,
    continues: FloatArray,
    gamma: float,
    targets0: FloatArray,
    *,
    y_mean: float,
    y_scale: float,
    max_sweeps: int,
    tol: float,
    bounds: tuple[float, float] = (-np.inf, np.inf),
    n_active: int = 3,
    refresh_every: int = 10,
    slots: IntArray | None = None,
) -> FittedQResult:
    """Iterate ``y <- r + gamma c max_a' Q_y(s', a')`` with the DTC posterior on a fixed basis.

    Parameters
    ----------
    V : whitened features of the stored inputs, ``R^{-T} K_BX`` ``[m, N]``.
    K_next : covariances of the next states x candidates with the basis
        ``[N * K, S]`` (row-major over ``(transition, candidate)``), basis vector
        ``j`` in column ``slots[j]``; the other ``S - m`` columns must be finite and
        get zero weight (:class:`~geoq.agents._covariance_cache.NextStateCovariances`).
    R : upper Cholesky factor of ``K_BV`` ``[m, m]``.
    noise : observation-noise variance ``sigma0^2`` (standardised units).
    rewards, continues : ``[N]``; ``continues = 1 - terminated`` (a truncation
        by a time limit is not terminal: it bootstraps).
    gamma : discount factor in ``[0, 1)``.
    targets0 : starting targets ``[N]`` (return units), e.g. the previous phase's.
    y_mean, y_scale : the standardisation ``z = (y - y_mean) / y_scale``.
    max_sweeps, tol : stopping rule (``tol`` in return units).
    bounds : every target is clipped to ``[lo, hi]`` (return units): the range of
        discounted returns of the rewards seen. Kernel regression is not a
        non-expansion, so the iteration can diverge without it.
    n_active, refresh_every : the max over candidates is taken over every
        candidate on a *full* sweep, which also keeps each transition's
        ``n_active`` best candidates; the sweeps in between take the max over those
        only (the argmax moves slowly, and these sweeps cost ``n_active / K`` of a
        full one). A full sweep runs every ``refresh_every`` sweeps and whenever a
        sweep changes no target by more than ``tol``; only a full sweep can end
        the iteration, so the fixed point is the one of the max over all candidates.
    slots : the column of ``K_next`` of each basis vector ``[m]`` (default: ``0..m-1``).
    """
    m, N = V.shape
    K = K_next.shape[0] // max(N, 1)
    B = noise * np.eye(m) + V @ V.T  # [m, m]
    factor = scipy.linalg.cho_factor(B, lower=True, check_finite=False)
    # Pre-applied solves: weights = R^{-1} B^{-1} V z, so a sweep is two mat-vecs.
    M_basis = scipy.linalg.solve_triangular(
        R, scipy.linalg.cho_solve(factor, V, check_finite=False), check_finite=False
    )  # [m, N]
    if slots is None and K_next.shape[1] == m:
        M = M_basis
    else:  # rows in K_next's column order, zero where no basis vector sits
        M = np.zeros((K_next.shape[1], N))
        M[np.arange(m) if slots is None else slots] = M_basis
    n_active = min(max(int(n_active), 1), K)
    first_row = np.arange(N)[:, None] * K  # [N, 1]
    y = np.array(targets0, dtype=np.float64)
    change = np.inf
    sweeps = since_full = 0
    K_active: FloatArray | None = None
    full = True
    while sweeps < max_sweeps:
        weights = M @ ((y - y_mean) / y_scale)  # [m], K_BV^{-1} f_BV
        if full or K_active is None:
            q_all = (K_next @ weights).reshape(N, K)
            top = np.argpartition(q_all, K - n_active, axis=1)[:, K - n_active :]
            # [N n_active, S]: the rows of the best candidates now (one flat gather; the
            # flat mat-vec below gives each row the bits of the full one above)
            K_active = K_next.take((first_row + top).ravel(), axis=0)
            q_next = q_all.max(axis=1)
            since_full = 0
        else:
            q_next = (K_active @ weights).reshape(N, n_active).max(axis=1)
            since_full += 1
        y_new = np.clip(rewards + gamma * continues * (y_mean + y_scale * q_next), *bounds)
        change = float(np.max(np.abs(y_new - y))) if N else 0.0
        y = y_new
        sweeps += 1
        if change <= tol and full:
            break  # converged under the max over *every* candidate
        full = change <= tol or since_full + 1 >= refresh_every
    return FittedQResult(targets=y, sweeps=sweeps, max_change=change)
