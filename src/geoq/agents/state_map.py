"""A map of where the agent has been and which moves it has seen: exploration over states.

The agent's GP is optimistic per (state, action) through a smooth kernel; behind a
wall that optimism leaks across the wall and drains one action at a time
(docs/exploration.md). :class:`StateMap` measures exploration over *states*, along
*observed moves*, in the manner of parti-game (Moore & Atkeson, Machine
Learning 21, 1995) and R-max's known-state MDP:

* **Cells** (:class:`~geoq.agents.map_cells.CellTree`): a grid over the observation
  box whose side per dimension is ``side_scale`` x the 0.9-quantile of the observed
  ``|s' - s|`` (the data's own step), each grid cell a k-d tree.
* **Blocked moves and splits.** A transition is *blocked* when it moved less than
  ``blocked_fraction`` of its candidate's typical move (the 0.9-quantile of that
  candidate's moves). A leaf is split where one candidate's outcomes in it disagree
  (blocked and moved), along the dimension (one the candidate moves along) and
  threshold that best separate the blocked starts from the moved ones, if that beats
  not splitting and leaves both halves at least ``min_split_fraction`` of the grid
  side wide.
* **Moves.** A tried (leaf, candidate) is worth the mean backup of its transitions
  that left the leaf (or were blocked, or ended the episode): ``n - 1`` steps inside
  the leaf at the candidate's mean reward (``n`` the steps its mean move takes to
  leave the leaf from the centre), then ``r + gamma (1 - done) V(leaf(s'))``, so a
  fast move beats a slow one to the same leaf. An untried one is predicted from the same
  candidate's moved transitions in the ``3^d`` grid cells around (else anywhere):
  from the leaf's centre, the mean move repeated until it leaves the leaf (``n``
  steps, worth ``r (1 - gamma^n) / (1 - gamma) + gamma^n (1 - done) V``: a macro
  move); predicted blocked (a self-loop) where a transition from the same leaf was
  blocked with a candidate at cosine >= ``blocked_cos`` (a wall seen with one move is
  a wall for the moves like it).
* **Two plans** by value iteration over the leaves, only when the map changed. The
  *explore* plan values a leaf nothing has left from (the frontier) at
  ``max(0, r_max) / (1 - gamma)`` until a goal is seen, then at the best goal's
  reward (as good as the goal), with tried and predicted moves. A *goal* is a
  termination that pays at least as much as a step that did not end the episode; one
  that pays less (a pit, a fall) is a *failure*: evidence about its place, backed up
  like any transition, not a reason to stop exploring. The
  *exploit* plan values the frontier at the lower bound and uses tried moves, and
  predicted ones only towards a leaf that a tried move from the same leaf reached (no
  route through a wall nothing crossed) or in a leaf with none tried: an unexplored
  state is not better than a found goal.
* **The greedy policy** (:meth:`StateMap.greedy`) weighs a move by Laplace's chance it
  works from anywhere in its leaf, a failure as standing still for good; at its state,
  a move whose nearest try (of a move like it, within a typical move) was blocked is
  dropped, one with no try that near counts half its value above the least return.
* **Halving.** In an observation box the space declares (finite bounds), when no
  goal has been seen and no unvisited leaf is in the explore plan's reach,
  every visited leaf is halved along its widest side (of the dimensions the moves
  cover: one nothing moved along is never halved) and the plans solved again: the
  halves nothing started from are the new frontier, so a goal smaller than a leaf is
  still sought. A box read from the data says nothing of what lies outside it: there
  the leaves are not halved.

Every scale comes from the observation box and the transitions; the design's
constants (:class:`MapSettings`) were chosen on TwoRooms and checked on five layouts
(docs/exploration.md, prototype 4). The map assumes the moves are the action's own
(a kinematic task: :func:`~geoq.agents.map_explorer.moves_follow_actions`); the agent
builds it only there.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from geoq._typing import FloatArray, IntArray
from geoq._validation import as_float_matrix, as_float_point, as_float_vector, check_real
from geoq.agents._map_model import LeafModel
from geoq.agents._map_persist import check_choices, check_flags, map_from_arrays
from geoq.agents.map_cells import CellTree, around_sums
from geoq.agents.map_settings import MapSettings

__all__ = ["MapSettings", "StateMap"]


class StateMap:
    """Explorer and greedy policy on a variable-resolution map of the observed moves.

    Parameters
    ----------
    low, high : the observation box ``[d]`` (finite, ``low <= high``).
    candidates : the agent's candidate actions ``[K, d_a]`` in the action box's centred,
        scaled coordinates (``[-1, 1]^d_a``); a transition counts for one. Moves are
        compared by their cosine there.
    gamma : the discount factor, in ``[0, 1)``.
    states, choices, rewards, next_states, terminated : the transitions so far
        (``[N, d]``, ``[N]`` candidate indices, ``[N]``, ``[N, d]``, ``[N]``), ``N >= 1``:
        they fix the grid's side.
    declared_box : whether ``low, high`` are the observation space's own bounds (not the
        data's range): only then, when no goal has been seen and nothing is left
        to explore, are the leaves halved to search inside them (:meth:`plan`).
    """

    def __init__(
        self, low: FloatArray, high: FloatArray, candidates: FloatArray, gamma: float,
        states: FloatArray, choices: IntArray, rewards: FloatArray, next_states: FloatArray,
        terminated: Any, settings: MapSettings | None = None, declared_box: bool = False,
    ) -> None:  # fmt: skip
        self.settings = MapSettings() if settings is None else settings
        if not isinstance(self.settings, MapSettings):
            raise ValueError(f"settings must be a MapSettings, got {settings!r}")
        if not isinstance(declared_box, bool | np.bool_):
            raise ValueError(f"declared_box must be True or False, got {declared_box!r}")
        self.declared_box = bool(declared_box)
        self.candidates = as_float_matrix(candidates, "candidates").copy()
        if len(self.candidates) == 0:
            raise ValueError("the map needs at least one candidate action")
        self.gamma = check_real(gamma, "gamma", low=0.0, high=1.0, high_open=True)
        d = np.size(low)
        self.S = as_float_matrix(states, "states", d).copy()
        n = len(self.S)
        if n == 0:
            raise ValueError("the map needs at least one transition: they fix its grid")
        self.S2 = as_float_matrix(next_states, "next_states", d).copy()
        self.k = check_choices(choices, n, self.n_candidates)
        self.r = as_float_vector(rewards, "rewards", n).copy()
        self.done = check_flags(terminated, n)
        if len(self.S2) != n:
            raise ValueError(f"next_states has {len(self.S2)} rows; expected {n} (one per state)")
        moves = np.abs(self.S2 - self.S)
        side = self.settings.side_scale * np.quantile(moves, self.settings.quantile, axis=0)
        self.cells = CellTree(low, high, side, anchor=self.S[0])
        self._set_typical_moves()
        self.leaf_s = self.cells.locate(self.S, create=True)
        self.leaf_s2 = self.cells.locate(self.S2, create=True)
        self._refine(set(np.unique(self.leaf_s).tolist()))
        self.V_explore = np.zeros(self.cells.n_leaves)
        self.V_exploit = np.zeros(self.cells.n_leaves)
        self.Q_explore = np.zeros((self.cells.n_leaves, self.n_candidates))
        self.Q_exploit = np.zeros((self.cells.n_leaves, self.n_candidates))
        self.Q_greedy = np.zeros((self.cells.n_leaves, self.n_candidates))
        self.changed = True
        self.plans = 0
        self.sweeps = 0
        self.halvings = 0

    @property
    def n_candidates(self) -> int:
        """``K``, the number of candidate actions."""
        return int(self.candidates.shape[0])

    @property
    def n_transitions(self) -> int:
        """Transitions the map holds."""
        return int(self.k.size)

    # ----------------------------------------------------------------- the data
    def _distances(self, S: FloatArray, S2: FloatArray) -> FloatArray:
        """The moves ``S -> S2`` (``[n, d]`` each) in grid sides ``[n]``."""
        return np.linalg.norm((S2 - S) / self.cells.side, axis=1)

    def _set_typical_moves(self) -> None:
        """Every transition's move ``[N]`` (``_dist``) and each candidate's typical move
        ``[K]`` (``_typical``: the ``quantile`` of its moves; 0 if never taken). Kept up
        to date by :meth:`observe`, which changes one candidate's at a time."""
        self._dist = self._distances(self.S, self.S2)
        self._typical = np.zeros(self.n_candidates)
        for k in np.unique(self.k):
            self._typical[k] = np.quantile(self._dist[self.k == k], self.settings.quantile)

    def _blocked(self) -> np.ndarray:
        """Blocked transitions ``[N]`` (bool): less than ``blocked_fraction`` of their
        candidate's typical move (a median is dragged to 0 by repeated blocked tries)."""
        return self._dist < self.settings.blocked_fraction * self._typical[self.k]

    def observe(self, s: FloatArray, k: int, r: float, s2: FloatArray, terminated: bool) -> None:
        """Add one transition ``s -(candidate k)-> s2``; split its leaf where it disagrees.

        The map is marked for re-planning when it changed: a new leaf, a new end leaf for
        its (leaf, candidate), a split, a termination or a blocked move."""
        s = as_float_point(s, "s", self.cells.dim)
        s2 = as_float_point(s2, "s2", self.cells.dim)
        k = int(check_choices([k], 1, self.n_candidates)[0])
        r = float(as_float_vector([r], "r")[0])
        terminated = bool(check_flags([terminated], 1)[0])
        c = int(self.cells.locate(s[None], create=True)[0])
        end = int(self.cells.locate(s2[None], create=True)[0])
        same = (self.leaf_s == c) & (self.k == k)
        new_end = not np.any(self.leaf_s2[same] == end)
        self.S, self.S2 = np.vstack([self.S, s]), np.vstack([self.S2, s2])
        self.k, self.r = np.append(self.k, k), np.append(self.r, r)
        self.done = np.append(self.done, terminated)
        self.leaf_s, self.leaf_s2 = np.append(self.leaf_s, c), np.append(self.leaf_s2, end)
        self._dist = np.append(self._dist, self._distances(s[None], s2[None]))
        self._typical[k] = np.quantile(self._dist[self.k == k], self.settings.quantile)
        split = self._refine({c})
        blocked = self._dist[-1] < self.settings.blocked_fraction * self._typical[k]
        self.changed |= bool(terminated or split or new_end or blocked)

    def _refine(self, leaves: set[int]) -> bool:
        """Split ``leaves`` (and their halves) while a candidate's outcomes disagree."""
        blocked, todo, any_split = self._blocked(), list(leaves), False
        while todo:
            leaf = todo.pop()
            cut = self._best_split(leaf, blocked)
            if cut is None:
                continue
            new = self.cells.split(leaf, *cut)
            any_split = True
            self.leaf_s = self.cells.locate(self.S)
            self.leaf_s2 = self.cells.locate(self.S2)
            todo += [leaf, new]
        return any_split

    def _cut_dims(self, moved: np.ndarray) -> list[int]:
        """The dimensions a candidate's outcomes may be cut along: those its ``moved``
        transitions (bool ``[N]``) cover at least half as far as their main one, in grid
        sides. A wall blocks a move by where it starts along the move; a cut across it
        that separates a few blocked and moved starts does so by chance, and left cells
        straddling TwoRooms' wall (docs/exploration.md)."""
        step = np.abs((self.S2[moved] - self.S[moved]) / self.cells.side).mean(axis=0)
        return np.flatnonzero(step >= 0.5 * step.max()).tolist()

    def _best_split(self, leaf: int, blocked: np.ndarray) -> tuple[int, float] | None:
        """The (dim, threshold) best separating one candidate's blocked starts from its
        moved ones in ``leaf``: fewest misclassified, then the widest gap; None if no
        cut beats not splitting."""
        in_leaf = self.leaf_s == leaf
        low, high = self.cells.leaf_low[leaf], self.cells.leaf_high[leaf]
        min_width = self.settings.min_split_fraction * self.cells.side
        best: tuple[float, float, int, float] | None = None  # (error rate, -gap, dim, cut)
        for k in np.unique(self.k[in_leaf]):
            sel = in_leaf & (self.k == k)
            b = blocked[sel]
            if b.all() or not b.any():
                continue
            X = self.S[sel]
            for dim in self._cut_dims(sel & ~blocked):
                order = np.argsort(X[:, dim], kind="stable")
                x, bb = X[order, dim], b[order]
                below_b = np.concatenate([[0], np.cumsum(bb)])
                below_m = np.concatenate([[0], np.cumsum(~bb)])
                nb, nm = below_b[-1], below_m[-1]
                # errors of "blocked above the cut" and "blocked below it", cuts between points
                err = np.minimum(below_m + nb - below_b, below_b + nm - below_m)[1:-1]
                cut = 0.5 * (x[:-1] + x[1:])
                ok = (x[1:] > x[:-1]) & (cut - low[dim] >= min_width[dim])
                ok &= high[dim] - cut >= min_width[dim]
                if not ok.any():
                    continue
                e = np.where(ok, err, np.inf)
                i = int(np.argmin(e))
                if e[i] >= min(nb, nm):
                    continue
                option = (float(e[i]) / sel.sum(), -float(x[i + 1] - x[i]), dim, float(cut[i]))
                if best is None or option[:2] < best[:2]:
                    best = option
        return None if best is None else (best[2], best[3])

    # ----------------------------------------------------------------- planning
    def bounds(self) -> tuple[float, float]:
        """``(lo, hi)``: the least discounted return of the rewards of the steps that did not
        end an episode (standing still for good: a route that never ends), and the most a
        return of the rewards seen can be."""
        g, r_max = self.gamma, float(self.r.max())
        ongoing = self.r[~self.done]
        r_min = float(ongoing.min() if ongoing.size else self.r.min())
        return min(r_min, r_min / (1 - g)), max(0.0, r_max) / (1 - g)

    def _goals(self) -> np.ndarray:
        """The transitions ``[N]`` (bool) that ended an episode and are not failures. A
        failure pays less than any step that did not end one (a pit, a fall): it is
        evidence about its place, not a goal to seek, and it does not stop the search."""
        ongoing = self.r[~self.done]
        if not ongoing.size:
            return self.done.copy()
        return self.done & (self.r >= ongoing.min())

    def _frontier(self) -> float:
        """The explore plan's value of a leaf nothing has left from: the best goal's reward
        once one is found (as good as the goal), the most a return can be before."""
        goals = self._goals()
        return float(self.r[goals].max()) if goals.any() else self.bounds()[1]

    def _predictions(self, blocked: np.ndarray) -> tuple[IntArray, FloatArray, FloatArray,
                                                         FloatArray]:  # fmt: skip
        """Predicted end leaf (-2: nothing to predict from), reward, termination and step
        count ``[L, K]`` of every (leaf, candidate) (a macro move from the leaf's centre)."""
        cells, K, d = self.cells, self.n_candidates, self.cells.dim
        moved = ~blocked
        cell = cells.roots_of(cells.grid_coords(self.S[moved]))  # every state's has a root
        starts, C = cells.root_grid, cells.n_roots
        idx = cell * K + self.k[moved]
        weights = [*(self.S2[moved] - self.S[moved]).T, self.r[moved], self.done[moved]]
        per_cell = [np.bincount(idx, minlength=C * K).reshape(C, K)]
        per_cell += [np.bincount(idx, weights=w, minlength=C * K).reshape(C, K) for w in weights]
        around = around_sums(cells, starts, np.concatenate(per_cell, axis=1))  # [R, (d + 3) K]
        count, *sums = np.split(around, d + 3, axis=1)
        count = count.astype(np.int64)
        every_count = np.bincount(self.k[moved], minlength=K)
        every_sum = [np.bincount(self.k[moved], weights=w, minlength=K) for w in weights]
        roots = cells.leaf_root
        local = count[roots] > 0  # [L, K]
        denom = np.where(local, count[roots], np.maximum(every_count, 1)[None, :])
        mean = [np.where(local, s[roots], e[None, :]) / denom
                for s, e in zip(sums, every_sum, strict=True)]  # fmt: skip
        move = np.stack(mean[:d], axis=-1)  # [L, K, d]
        half = 0.5 * (cells.leaf_high - cells.leaf_low)  # [L, d]
        with np.errstate(divide="ignore"):
            ratio = (half[:, None, :] / np.abs(move)).min(axis=2)
        n_steps = np.clip(np.floor(ratio) + 1, 1, self.settings.max_macro)
        centre = 0.5 * (cells.leaf_low + cells.leaf_high)
        ends = np.clip(centre[:, None, :] + n_steps[:, :, None] * move, cells.low, cells.high)
        target = cells.locate(ends.reshape(-1, d)).reshape(-1, K)
        target = np.where(local | (every_count > 0)[None, :], target, -2)
        if blocked.any():  # a wall seen with one move is a wall for the moves like it
            alike = self._alike()
            seen = np.zeros((cells.n_leaves, K), dtype=np.int64)
            seen[self.leaf_s[blocked], self.k[blocked]] = 1
            wall = (seen @ alike.astype(np.int64)) > 0
            target = np.where(wall, np.arange(cells.n_leaves)[:, None], target)
        return target, mean[d], mean[d + 1], n_steps

    def plan(self) -> None:
        """Value iteration for both plans, if the map changed since the last one; in a
        declared box with nothing left to explore, halve the leaves and plan again."""
        if not self.changed:
            return
        self._solve()
        while self.declared_box and self._nothing_to_explore() and self._halve_leaves():
            self._solve()
        self.changed = False

    def _nothing_to_explore(self) -> bool:
        """No goal seen and every visited leaf's explore value within
        ``route_margin`` of the least return: no unvisited leaf is in reach."""
        lo, hi = self.bounds()
        top = lo + self.settings.route_margin * (hi - lo)
        visited = np.bincount(self.leaf_s, minlength=self.cells.n_leaves) > 0
        return not self._goals().any() and bool(self.V_explore[visited].max() < top)

    def _halve_leaves(self) -> bool:
        """Halve each visited leaf's part inside the box along its widest side (in grid
        sides, of the dimensions some move covered) where the halves stay
        ``min_split_fraction`` wide; whether any was. The halves nothing has started
        from are the explore plan's new frontier, so a goal smaller than a leaf is still
        sought (docs/exploration.md). Each round at most
        doubles the visited leaves, and a leaf that is not visited is not halved: the
        leaves stay fewer than twice the transitions plus the rounds x the leaves."""
        low = np.maximum(self.cells.leaf_low, self.cells.low)
        high = np.minimum(self.cells.leaf_high, self.cells.high)
        moving = np.any(self.S2 != self.S, axis=0)  # [d]: a dimension some move covers
        width = np.where(moving, (high - low) / self.cells.side, 0.0)
        dims = np.argmax(width, axis=1)
        visited = np.bincount(self.leaf_s, minlength=width.shape[0]) > 0
        wide = width[np.arange(width.shape[0]), dims] / 2 >= self.settings.min_split_fraction
        halved = np.flatnonzero(visited & wide)
        for leaf in halved.tolist():
            dim = int(dims[leaf])
            self.cells.split(leaf, dim, float(0.5 * (low[leaf, dim] + high[leaf, dim])))
        if halved.size:
            self.leaf_s = self.cells.locate(self.S)
            self.leaf_s2 = self.cells.locate(self.S2)
            self.halvings += 1
        return bool(halved.size)

    def _solve(self) -> None:
        """Value iteration for both plans on the current leaves."""
        L, K = self.cells.n_leaves, self.n_candidates
        blocked = self._blocked()
        target, r_hat, d_hat, n_steps = self._predictions(blocked)
        visited = np.bincount(self.leaf_s, minlength=L) > 0
        # a move that stayed inside its leaf is part of a macro move, not a self-loop
        use = ~((self.leaf_s2 == self.leaf_s) & ~blocked & ~self.done)
        idx = self.leaf_s[use] * K + self.k[use]
        tried = np.bincount(idx, minlength=L * K).reshape(L, K)
        lo, _ = self.bounds()
        predicted = (tried == 0) & (target >= -1) & visited[:, None]
        model = LeafModel(self, use, idx, tried, target, r_hat, d_hat, n_steps, blocked)
        # exploit: a predicted move only towards a leaf some tried move from here reached
        # (no route through a wall nothing crossed), or in a leaf with no tried move
        reached = np.isin(np.arange(L)[:, None] * L + target,
                          np.unique(self.leaf_s[use] * L + self.leaf_s2[use]))  # fmt: skip
        explore_moves = predicted
        exploit_moves = predicted & (reached | (tried.sum(1) == 0)[:, None])
        frontier = self._frontier()
        self.V_explore = model.solve(self._grown(self.V_explore), explore_moves, visited, frontier)
        self.V_exploit = model.solve(self._grown(self.V_exploit), exploit_moves, visited, lo)
        self.Q_explore = model.q(self.V_explore, explore_moves, frontier)
        self.Q_exploit = model.q(self.V_exploit, exploit_moves, lo)
        self.Q_greedy = model.q_cautious(exploit_moves, visited, lo)
        self.sweeps += model.sweeps
        self.plans += 1

    def _grown(self, V: FloatArray) -> FloatArray:
        """``V`` warm start for the current leaves (a new leaf starts at 0)."""
        return np.concatenate([V, np.zeros(self.cells.n_leaves - V.size)])

    # ----------------------------------------------------------------- acting
    def knows_route(self, leaves: IntArray) -> np.ndarray:
        """Whether the exploit plan values each leaf ``[n]`` above the lower bound by
        ``route_margin`` of the range (a route to a goal is known); False at -1."""
        lo, hi = self.bounds()
        ok = leaves >= 0
        v = self.V_exploit[np.maximum(leaves, 0)]
        return ok & self._goals().any() & (v > lo + self.settings.route_margin * (hi - lo))

    def explore(self, s: FloatArray, rng: np.random.Generator) -> int:
        """The candidate to take in training at ``s [d]``: the explore plan's best (ties
        drawn from ``rng``; a point in no leaf: a random candidate). Plans first if the
        map changed."""
        self.plan()
        c = int(self.cells.locate(np.asarray(s, dtype=np.float64)[None])[0])
        if c < 0:
            return int(rng.integers(self.n_candidates))
        q = self.Q_explore[c]
        best = np.flatnonzero(q >= q.max() - 1e-9)
        return int(best[0] if best.size == 1 else rng.choice(best))

    def greedy(self, states: FloatArray) -> tuple[np.ndarray, np.ndarray]:
        """The greedy policy's best candidates ``[n, K]`` (bool: ties within ``1e-9`` of the
        value range; :meth:`LeafModel.q_cautious`, then :meth:`_nearest_tries`) at each
        state ``[n, d]`` and whether the exploit plan knows a route from there ``[n]``
        (no randomness). Plans first if the map changed: the plans are a function of the
        transitions, and :meth:`explore` would make the same ones before its next answer."""
        self.plan()
        X = np.asarray(states, dtype=np.float64)
        leaves = self.cells.locate(X)
        q = self.Q_greedy[np.maximum(leaves, 0)]
        lo, hi = self.bounds()
        best = q >= q.max(axis=1, keepdims=True) - 1e-9 * (hi - lo)
        if self.settings.nearest_tries:
            near, blocked = self._nearest_tries(X)
            q = np.where(near, q, lo + 0.5 * (q - lo))
            q = np.where(near & blocked, -np.inf, q)
            top = q.max(axis=1, keepdims=True)
            best = np.where(np.isfinite(top), q >= top - 1e-9 * (hi - lo), best)
        return best, self.knows_route(leaves)

    def _alike(self) -> np.ndarray:
        """``[K, K]`` bool: candidate pairs at cosine ``>= blocked_cos`` (moves alike)."""
        unit = self.candidates / np.maximum(
            np.linalg.norm(self.candidates, axis=1, keepdims=True), 1e-12
        )
        return (unit @ unit.T) >= self.settings.blocked_cos

    def _nearest_tries(self, X: FloatArray) -> tuple[np.ndarray, np.ndarray]:
        """Per state ``[n, d]`` and candidate: whether a try of a candidate like it (cosine
        >= ``blocked_cos``) started within one typical move ``[n, K]``, and whether the
        nearest such try was blocked ``[n, K]`` (of tries equally near, a blocked one:
        a blocked step starts the next try at the same point). A leaf that straddles a
        wall holds tries from its open part only (docs/exploration.md)."""
        cache = getattr(self, "_tries", None)  # predict calls this every step: built once
        if cache is None or cache[0] != self.n_transitions:  # per map change (observe)
            cache = (self.n_transitions, cKDTree(self.S / self.cells.side), self._blocked(),
                     float(self._typical.max()), self._alike())  # fmt: skip
            self._tries = cache
        _, tree, is_blocked, radius, alike = cache
        n, K = X.shape[0], self.n_candidates
        near, blocked = np.zeros((n, K), dtype=bool), np.zeros((n, K), dtype=bool)
        for i, x in enumerate(X / self.cells.side):
            idx = np.asarray(tree.query_ball_point(x, radius), dtype=np.int64)
            if idx.size == 0:
                continue
            dist = np.linalg.norm(tree.data[idx] - x, axis=1)
            idx = idx[np.lexsort((~is_blocked[idx], dist))]  # nearest first; at a tie, blocked
            hit = alike[:, self.k[idx]]  # [K, m]
            near[i] = hit.any(axis=1)
            blocked[i] = near[i] & is_blocked[idx[np.argmax(hit, axis=1)]]
        return near, blocked

    # ----------------------------------------------------------------- persistence
    _ARRAYS = ("S", "S2", "k", "r", "done", "leaf_s", "leaf_s2", "V_explore", "V_exploit",
               "Q_explore", "Q_exploit", "Q_greedy", "candidates")  # fmt: skip

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The map as named arrays (:meth:`from_arrays` inverts it)."""
        out = {f"cells/{k}": v for k, v in self.cells.to_arrays().items()}
        out.update({name: getattr(self, name) for name in self._ARRAYS})
        out["counters"] = np.array([self.gamma, float(self.changed), self.plans, self.sweeps,
                                    self.halvings, float(self.declared_box)])  # fmt: skip
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, Any], settings: MapSettings | None = None) -> StateMap:
        """A map from :meth:`to_arrays`' output; ``ValueError`` naming the first array that
        is inconsistent (:func:`geoq.agents._map_persist.map_from_arrays`)."""
        return map_from_arrays(cls, arrays, settings)
