"""A small chain MDP with a closed-form ``Q^pi``, to check the estimators of Q.

States ``0 .. n-1`` (stored as ``[N, 1]`` float arrays so the chain plugs into
the same :data:`geoq.rollouts.StepFn` interface as the pendulum), actions
``-1`` (left) and ``+1`` (right; any action ``> 0`` counts as right),
deterministic moves clipped to the ends of the chain, reward
``1[s = n-1] - move_cost 1[a > 0]``. The policy :meth:`ChainMDP.policy` goes
right with probability ``p_right``. With ``P_pi`` the policy's transition
matrix and ``r_pi`` its expected reward,

    V^pi = (I - gamma P_pi)^{-1} r_pi,    Q^pi(s, a) = r(s, a) + gamma V^pi(next(s, a)),

returned by :meth:`ChainMDP.q_values`. The Monte-Carlo and TD tests compare
against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoq._typing import FloatArray

__all__ = ["ChainMDP"]


@dataclass(frozen=True)
class ChainMDP:
    """A chain of ``n_states`` states walked by a biased random policy."""

    n_states: int = 5
    """Number of states."""
    p_right: float = 0.7
    """Probability that the policy moves right."""
    move_cost: float = 0.1
    """Cost of moving right."""

    def __post_init__(self) -> None:
        if self.n_states < 2:
            raise ValueError(f"n_states must be >= 2, got {self.n_states}")
        if not 0.0 <= self.p_right <= 1.0:
            raise ValueError(f"p_right must be in [0, 1], got {self.p_right}")

    def step(self, states: FloatArray, actions: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Pure vectorised dynamics: states ``[N, 1]``, actions ``[N]`` -> ``([N, 1], [N])``."""
        s = np.asarray(states, dtype=np.float64)[:, 0]
        right = np.asarray(actions, dtype=np.float64) > 0
        rewards = (s == self.n_states - 1).astype(np.float64) - self.move_cost * right
        nxt = np.clip(s + np.where(right, 1.0, -1.0), 0, self.n_states - 1)
        return nxt[:, None], rewards

    def policy(self, states: FloatArray, rng: np.random.Generator) -> FloatArray:
        """Actions ``[N]``: ``+1`` with probability ``p_right``, else ``-1``."""
        return np.where(rng.random(np.asarray(states).shape[0]) < self.p_right, 1.0, -1.0)

    def start(self, rng: np.random.Generator, n: int) -> FloatArray:
        """``n`` start states drawn uniformly from the chain, ``[n, 1]``."""
        return rng.integers(0, self.n_states, size=(n, 1)).astype(np.float64)

    def q_values(self, gamma: float) -> FloatArray:
        """Closed-form ``Q^pi[s, k]`` (``k = 0`` left, ``1`` right), shape ``[n_states, 2]``."""
        n = self.n_states
        states = np.repeat(np.arange(n, dtype=np.float64), 2)[:, None]  # [2n, 1]
        actions = np.tile([-1.0, 1.0], n)  # [2n]
        nxt, r = self.step(states, actions)
        nxt_idx = nxt[:, 0].astype(np.int64).reshape(n, 2)
        probs = np.array([1.0 - self.p_right, self.p_right])
        P = np.zeros((n, n))
        for k in range(2):
            np.add.at(P, (np.arange(n), nxt_idx[:, k]), probs[k])
        V = np.linalg.solve(np.eye(n) - gamma * P, r.reshape(n, 2) @ probs)
        return r.reshape(n, 2) + gamma * V[nxt_idx]
