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
matrix-vector products (``K'`` is never whitened: that would cost O(N K m^2)).
Sweeps stop when no target moves by more than ``tol`` (in target units) or after
``max_sweeps``.

Most sweeps use only each transition's few best candidates (``n_active``), so
hundreds of sweeps cost about one refit. ``K'`` comes in one of two forms
(:data:`CandidateCovariances`):

* :class:`DenseCandidates`, the matrix itself (the graph kernels).
* :class:`SeparableCandidates`, for a kernel that is a product of a state factor and
  an action factor (the squared exponential: ``exp(-|x - x'|^2 / 2)`` over
  ``x = [s, a]`` splits into ``exp(-|s - s'|^2 / 2) exp(-|a - a'|^2 / 2)``):
  ``K'[(i, k), j] = k_s(s'_i, s_j) k_a(a_k, a_j)``, so ``Q(s'_i, a_k) = (K_s
  diag(w) K_a^T)_{ik}``: a full sweep is an ``[N, S] x [S, K]`` matrix product
  over the ``K`` times smaller ``K_s`` [N, S] (with ``K_a`` [K, S]), 10x faster than
  the dense ``[N K, S]`` mat-vec (0.54 against 5.7 ms at N = 1,000, K = 21,
  S = 256, one thread); the pruned sweeps in between take ``K_s[i] . (w * K_a[k])``
  for the best candidates ``k`` of each transition (:class:`SeparableBest`).

Targets are in *standardised* units ``z = (y - y_mean) / y_scale``; the
rewards are standardised with the same affine map, so
``z = (r - y_mean) / y_scale + gamma (1 - done) (max Q'_z + y_mean / y_scale)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from geoq._typing import FloatArray, IntArray
from geoq.agents._candidates import (
    CandidateCovariances,
    DenseCandidates,
    SeparableBest,
    SeparableCandidates,
)
from geoq.agents._covariance_cache import NextStateCovariances, separable_factors
from geoq.agents.config import GPQConfig
from geoq.agents.phase_inputs import PhaseInputs
from geoq.agents.replay import ReplayStrategy
from geoq.gp import ProjectedSystem

__all__ = [
    "CandidateCovariances",
    "DenseCandidates",
    "FittedQPhase",
    "FittedQResult",
    "PhaseInputs",
    "PhaseResult",
    "SeparableBest",
    "SeparableCandidates",
    "fitted_q_sweeps",
    "standardisation",
]


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
    system: ProjectedSystem,
    K_next: FloatArray | CandidateCovariances,
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
    n_active: int | None = 3,
    refresh_every: int = 10,
    slots: IntArray | None = None,
) -> FittedQResult:
    """Iterate ``y <- r + gamma c max_a' Q_y(s', a')`` with the DTC posterior on a fixed basis.

    Parameters
    ----------
    system : the projected-process system of the transitions' inputs ``[s, a]`` on the
        basis (:meth:`geoq.gp.SparseOnlineGP.projected_system`).
    K_next : covariances of the next states x candidates with the basis: a
        :data:`CandidateCovariances`, or the dense ``[N * K, S]`` matrix (row-major
        over ``(transition, candidate)``); basis vector ``j`` in column
        ``slots[j]``, the other ``S - m`` columns must be finite and get zero weight
        (:class:`~geoq.agents._covariance_cache.NextStateCovariances`).
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
        ``None``: every sweep is a full one.
    slots : the column of ``K_next`` of each basis vector ``[m]`` (default: ``0..m-1``).
    """
    m, N = system.V.shape
    if isinstance(K_next, np.ndarray):
        K_next = DenseCandidates(K_next, K_next.shape[0] // max(N, 1))
    K, n_columns = K_next.n_candidates, K_next.n_columns
    # Weights in K_next's column order, zero where no basis vector sits.
    columns = np.arange(m) if slots is None else np.asarray(slots)
    weights = np.zeros(n_columns)
    n_best = K if n_active is None else min(max(int(n_active), 1), K)
    gamma_continues = gamma * np.asarray(continues, dtype=np.float64)
    rewards = np.ascontiguousarray(rewards, dtype=np.float64)
    lo, hi = (float(b) for b in bounds)
    y = np.array(targets0, dtype=np.float64)
    y_new = np.empty_like(y)
    change = np.inf
    sweeps = since_full = 0
    active: DenseCandidates | SeparableBest | None = None
    full = True
    while sweeps < max_sweeps:
        weights[columns] = system.mean_weights((y - y_mean) / y_scale)  # K_BV^{-1} f_BV
        if full or active is None:
            q = K_next.q(weights)  # [N, K]
            if n_best < K:  # the best candidates now
                active = K_next.restrict(_best_candidates(q, n_best))
            since_full = 0
        else:
            q = active.q(weights)  # [N, n_best]
            since_full += 1
        change = _bootstrap(
            q, rewards, gamma_continues, y_mean, y_scale, lo, hi, y, y_new
        )  # fmt: skip
        y, y_new = y_new, y
        sweeps += 1
        if change <= tol and full:
            break  # converged under the max over *every* candidate
        full = active is None or change <= tol or since_full + 1 >= refresh_every
    return FittedQResult(targets=y, sweeps=sweeps, max_change=change)


@numba.njit(cache=True, nogil=True)
def _bootstrap(
    q: FloatArray,
    rewards: FloatArray,
    gamma_continues: FloatArray,
    y_mean: float,
    y_scale: float,
    lo: float,
    hi: float,
    y: FloatArray,
    y_new: FloatArray,
) -> float:  # pragma: no cover - compiled
    """``y_new = clip(r + gamma c (y_mean + y_scale max_k q[:, k]), lo, hi)``; returns
    ``max |y_new - y|`` (0 for no transition). The operations of the numpy expression in
    its order, so the same bits, in one pass instead of eight (``q`` finite)."""
    change = 0.0
    for i in range(q.shape[0]):
        best = q[i, 0]
        for k in range(1, q.shape[1]):
            if q[i, k] > best:
                best = q[i, k]
        v = min(max(rewards[i] + gamma_continues[i] * (y_mean + y_scale * best), lo), hi)
        y_new[i] = v
        d = abs(v - y[i])
        if d > change:
            change = d
    return change


@numba.njit(cache=True, nogil=True)
def _best_candidates(q: FloatArray, n: int) -> IntArray:  # pragma: no cover - compiled
    """The columns of the ``n`` largest entries of each row of ``q`` ``[N, K]``, ``[N, n]``
    in no particular order (ties broken by position): ``np.argpartition``'s set, without
    its per-row sort machinery (0.28 ms at N = 900, K = 21, n = 3)."""
    N, K = q.shape
    top = np.empty((N, n), dtype=np.intp)
    for i in range(N):
        for c in range(n):  # start from the first n columns, smallest tracked
            top[i, c] = c
        low = 0
        for c in range(1, n):
            if q[i, top[i, c]] < q[i, top[i, low]]:
                low = c
        for k in range(n, K):
            if q[i, k] > q[i, top[i, low]]:
                top[i, low] = k
                low = 0
                for c in range(1, n):
                    if q[i, top[i, c]] < q[i, top[i, low]]:
                        low = c
    return top


def standardisation(y: FloatArray, bounds: tuple[float, float], prior: str) -> tuple[float, float]:
    """``(y_mean, y_scale)`` of targets ``y`` for a prior (:attr:`GPQConfig.prior`)."""
    lo, hi = bounds
    floor = 1e-6 * max(abs(lo), abs(hi), 1.0)  # all rewards equal: keep a positive scale
    if prior == "empirical":
        return float(np.mean(y)), max(float(np.std(y)), floor)
    half = max(0.5 * (hi - lo), floor)
    return (hi if prior == "optimistic" else 0.5 * (lo + hi)), half


@dataclass(frozen=True)
class PhaseResult:
    """Outcome of a fitted-Q phase: new targets of the stored transitions (None: a phase
    without sweeps keeps them), the new standardisation, the sweeps, the last sweep's
    largest change and the number of imagined transitions (None: no graph replay)."""

    targets: FloatArray | None
    y_mean: float
    y_scale: float
    sweeps: int
    residual: float
    imagined: int | None


class FittedQPhase:
    """One fitted-Q phase (module docstring): a replay strategy adds transitions, the
    sweeps re-bootstrap every target on the GP's current basis, the GP is refit.

    It owns what lives from phase to phase: the next states' covariances with the
    basis (:class:`NextStateCovariances`) and the replay strategy, chosen once.
    """

    def __init__(self, config: GPQConfig, replay: ReplayStrategy) -> None:
        self.config = config
        self.replay = replay
        self.covariances = NextStateCovariances(config.max_bv or 0)

    def run(self, inp: PhaseInputs) -> PhaseResult | None:
        """The phase on ``inp`` (the GP refit in place); None while the basis is empty."""
        c, gp = self.config, inp.gp
        data, y0, imagined = inp.stored, inp.targets, None
        if gp.n_bv > 0:
            data, y0, imagined = self.replay.extend(self, inp)
        if gp.n_bv == 0:
            return None
        # V = R^{-T} K_BX and B^{-1} on a fresh factor of the current K_BV (a graph kernel's
        # follows its graph), formed once: every sweep and the final refit use them.
        system = gp.projected_system(inp.inputs(data))
        if not self.replay.sweeps:  # no re-bootstrapping: refit to the online targets
            y_mean, y_scale = standardisation(y0, inp.bounds, c.prior)
            gp.refit_projected(system, (y0 - y_mean) / y_scale)
            return PhaseResult(None, y_mean, y_scale, 0, 0.0, imagined)
        N = len(inp.stored)
        K_next, slots = self.next_state_covariances(inp, data.next_states, N)
        result = fitted_q_sweeps(
            system, K_next, data.rewards, 1.0 - data.terminated.astype(np.float64), c.gamma,
            y0, y_mean=inp.y_mean, y_scale=inp.y_scale, max_sweeps=c.max_sweeps,
            tol=c.sweep_tol * inp.y_scale, bounds=inp.bounds, slots=slots,
        )  # fmt: skip
        y = result.targets[:N]
        y_mean, y_scale = standardisation(y, inp.bounds, c.prior)
        # The posterior the agent acts with is fit to the stored transitions only: imagined
        # ones (replay="graph") shape their targets, not the uncertainty that drives
        # exploration (docs/design-notes.md).
        stored = system if system.n_inputs == N else system.head(N)
        gp.refit_projected(stored, (y - y_mean) / y_scale)
        return PhaseResult(y, y_mean, y_scale, result.sweeps, result.max_change, imagined)

    def next_state_covariances(
        self, inp: PhaseInputs, S2: FloatArray, n_stored: int
    ) -> tuple[CandidateCovariances, IntArray]:
        """``k([s'_i, a_k], BV)`` for the next states ``S2`` x candidates, basis vector ``j``
        in column ``slots[j]``, and ``slots`` ``[m]``. The first ``n_stored`` next states
        are the stored transitions', kept from phase to phase where the kernel allows
        (only their state factor, the squared exponential being a product of a state and
        an action factor), the rest imagined ones (computed)."""
        kernel, bv = inp.gp.kernel, inp.gp.basis_vectors
        n_cand, d_s = inp.candidates.shape[0], inp.obs_dim
        factors = None if kernel.tracks_basis else separable_factors(kernel, d_s)
        if factors is None:
            dense = kernel.to_basis(inp.scaling.transform_pairs(S2, inp.candidates), bv)
            return DenseCandidates(dense, n_cand), np.arange(bv.shape[0])
        state, action = factors
        scale = np.asarray(inp.scaling.scale, dtype=np.float64)
        K_state, slots = self.covariances.get(
            state, lambda X: X / scale[:d_s], S2[:n_stored], inp.n_seen - n_stored, bv,
            1, scratch_states=S2[n_stored:] if len(S2) > n_stored else None,
        )  # fmt: skip
        K_action = np.zeros((n_cand, K_state.shape[1]))
        K_action[:, slots] = action.to_basis(
            inp.candidates / scale[d_s:], np.ascontiguousarray(bv[:, d_s:])
        )
        return SeparableCandidates(K_state, K_action), slots

    def stored_next_q(self, inp: PhaseInputs) -> FloatArray:
        """Posterior mean of ``Q`` ``[N, K]`` at the stored next states x candidates: the
        GP's prediction up to rounding, but from the kept covariances (no kernel
        evaluation) where the kernel allows."""
        gp, S2 = inp.gp, inp.stored.next_states
        if gp.kernel.tracks_basis:
            mean = gp.predict(inp.scaling.transform_pairs(S2, inp.candidates))
            return (inp.y_mean + inp.y_scale * mean).reshape(S2.shape[0], -1)
        K_next, slots = self.next_state_covariances(inp, S2, len(S2))
        weights = np.zeros(K_next.n_columns)
        weights[slots] = gp.alpha
        return inp.y_mean + inp.y_scale * K_next.q(weights)
