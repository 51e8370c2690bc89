"""``greedy_actions="data"``: the greedy action among the actions the data hold near a state.

``Q``'s posterior mean is the GP's interpolation of its targets where actions were tried,
and its extrapolation elsewhere. With one action dimension the agent's candidates are a
grid, each point of it near the actions tried; in more they are a few points of a wide
box (32 Sobol' points in ``Walker2d-v5``'s six dimensions), most of them far from every
action tried at a state, and the candidates' best mean is often an extrapolation's error
(the extrapolation error of Fujimoto et al. 2019; docs/design-notes.md, part nineteen).

Here the greedy action at ``s`` is the best, by ``Q``'s posterior mean, of the actions
taken at the ``K`` stored states nearest ``s`` (``K`` the candidates' count; the stored
transitions ``Q`` learns from, its ``window``): batch-constrained Q-learning's choice
(Fujimoto et al. 2019), the data's own actions standing in for its generative model.
Nearness is the squared-exponential kernel's: each state input wrapped where periodic,
in the scaled inputs over the state length-scales in use; states are taken in blocks of at
most :data:`BLOCK` distances. Of equal means, the nearer state's action is taken.

The greedy action changes, and with it the training actions of ``exploration="greedy"``
and ``"gaussian"`` (:func:`act_in_data`: the greedy action plus noise, as TD3's,
Fujimoto et al. 2018). The other explorations' training actions (UCB, Thompson) and the
targets (their max is over the candidates) are as with the candidates.
"""

from __future__ import annotations

from typing import Any, Literal, Protocol

import numpy as np

from geoq._geometry import scaled_wrapped_squared_distances
from geoq._typing import FloatArray
from geoq.agents.buffer import Transitions
from geoq.gp import SparseOnlineGP
from geoq.learners.scaling import InputScaling

__all__ = [
    "BLOCK",
    "GREEDY_ACTIONS",
    "GreedyActions",
    "act_in_data",
    "greedy_in_data",
    "nearest_actions",
    "resolve_greedy_actions",
]

#: Where ``Q``'s greedy action is sought (``GPQConfig.greedy_actions``).
GreedyActions = Literal["auto", "candidates", "data"]
GREEDY_ACTIONS: tuple[str, ...] = ("auto", "candidates", "data")
#: Most state-to-stored-state distances held at once (32 MB): a batch of states is taken
#: in blocks of ``BLOCK // N`` states (at least one), ``N`` the stored states.
BLOCK = 2**22


class _Stored(Protocol):
    """What :func:`greedy_in_data` reads of the stored transitions (a
    :class:`~geoq.agents.buffer.TransitionBuffer`, or a prefix of one)."""

    def transitions(self, last: int | None = None) -> Transitions: ...


class _Agent(Protocol):
    """What :func:`greedy_in_data` reads of a :class:`~geoq.agents.GPQAgent` (named by
    its members: the agent's module imports this one)."""

    config: Any
    obs_dim: int
    action_low: FloatArray
    action_high: FloatArray
    candidates: FloatArray
    scaling: InputScaling
    gp: SparseOnlineGP

    @property
    def buffer(self) -> _Stored: ...

    def inputs(self, states: FloatArray, actions: FloatArray) -> FloatArray: ...

    def _lengthscale(self) -> float | tuple[float, ...]: ...


def resolve_greedy_actions(setting: GreedyActions, action_dim: int) -> GreedyActions:
    """``greedy_actions=setting`` for a task of ``action_dim`` actions: ``auto`` is ``data``
    past one action dimension, where the candidates are a few Sobol' points of a wide box,
    most far from every action tried, and ``candidates`` in 1-D, where they are a grid,
    each point near the actions tried; the other settings are what they say."""
    return ("data" if action_dim > 1 else "candidates") if setting == "auto" else setting


def nearest_actions(
    states: FloatArray, stored_states: FloatArray, stored_actions: FloatArray, k: int,
    periods: FloatArray, lengthscales: FloatArray,
) -> FloatArray:  # fmt: skip
    """The actions ``[n, k', d_a]`` taken at the ``k' = min(k, N)`` stored states
    ``[N, d_s]`` nearest each of ``states`` [n, d_s] (all in scaled units), nearest
    first (ties: the earlier stored), by ``sum_j (wrap(s_j - t_j, periods_j) /
    lengthscales_j)^2`` (``periods`` [d_s], 0 where not periodic)."""
    r2 = scaled_wrapped_squared_distances(states, stored_states, periods, lengthscales)
    order = np.argsort(r2, axis=1, kind="stable")[:, : min(k, stored_states.shape[0])]
    return stored_actions[order]


def greedy_in_data(agent: _Agent, states: FloatArray, candidates: FloatArray) -> FloatArray:
    """``agent``'s greedy actions ``[n, d_a]`` at raw ``states`` [n, d_s] (module
    docstring); ``candidates`` [n, d_a], the candidates' greedy ones, while it has stored
    nothing."""
    stored = agent.buffer.transitions(last=agent.config.window)
    if len(stored) == 0:
        return candidates
    d_s = agent.obs_dim
    scale = np.asarray(agent.scaling.scale, dtype=np.float64)[:d_s]
    lengthscales = np.broadcast_to(np.asarray(agent._lengthscale(), dtype=np.float64),
                                   (agent.scaling.dim,))[:d_s]  # fmt: skip
    periods, x, data = agent.scaling.scaled_periods()[:d_s], states / scale, stored.states / scale
    rows = max(1, BLOCK // len(stored))
    actions = np.concatenate([
        nearest_actions(x[i : i + rows], data, stored.actions, len(agent.candidates), periods,
                        np.ascontiguousarray(lengthscales))
        for i in range(0, len(x), rows)
    ])  # fmt: skip
    n, k, d_a = actions.shape
    X = agent.inputs(np.repeat(states, k, axis=0), actions.reshape(n * k, d_a))
    q = agent.gp.predict(X).reshape(n, k)  # standardised: the same order as Q's
    return actions[np.arange(n), np.argmax(q, axis=1)]


def act_in_data(agent: _Agent, states: FloatArray, mean: FloatArray, mode: str,
                rng: np.random.Generator) -> FloatArray:  # fmt: skip
    """``agent``'s actions ``[n, d_a]`` at raw ``states`` [n, d_s] by ``mode``, ``greedy``
    or ``gaussian``, from ``Q``'s means ``mean`` [n, K] at its candidates: the greedy
    action among the data's (:func:`greedy_in_data`), plus, with ``gaussian``, noise of
    ``config.action_noise`` half-ranges drawn from ``rng``; clipped to the action box."""
    actions = greedy_in_data(agent, states, agent.candidates[np.argmax(mean, axis=1)])
    if mode == "gaussian":
        half = 0.5 * (agent.action_high - agent.action_low)
        actions = actions + agent.config.action_noise * half * rng.standard_normal(actions.shape)
    return np.clip(actions, agent.action_low, agent.action_high)
