"""The exploration map's MDP over its leaves, for one planning round: Bellman backups.

:class:`~geoq.agents.state_map.StateMap` builds one per plan from its transitions and
predicted moves (see its docstring for the model); this module holds the backups and
the value iterations of the explore, exploit and cautious greedy plans.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from geoq._typing import FloatArray, IntArray
from geoq.agents.map_settings import MapSettings

__all__ = ["LeafModel", "MapTransitions"]


class MapTransitions(Protocol):
    """What the backups read of the map (a :class:`~geoq.agents.state_map.StateMap`): its
    transitions ``[N]`` (leaves of ``s`` and ``s'``, candidate, reward, termination), the
    discount and the value iterations' settings."""

    gamma: float
    settings: MapSettings
    leaf_s: IntArray
    leaf_s2: IntArray
    k: IntArray
    r: FloatArray
    done: np.ndarray


class LeafModel:
    """The map's MDP over leaves for one planning round: Bellman backups of both plans."""

    def __init__(self, m: MapTransitions, use: np.ndarray, idx: IntArray, tried: IntArray,
                 target: IntArray, r_hat: FloatArray, d_hat: FloatArray,
                 n_steps: FloatArray, blocked: np.ndarray) -> None:  # fmt: skip
        self.m, self.use, self.idx, self.tried = m, use, idx, tried
        self.moved = ~blocked[use]  # [N_used]
        self.target, self.r_hat, self.d_hat = target, r_hat, d_hat
        g = m.gamma
        self.discount = g**n_steps  # [L, K]
        self.macro_reward = r_hat * (1 - self.discount) / (1 - g)
        # a tried move's exit is its last step: n - 1 steps inside the leaf come first
        n_used = n_steps[m.leaf_s[use], m.k[use]] - 1  # [N_used]
        self.inside_discount = g**n_used
        self.inside_reward = r_hat[m.leaf_s[use], m.k[use]] * (1 - self.inside_discount) / (1 - g)
        self.sweeps = 0

    def _backups(self, V: FloatArray) -> FloatArray:
        """Each used transition's backup ``[N_used]``: ``n - 1`` steps inside its leaf at
        the mean reward, then its observed exit."""
        m, u = self.m, self.use
        exit_backup = m.r[u] + m.gamma * (~m.done[u]) * V[m.leaf_s2[u]]
        return self.inside_reward + self.inside_discount * exit_backup

    def _predicted_backups(self, V: FloatArray, unvisited: float) -> FloatArray:
        """Every (leaf, candidate)'s macro backup ``[L, K]`` to its predicted end leaf."""
        v_end = np.where(self.target >= 0, V[np.maximum(self.target, 0)], unvisited)
        return self.macro_reward + self.discount * (1 - self.d_hat) * v_end

    def q_cautious(self, predicted: np.ndarray, visited: np.ndarray, lo: float) -> FloatArray:
        """``Q [L, K]`` of a policy that cannot retry: a move works with Laplace's chance
        ``(moved + 1) / (tried + 2)`` over its tries in the leaf (predicted: 1/2), else the
        policy stands still for good (``lo``); a working move is worth the mean of its moved
        backups. Value iteration from ``lo`` (docs/exploration.md, a cautious greedy policy)."""
        L, K = self.tried.shape
        ok = self.moved
        n_moved = np.bincount(self.idx[ok], minlength=L * K).reshape(L, K)
        p = (n_moved + 1) / (self.tried + 2)

        def q(V: FloatArray) -> FloatArray:
            total = np.bincount(self.idx[ok], weights=self._backups(V)[ok],
                                minlength=L * K).reshape(L, K)  # fmt: skip
            Q = np.where(n_moved > 0, p * total / np.maximum(n_moved, 1) + (1 - p) * lo, -np.inf)
            return np.where(predicted, 0.5 * self._predicted_backups(V, lo) + 0.5 * lo, Q)

        V = np.full(L, lo)
        for _ in range(self.m.settings.max_sweeps):
            best = q(V).max(axis=1)
            new = np.where(visited & np.isfinite(best), best, lo)
            self.sweeps += 1
            if np.max(np.abs(new - V)) < self.m.settings.tol:
                return q(new)
            V = new
        return q(V)

    def q(self, V: FloatArray, predicted: np.ndarray, unvisited: float) -> FloatArray:
        """``Q [L, K]``: mean backups of tried moves, macro backups of predicted ones, -inf
        for neither. Both count the steps a move takes to leave its leaf (from the
        centre, at the candidate's mean move), so a fast move beats a slow one to the
        same leaf."""
        L, K = self.tried.shape
        total = np.bincount(self.idx, weights=self._backups(V), minlength=L * K).reshape(L, K)
        Q = np.where(self.tried > 0, total / np.maximum(self.tried, 1), -np.inf)
        return np.where(predicted, self._predicted_backups(V, unvisited), Q)

    def solve(self, V: FloatArray, predicted: np.ndarray, visited: np.ndarray,
              unvisited: float) -> FloatArray:  # fmt: skip
        """Value iteration from ``V`` (warm start) until no value moves more than ``tol``;
        a leaf nothing has left from, or with no move, is worth ``unvisited``."""
        V = np.where(visited, V, unvisited)
        for _ in range(self.m.settings.max_sweeps):
            best = self.q(V, predicted, unvisited).max(axis=1)
            new = np.where(visited & np.isfinite(best), best, unvisited)
            self.sweeps += 1
            if np.max(np.abs(new - V)) < self.m.settings.tol:
                return new
            V = new
        return V
