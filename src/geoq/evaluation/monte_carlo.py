"""Monte-Carlo ground truth ``Q^pi(s, a)`` at arbitrary state-action pairs.

``Q^pi(s, a) = E[sum_{t>=0} gamma^t r_t | s_0 = s, a_0 = a, a_t ~ pi(s_t) for t >= 1]``
is estimated by taking ``a`` in ``s`` and then following the policy, many
times per pair. Every pair and every roll-out advance together: the
``N * R`` pendulums form one batch of the vectorised physics, so one time step
is a handful of numpy calls on arrays of length ``N * R``.

**Horizon.** The infinite sum is cut at the smallest ``H`` with
``gamma^H < 1e-4`` (:func:`mc_horizon`; ``H = 180`` for ``gamma = 0.95``). With
rewards bounded by ``r_max`` (``1`` for the pendulum) the cut changes ``Q`` by
at most ``gamma^H r_max / (1 - gamma) < 2e-3``, an order of magnitude below
the Monte-Carlo standard errors at 100 roll-outs.

**Any task.** Actions are scalars ``[N]`` or vectors ``[N, d_a]``. When the
step function also returns ``terminated``, a roll-out's return stops
accumulating at its terminating step (the reward of that step counts, nothing
after it); the terminated rows keep being stepped and given policy actions,
masked, so the generator is consumed the same way whatever terminates.

**Uncertainty.** Each estimate comes with its standard error
``std(G, ddof=1) / sqrt(R)`` over the ``R`` sampled returns ``G``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import as_float_matrix, as_float_vector
from geoq.policies import Policy
from geoq.rollouts import (
    DEFAULT_GAMMA,
    StartSpec,
    StepFn,
    collect_rollouts,
    resolve_step,
    split_step,
)

__all__ = [
    "HORIZON_TOLERANCE",
    "MCEstimate",
    "mc_horizon",
    "mc_q_values",
    "sample_evaluation_pairs",
]

#: The Monte-Carlo horizon is the first ``H`` with ``gamma^H`` below this.
HORIZON_TOLERANCE = 1e-4


@dataclass(frozen=True)
class MCEstimate:
    """Monte-Carlo estimate of ``Q^pi`` at ``N`` pairs.

    Attributes
    ----------
    mean : ``[N]`` sample mean of the discounted returns.
    stderr : ``[N]`` standard error of ``mean`` (``0`` for a deterministic policy).
    n_rollouts : roll-outs per pair, ``R``.
    horizon : steps per roll-out, ``H``.
    gamma : discount.
    """

    mean: FloatArray
    stderr: FloatArray
    n_rollouts: int
    horizon: int
    gamma: float


def mc_horizon(gamma: float, tol: float = HORIZON_TOLERANCE) -> int:
    """Smallest ``H >= 1`` with ``gamma^H < tol`` (``1`` when ``gamma == 0``)."""
    if not 0.0 <= gamma < 1.0:
        raise ValueError(f"gamma must be in [0, 1) for an infinite-horizon Q, got {gamma!r}")
    if not 0.0 < tol < 1.0:
        raise ValueError(f"tol must be in (0, 1), got {tol!r}")
    if gamma == 0.0:
        return 1
    h = max(1, math.ceil(math.log(tol) / math.log(gamma)))
    while gamma**h >= tol:  # guard against rounding in the logarithms
        h += 1
    return h


def mc_q_values(
    states: ArrayLike,
    actions: ArrayLike,
    policy: Policy,
    rng: np.random.Generator,
    n_rollouts: int = 100,
    gamma: float = DEFAULT_GAMMA,
    horizon: int | None = None,
    step: StepFn | None = None,
    max_batch: int | None = None,
) -> MCEstimate:
    """Estimate ``Q^pi(s_i, a_i)`` for ``N`` pairs by ``n_rollouts`` roll-outs each.

    Parameters
    ----------
    states : ``[N, d]`` start states.
    actions : ``[N]`` or ``[N, d_a]`` first actions (clipped by the dynamics like any action).
    policy : the policy followed after the first action.
    rng : the only source of randomness; the same generator state gives the same numbers.
    n_rollouts : roll-outs per pair ``R`` (``>= 2`` for a standard error).
    gamma : discount, in ``[0, 1)``.
    horizon : steps per roll-out; default :func:`mc_horizon` ``(gamma)``.
    step : pure vectorised dynamics; default the pendulum (:func:`geoq.envs.pendulum_step`).
        If it returns ``terminated``, returns stop at termination (module docstring).
    max_batch : at most this many simulated pendulums (pairs x roll-outs) at once, to
        bound memory; pairs are then processed in consecutive chunks with the same
        generator. Default: all at once. The numbers depend on the chunking (the
        generator is consumed in another order) but are reproducible for a given
        ``max_batch``.
    """
    S = as_float_matrix(states, "states")
    if np.ndim(actions) == 2:
        A = as_float_matrix(actions, "actions")
        if A.shape[0] != S.shape[0]:
            raise ValueError(
                f"actions has {A.shape[0]} rows; expected {S.shape[0]} (one per state)"
            )
    else:
        A = as_float_vector(actions, "actions", length=S.shape[0])
    if n_rollouts < 2:
        raise ValueError(f"n_rollouts must be >= 2 to estimate a standard error, got {n_rollouts}")
    H = mc_horizon(gamma) if horizon is None else int(horizon)
    if H < 1:
        raise ValueError(f"horizon must be >= 1, got {horizon}")
    step_fn = resolve_step(step)
    n = S.shape[0]
    if n == 0:
        raise ValueError("states is empty; pass at least one state-action pair")
    chunk = n if max_batch is None else max(1, int(max_batch) // n_rollouts)
    G = np.concatenate(  # [N, R]
        [
            _discounted_mc_returns(
                S[i : i + chunk], A[i : i + chunk], policy, rng, n_rollouts, gamma, H, step_fn
            )
            for i in range(0, n, chunk)
        ]
    )
    mean = G.mean(axis=1)
    stderr = G.std(axis=1, ddof=1) / np.sqrt(n_rollouts)
    return MCEstimate(mean, stderr, int(n_rollouts), H, float(gamma))


def _discounted_mc_returns(
    S: FloatArray,
    A: FloatArray,
    policy: Policy,
    rng: np.random.Generator,
    n_rollouts: int,
    gamma: float,
    horizon: int,
    step_fn: StepFn,
) -> FloatArray:
    """Sampled returns ``[N, R]`` of ``N`` pairs, all pairs and roll-outs in one batch."""
    n = S.shape[0]
    # Pair-major batch: rows i*R .. i*R + R-1 are the roll-outs of pair i.   # [N R, d]
    s = np.repeat(S, n_rollouts, axis=0)
    a = np.repeat(A, n_rollouts, axis=0)  # [N R] or [N R, d_a]
    total = np.zeros(n * n_rollouts)
    alive: np.ndarray | None = None  # [N R] bool, once the dynamics report termination
    discount = 1.0
    for t in range(horizon):
        if t > 0:
            a = np.asarray(policy(s, rng), dtype=np.float64)
        s, r, terminated = split_step(step_fn(s, a), n * n_rollouts)
        if terminated is None:
            total += discount * r
        else:
            if alive is None:
                alive = np.ones(n * n_rollouts, dtype=bool)
            total += discount * np.where(alive, r, 0.0)
            alive &= ~terminated
            if not alive.any():
                break
        discount *= gamma
    return total.reshape(n, n_rollouts)


def sample_evaluation_pairs(
    n_pairs: int,
    policy: Policy,
    rng: np.random.Generator,
    n_rollouts: int = 10,
    steps: int = 250,
    start: StartSpec = None,
    step: StepFn | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Draw evaluation pairs from held-out roll-outs of the same policy.

    Collects ``n_rollouts`` fresh roll-outs of ``steps`` steps with ``rng``
    (so they are independent of any training roll-outs drawn from another
    generator), pools their ``n_rollouts * steps`` visited pairs (fewer when
    episodes terminate) and picks ``n_pairs`` of them uniformly without replacement.

    Returns
    -------
    states ``[n_pairs, d]`` and actions ``[n_pairs]`` (or ``[n_pairs, d_a]``).
    """
    pool = n_rollouts * steps
    if not 1 <= n_pairs <= pool:
        raise ValueError(
            f"n_pairs = {n_pairs} must be in [1, n_rollouts * steps = {pool}]; "
            "collect more or longer roll-outs"
        )
    rollouts = collect_rollouts(n_rollouts, steps, policy, rng, start=start, step=step)
    visited = sum(len(ro) for ro in rollouts)
    if n_pairs > visited:
        raise ValueError(
            f"n_pairs = {n_pairs} exceeds the {visited} pairs the terminating roll-outs "
            "visited; collect more roll-outs"
        )
    pool = visited
    all_states = np.concatenate([ro.states for ro in rollouts], axis=0)
    all_actions = np.concatenate([ro.actions for ro in rollouts])
    idx = np.sort(rng.choice(pool, size=n_pairs, replace=False))
    return all_states[idx], all_actions[idx]
