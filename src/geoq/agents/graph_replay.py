"""Replay along the MDP graph: imagined transitions from the graph's crude dynamics model.

The paper's last sentence (JC12 §6): "The crude system dynamics model given
by the constructed graph structure could also be used to perform experience
replay in order to reduce the number of required environment interactions."

**The model.** Nodes are the stored state-action pairs ``x_j = [s_j, a_j]``;
two nodes are linked when their squared-exponential similarity in the
agent's length-scale units passes the threshold of JC12 eq. 2,
``exp(-||x_i - x_j||^2 / 2) > eps`` (``||.||`` wrap-aware for angles). Each
node knows what followed it: its reward ``r_j``, its step ``s'_j - s_j`` and
whether it terminated. A state-action pair ``x = [s, a]`` that was never
tried is put into the graph as a virtual node: its linked nodes predict its
outcome, weighted by JC12 eq. 2's ``w_j = exp(-||x - x_j||^2 / 2)``: the next state
is ``s + step``, the step, the reward and the termination (``> 1/2``) fitted
locally (below). A pair with no linked node gets no imagined transition:
where the graph knows nothing the agent keeps its optimism and has to go and
look.

Written out: with ``o_j = (x_j - x) / units`` (wrap-aware) the outcome ``y`` of a
node (its step, reward and termination) is fitted as ``y ~ b0 + B o`` by
weighted ridge regression over the linked nodes (``ridge |B|^2``, intercept
free) and ``b0`` is the prediction: Nadaraya-Watson made first order, so an
action that was tried only nearby still moves the next state the way the
dynamics slope says (a local-linear model, Atkeson, Moore & Schaal 1997).
Rewards are clipped to the range observed; next states to the observation box.

**What is replayed.** For stored states ``s_i`` the agent imagines the
outcome of the candidate actions it did *not* take; the imagined transitions
join the stored ones in the fitted-Q sweeps (their targets bootstrap like any
other, :mod:`geoq.agents.fitted_q`), so the stored transitions bootstrap from a
``Q`` that knows what the untried actions at their next states do; the
posterior the agent then acts with is refit to the stored transitions only,
keeping the optimism that drives its exploration. They are drawn
afresh every phase (the model improves as the graph grows), within a budget
of ``budget`` transitions. Sources are taken in decreasing ``priority``,
prioritised-sweeping style (Moore & Atkeson 1993): the agent passes the
absolute TD error of each stored target under the current posterior, so the
imagined backups go where the values are still moving (first near rewards,
then backwards from them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from geoq._geometry import wrap_difference
from geoq._typing import FloatArray
from geoq.agents.buffer import Transitions

__all__ = ["GraphModel", "ImaginedTransitions", "imagine_transitions", "link_radius"]


@dataclass(frozen=True)
class ImaginedTransitions(Transitions):
    """Transitions predicted by the graph model (``n <= budget`` rows): a
    :class:`~geoq.agents.buffer.Transitions` record, and ``n_linked`` ``[n]``, the number of
    graph nodes linked to each imagined pair."""

    n_linked: np.ndarray


def link_radius(eps: float) -> float:
    """Distance (in length-scales) below which JC12 eq. 2 links two nodes: ``sqrt(-2 ln eps)``."""
    if not 0.0 < eps < 1.0:
        raise ValueError(f"eps must be in (0, 1), got {eps!r}")
    return float(np.sqrt(-2.0 * np.log(eps)))


@dataclass(frozen=True)
class GraphModel:
    """The graph's dynamics model: how stored transitions are linked and what they predict.

    Attributes
    ----------
    units : length of one graph unit per raw input dimension ``[d_s + d_a]``
        (the agent's scale x length-scale): distances are measured in these.
    periods : wrap-around period of each raw input dimension ``[d_s + d_a]`` (0 = none).
    eps : JC12 eq. 2 threshold, in ``(0, 1)``.
    max_links : at most this many linked nodes (the nearest) predict an outcome.
    ridge : penalty on the local model's slopes (per graph unit).
    obs_low, obs_high : observation bounds ``[d_s]``; imagined next states are clipped
        to the finite ones.
    """

    units: FloatArray
    periods: FloatArray
    eps: float
    max_links: int = 16
    ridge: float = 0.1
    obs_low: FloatArray | None = None
    obs_high: FloatArray | None = None


def imagine_transitions(
    stored: Transitions,
    model: GraphModel,
    candidates: FloatArray,
    priority: FloatArray,
    budget: int,
) -> ImaginedTransitions:
    """Imagine the untried candidate actions of the highest-priority stored states.

    Parameters
    ----------
    stored : the stored transitions (``N`` of them).
    model : how they are linked and what the links predict.
    candidates : the agent's candidate actions ``[K, d_a]``.
    priority : per stored transition ``[N]``; sources are taken in decreasing
        priority (ties: the later transition first).
    budget : largest number of imagined transitions.
    """
    S, A, R, S2 = stored.states, stored.actions, stored.rewards, stored.next_states
    terminated = stored.terminated
    units, periods, eps = model.units, model.periods, model.eps
    max_links, ridge, obs_low, obs_high = (
        model.max_links,
        model.ridge,
        model.obs_low,
        model.obs_high,
    )
    N, d_s = S.shape
    d_a = A.shape[1]
    K = candidates.shape[0]
    empty = ImaginedTransitions(
        np.empty((0, d_s)), np.empty((0, d_a)), np.empty(0), np.empty((0, d_s)),
        np.empty(0, dtype=bool), np.empty(0, dtype=np.int64),
    )  # fmt: skip
    if N == 0 or budget <= 0:
        return empty
    units = np.asarray(units, dtype=np.float64)
    p_units = np.asarray(periods, dtype=np.float64) / units  # periods in graph units
    U = np.hstack([S, A]) / units  # [N, d]
    box = np.where(p_units > 0, p_units, 0.0)
    tree = cKDTree(_into_box(U, box), boxsize=box if np.any(box > 0) else None)
    radius = link_radius(eps)

    # Sources: each stored state in priority order; imagine every candidate that is
    # not the action taken there (those are known, not imagined).
    order = np.lexsort((-np.arange(N), -np.asarray(priority, dtype=np.float64)))
    per_source = max(K - 1, 1)
    n_sources = min(N, -(-int(budget) // per_source))
    src = order[:n_sources]
    cand_u = candidates / units[d_s:]
    taken_u = A[src] / units[d_s:]
    # Drop the candidate nearest to the action actually taken at each source.
    gap = np.sum((taken_u[:, None, :] - cand_u[None, :, :]) ** 2, axis=2)  # [n_src, K]
    keep = np.ones((n_sources, K), dtype=bool)
    keep[np.arange(n_sources), np.argmin(gap, axis=1)] = K == 1
    si, ki = np.nonzero(keep)
    si, ki = si[: int(budget)], ki[: int(budget)]
    states = S[src[si]]
    actions = candidates[ki]
    k = min(int(max_links), N)
    Q = _into_box(np.hstack([states, actions]) / units, box)
    dist, idx = tree.query(Q, k=k, distance_upper_bound=radius)
    dist, idx = dist.reshape(len(Q), k), idx.reshape(len(Q), k)
    linked = idx < N  # missing neighbours come back as index N, distance inf
    n_linked = linked.sum(axis=1)
    ok = n_linked > 0
    if not np.any(ok):
        return empty
    dist, idx, linked = dist[ok], np.where(linked[ok], idx[ok], 0), linked[ok]
    w = np.where(linked, np.exp(-0.5 * dist**2), 0.0)  # [n, k] JC12 eq. 2 weights
    w /= w.sum(axis=1, keepdims=True)
    per = np.asarray(periods, dtype=np.float64)
    step = wrap_difference(S2 - S, per[:d_s])  # [N, d_s]
    outcome = np.column_stack([step, R, terminated.astype(np.float64)])  # [N, d_s + 2]
    query = np.hstack([states[ok], actions[ok]])  # [n, d]
    offsets = wrap_difference(np.hstack([S, A])[idx] - query[:, None, :], per) / units
    pred = _local_linear(offsets, w, outcome[idx], ridge)  # [n, d_s + 2]
    s_next = wrap_difference(states[ok] + pred[:, :d_s], per[:d_s])
    if obs_low is not None and obs_high is not None:
        s_next = np.clip(s_next, obs_low, obs_high)
    rewards = np.clip(pred[:, d_s], R.min(), R.max())
    term = pred[:, d_s + 1] > 0.5
    return ImaginedTransitions(
        states[ok], actions[ok], rewards, s_next, term, n_linked[ok].astype(np.int64)
    )


def _local_linear(offsets: FloatArray, w: FloatArray, Y: FloatArray, ridge: float) -> FloatArray:
    """Weighted ridge regression ``Y ~ b0 + B offsets`` per query; returns ``b0`` ``[n, q]``.

    ``offsets`` ``[n, k, d]`` (linked node minus query, graph units), ``w`` ``[n, k]``
    (zero for missing links), ``Y`` ``[n, k, q]``. Only the slopes are penalised
    (``ridge |B|^2``), so one linked node gives its own outcome.
    """
    n, k, d = offsets.shape
    D = np.concatenate([np.ones((n, k, 1)), offsets], axis=2)  # [n, k, d + 1]
    Dw = D * w[:, :, None]
    G = np.einsum("nki,nkj->nij", Dw, D)  # [n, d + 1, d + 1]
    G[:, 1:, 1:] += ridge * np.eye(d)
    beta = np.linalg.solve(G, np.einsum("nki,nkq->niq", Dw, Y))  # [n, d + 1, q]
    return beta[:, 0, :]


def _into_box(U: FloatArray, box: FloatArray) -> FloatArray:
    """Periodic coordinates taken into ``[0, box)`` (what ``cKDTree(boxsize=...)`` requires)."""
    if not np.any(box > 0):
        return U
    safe = np.where(box > 0, box, 1.0)
    V = np.mod(U, safe)
    V = np.where(V >= safe, 0.0, V)  # mod of a tiny negative number can round up to the period
    return np.where(box > 0, V, U)
