"""Prototype 4 of docs/exploration.md: a variable-resolution map (parti-game's splits).

A standalone explorer, not a GPQAgent: it acts with the GP agent's candidate
actions (``geoq.agents.acquisition.candidate_actions``) and plans on a map of
cells that it refines where the data show an obstacle.

* **Cells.** A grid over the observation box whose side per dimension is the
  0.9-quantile of the observed ``|s' - s|`` after a warm-up of random candidates
  (the data's own step size). Each grid cell is the root of a k-d tree: a leaf
  is split where one candidate's outcomes in it disagree, some *moved* and some
  *blocked* (covered less than a quarter of that candidate's typical move, the
  0.9-quantile of its moves: a median is dragged to 0 by repeated blocked tries), along
  the dimension and threshold that best separate the blocked starts from the
  moved ones (Moore & Atkeson's parti-game, Machine Learning 21, 1995).
* **Moves.** A transition counts for the candidate it took. A tried
  (leaf, candidate) is worth the mean backup ``r + gamma (1 - done) V(leaf(s'))``
  of its transitions. An untried one is predicted from the same candidate's
  moved transitions in the 3^d grid cells around the leaf (else anywhere): the
  leaf's centre plus their mean move, their mean reward and termination.
* **Explore plan.** A leaf without transitions from it (the frontier) is worth
  ``frontier``: ``max(0, r_max) / (1 - gamma)`` before any termination is
  seen, then the value of the best terminal transition ("as good as the goal",
  ``frontier_after_goal="goal"``) or the lower bound (``"lo"``: explore no more).
  Tried and predicted moves both count.
* **Exploit plan** (``predict``): no optimism, a frontier leaf is worth the lower
  bound ``r_min / (1 - gamma)``; moves as ``exploit`` says: ``"tried"`` (tried
  moves only; a leaf with none falls back to predicted ones), ``"clean"``
  (predicted moves also where the leaf holds no blocked transition and the
  predicted leaf has transitions from it) or ``"all"``.
* **Planning** by value iteration over the leaves, warm-started, only when the
  map changed: a new leaf, a new (leaf, candidate), a split, a termination, or a
  transition that ended in a leaf its (leaf, candidate) had not reached before.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from geoq.agents.acquisition import candidate_actions

__all__ = ["MapConfig", "PartiMap"]


@dataclass(frozen=True)
class MapConfig:
    """The prototype's settings; every scale is read from the data or the spaces."""

    gamma: float = 0.98
    n_candidates: int = 21  # GPQAgent's default (a Sobol' set of 32 in 2-D)
    quantile: float = 0.9  # the cell side: this quantile of |s' - s| per dimension
    side_scale: float = 1.0  # ... times this
    blocked_fraction: float = 0.25  # blocked: less than this x the candidate's typical move
    min_split_fraction: float = 1 / 16  # no leaf narrower than this x the cell side
    split: bool = True  # False: the fixed data-sized grid (prototype 1's map)
    exploit: str = "tried"  # "tried" | "clean" | "all"
    frontier_after_goal: str = "goal"  # "goal" | "lo" | "hi"
    tol: float = 1e-3  # value iteration stops when no value moves more than this
    max_sweeps: int = 2000
    # a move that stays inside its leaf is no self-loop: such transitions are left out of
    # the tried backups, and a predicted move is repeated until it leaves the leaf
    # (cost and discount of those steps), so cells larger than a move do not trap
    macro: bool = False
    max_macro: int = 50
    # an untried (leaf, candidate) is predicted blocked (a self-loop) when a transition
    # from the same leaf was blocked with a candidate at cosine >= this (None: never)
    blocked_cos: float | None = None
    # once a termination is seen, every n-th training episode follows the exploit plan
    # (0: never), so that blocked moves on the greedy route are seen and split on
    greedy_every: int = 0
    # where the exploit plan knows no route (its value is the lower bound), act by the
    # explore plan instead (greedy evaluation included): a trapped leaf does not hold
    fallback: bool = False


@dataclass
class _Stats:
    plans: int = 0
    sweeps: int = 0
    plan_seconds: float = 0.0
    splits: int = 0
    extra: dict[str, float] = field(default_factory=dict)


class PartiMap:
    """Explorer and greedy policy on a variable-resolution map of the observed moves."""

    def __init__(self, obs_low, obs_high, act_low, act_high, config: MapConfig, rng) -> None:
        self.c = config
        self.rng = rng
        self.low = np.asarray(obs_low, dtype=np.float64)
        self.high = np.asarray(obs_high, dtype=np.float64)
        self.cand = candidate_actions(act_low, act_high, config.n_candidates, rng)  # [K, d_a]
        self.K = len(self.cand)
        self.d = self.low.size
        self.warmup = 2 * self.K  # steps of random candidates before the cell side is read
        self.S = np.zeros((0, self.d))
        self.S2 = np.zeros((0, self.d))
        self.k = np.zeros(0, dtype=np.int64)
        self.r = np.zeros(0)
        self.done = np.zeros(0, dtype=bool)
        self.side: np.ndarray | None = None
        self.stats = _Stats()
        self.changed = True
        self.V_explore = np.zeros(0)
        self.V_exploit = np.zeros(0)
        self.episodes = 0

    # ----------------------------------------------------------------- the tree
    def _build_grid(self) -> None:
        side = self.c.side_scale * np.quantile(np.abs(self.S2 - self.S), self.c.quantile, axis=0)
        span = self.high - self.low
        side = np.where(side > 0, side, span)
        self.n_grid = np.maximum(np.ceil(span / side).astype(np.int64), 1)  # [d]
        self.side = side
        self.root = np.full(int(np.prod(self.n_grid)), -1, dtype=np.int64)
        # nodes: split dimension (-1: a leaf), threshold, children, leaf id
        self.n_dim = np.zeros(0, dtype=np.int64)
        self.n_thr = np.zeros(0)
        self.n_lo = np.zeros(0, dtype=np.int64)
        self.n_hi = np.zeros(0, dtype=np.int64)
        self.n_leaf = np.zeros(0, dtype=np.int64)
        self.leaf_node = np.zeros(0, dtype=np.int64)
        self.leaf_lo = np.zeros((0, self.d))
        self.leaf_hi = np.zeros((0, self.d))
        self.leaf_root = np.zeros(0, dtype=np.int64)
        self.V_explore = np.zeros(0)
        self.V_exploit = np.zeros(0)

    def _grid_index(self, X: np.ndarray) -> np.ndarray:
        g = np.floor((X - self.low) / self.side).astype(np.int64)
        g = np.clip(g, 0, self.n_grid - 1)
        return np.ravel_multi_index(g.T, self.n_grid)

    def _new_leaf(self, lo: np.ndarray, hi: np.ndarray, root: int, v: float) -> int:
        node, leaf = self.n_dim.size, self.leaf_lo.shape[0]
        self.n_dim = np.append(self.n_dim, -1)
        self.n_thr = np.append(self.n_thr, 0.0)
        self.n_lo = np.append(self.n_lo, -1)
        self.n_hi = np.append(self.n_hi, -1)
        self.n_leaf = np.append(self.n_leaf, leaf)
        self.leaf_node = np.append(self.leaf_node, node)
        self.leaf_lo = np.vstack([self.leaf_lo, lo])
        self.leaf_hi = np.vstack([self.leaf_hi, hi])
        self.leaf_root = np.append(self.leaf_root, root)
        self.V_explore = np.append(self.V_explore, v)
        self.V_exploit = np.append(self.V_exploit, v)
        return node

    def locate(self, X: np.ndarray, create: bool = False) -> np.ndarray:
        """Leaf ids ``[n]`` of the points ``X [n, d]``; -1 in a grid cell without a leaf."""
        flat = self._grid_index(X)
        if create:
            for f in np.unique(flat[self.root[flat] < 0]):
                g = np.array(np.unravel_index(f, self.n_grid))
                lo = self.low + g * self.side
                self.root[f] = self._new_leaf(lo, lo + self.side, int(f), self._frontier())
        node = self.root[flat]
        inner = node >= 0
        while True:
            idx = np.flatnonzero(inner & (self.n_dim[np.maximum(node, 0)] >= 0))
            if idx.size == 0:
                break
            nd = node[idx]
            go_hi = X[idx, self.n_dim[nd]] >= self.n_thr[nd]
            node[idx] = np.where(go_hi, self.n_hi[nd], self.n_lo[nd])
        return np.where(inner, self.n_leaf[np.maximum(node, 0)], -1)

    def _split(self, leaf: int, dim: int, thr: float) -> None:
        """The leaf keeps its id for the part below ``thr``; the part above is a new leaf."""
        node = self.leaf_node[leaf]
        hi_lo = self.leaf_lo[leaf].copy()
        hi_lo[dim] = thr
        new_node = self._new_leaf(hi_lo, self.leaf_hi[leaf], int(self.leaf_root[leaf]), 0.0)
        new_leaf = self.n_leaf[new_node]
        self.V_explore[new_leaf] = self.V_explore[leaf]
        self.V_exploit[new_leaf] = self.V_exploit[leaf]
        lo_node = self.n_dim.size
        self.n_dim = np.append(self.n_dim, -1)
        self.n_thr = np.append(self.n_thr, 0.0)
        self.n_lo = np.append(self.n_lo, -1)
        self.n_hi = np.append(self.n_hi, -1)
        self.n_leaf = np.append(self.n_leaf, leaf)
        self.leaf_node[leaf] = lo_node
        self.leaf_hi[leaf, dim] = thr
        self.n_dim[node], self.n_thr[node] = dim, thr
        self.n_lo[node], self.n_hi[node], self.n_leaf[node] = lo_node, new_node, -1
        self.stats.splits += 1

    def _blocked(self) -> np.ndarray:
        """Blocked transitions ``[N]``: less than a fraction of their candidate's typical move."""
        dist = np.linalg.norm((self.S2 - self.S) / self.side, axis=1)  # [N]
        med = np.zeros(self.K)
        for k in np.unique(self.k):
            med[k] = np.quantile(dist[self.k == k], self.c.quantile)
        return dist < self.c.blocked_fraction * med[self.k]

    def _best_split(self, leaf: int, blocked: np.ndarray) -> tuple[int, float] | None:
        """The (dim, threshold) separating one candidate's blocked starts from its moved ones."""
        in_leaf = self.leaf_s == leaf
        best: tuple[float, float, int, float] | None = None  # (errors, -gap, dim, thr)
        min_w = self.c.min_split_fraction * self.side
        for k in np.unique(self.k[in_leaf]):
            sel = in_leaf & (self.k == k)
            b = blocked[sel]
            if b.all() or not b.any():
                continue
            X = self.S[sel]
            for dim in range(self.d):
                order = np.argsort(X[:, dim], kind="stable")
                x, bb = X[order, dim], b[order]
                # errors of "blocked below t" and "blocked above t" at every cut
                below_b = np.concatenate([[0], np.cumsum(bb)])
                below_m = np.concatenate([[0], np.cumsum(~bb)])
                nb, nm = below_b[-1], below_m[-1]
                err_lo = below_m + (nb - below_b)  # moved below, blocked above
                err_hi = below_b + (nm - below_m)
                err = np.minimum(err_lo, err_hi)[1:-1]  # cuts between points
                if err.size == 0:
                    continue
                thr_all = 0.5 * (x[:-1] + x[1:])
                ok = (
                    (x[1:] > x[:-1])
                    & (thr_all - self.leaf_lo[leaf, dim] >= min_w[dim])
                    & (self.leaf_hi[leaf, dim] - thr_all >= min_w[dim])
                )
                if not ok.any():
                    continue
                e = np.where(ok, err, np.inf)
                i = int(np.argmin(e))
                if e[i] >= min(nb, nm):
                    continue  # no better than not splitting
                cand = (float(e[i]) / sel.sum(), -(x[i + 1] - x[i]), dim, float(thr_all[i]))
                if best is None or cand[:2] < best[:2]:
                    best = cand
        return None if best is None else (best[2], best[3])

    def _refine(self, leaves: set[int]) -> bool:
        if not self.c.split:
            return False
        blocked = self._blocked()
        todo, any_split = list(leaves), False
        while todo:
            leaf = todo.pop()
            cut = self._best_split(leaf, blocked)
            if cut is None:
                continue
            self._split(leaf, *cut)
            any_split = True
            self._relocate()
            todo += [leaf, self.leaf_lo.shape[0] - 1]
        return any_split

    def _relocate(self) -> None:
        self.leaf_s = self.locate(self.S)
        self.leaf_s2 = self.locate(self.S2, create=True)

    # ----------------------------------------------------------------- data
    def observe(self, s, k: int, r: float, s2, terminated: bool, end: bool = False) -> None:
        """Record one transition (``end``: the episode ends); refine the map where it changed."""
        self.episodes += bool(end)
        self.S = np.vstack([self.S, s])
        self.S2 = np.vstack([self.S2, s2])
        self.k = np.append(self.k, k)
        self.r = np.append(self.r, r)
        self.done = np.append(self.done, terminated)
        n = self.S.shape[0]
        if n < self.warmup:
            return
        if self.side is None:
            self._build_grid()
            self.locate(self.S, create=True)
            self._relocate()
            self._refine(set(np.unique(self.leaf_s).tolist()))
            self.changed = True
            return
        c = int(self.locate(s[None], create=True)[0])
        self.leaf_s = np.append(self.leaf_s, c)
        self.leaf_s2 = np.append(self.leaf_s2, self.locate(s2[None], create=True)[0])
        same = (self.leaf_s[:-1] == c) & (self.k[:-1] == k)
        new_end = not np.any(self.leaf_s2[:-1][same] == self.leaf_s2[-1])
        split = self._refine({c})
        dist = np.linalg.norm((self.S2 - self.S)[self.k == k] / self.side, axis=1)
        was_blocked = dist[-1] < self.c.blocked_fraction * np.quantile(dist, self.c.quantile)
        self.changed |= bool(terminated or split or new_end or was_blocked)

    # ----------------------------------------------------------------- planning
    def _bounds(self) -> tuple[float, float]:
        g = self.c.gamma
        r_min, r_max = float(self.r.min()), float(self.r.max())
        lo = min(r_min, r_min / (1 - g))
        hi = max(0.0, r_max) / (1 - g)
        return lo, hi

    def _frontier(self) -> float:
        if self.r.size == 0:
            return 0.0
        lo, hi = self._bounds()
        if not self.done.any() or self.c.frontier_after_goal == "hi":
            return hi
        if self.c.frontier_after_goal == "lo":
            return lo
        return float(self.r[self.done].max())  # the best terminal transition's value

    def _predictions(self, blocked: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted end leaf, reward and termination ``[L, K]`` of every (leaf, candidate)."""
        G, K, d = self.root.size, self.K, self.d
        moved = ~blocked
        gi = self._grid_index(self.S[moved])
        idx = gi * K + self.k[moved]
        cnt = np.bincount(idx, minlength=G * K).reshape([*self.n_grid.tolist(), K])
        sums = [
            np.bincount(idx, weights=w, minlength=G * K).reshape([*self.n_grid.tolist(), K])
            for w in [*(self.S2[moved] - self.S[moved]).T, self.r[moved], self.done[moved]]
        ]

        def neighbourhood(a: np.ndarray) -> np.ndarray:  # sum over the 3^d grid cells around
            out = a
            for ax in range(d):
                pad = [(1, 1) if i == ax else (0, 0) for i in range(a.ndim)]
                p, n = np.pad(out, pad), out.shape[ax]
                out = sum(
                    p[tuple(slice(s, s + n) if i == ax else slice(None) for i in range(a.ndim))]
                    for s in range(3)
                )
            return out

        cnt_n = neighbourhood(cnt).reshape(G, K)
        sums_n = [neighbourhood(x).reshape(G, K) for x in sums]
        glob_cnt = np.bincount(self.k[moved], minlength=K)
        glob = [
            np.bincount(self.k[moved], weights=w, minlength=K)
            for w in [*(self.S2[moved] - self.S[moved]).T, self.r[moved], self.done[moved]]
        ]
        rc = self.leaf_root  # [L]
        local = cnt_n[rc] > 0  # [L, K]
        denom = np.where(local, cnt_n[rc], np.maximum(glob_cnt, 1)[None, :])
        mean = [
            np.where(local, sn[rc], gl[None, :]) / denom
            for sn, gl in zip(sums_n, glob, strict=True)
        ]
        centre = 0.5 * (self.leaf_lo + self.leaf_hi)  # [L, d]
        move = np.stack(mean[:d], axis=-1)  # [L, K, d]
        n_steps = np.ones(move.shape[:2])  # [L, K]
        if self.c.macro:  # repeat the move until it leaves the leaf (from the centre)
            half = 0.5 * (self.leaf_hi - self.leaf_lo)  # [L, d]
            with np.errstate(divide="ignore"):
                ratio = half[:, None, :] / np.abs(move)
            n_steps = np.clip(np.floor(ratio.min(axis=2)) + 1, 1, self.c.max_macro)
        self.n_steps = n_steps
        ends = centre[:, None, :] + n_steps[:, :, None] * move
        ends = np.clip(ends, self.low, self.high)
        target = self.locate(ends.reshape(-1, d)).reshape(-1, K)
        known = local | (glob_cnt > 0)[None, :]
        target = np.where(known, target, -2)  # -2: nothing to predict from
        if self.c.blocked_cos is not None and blocked.any():
            a = self.cand / np.maximum(np.linalg.norm(self.cand, axis=1, keepdims=True), 1e-12)
            near = (a @ a.T) >= self.c.blocked_cos  # [K, K]
            L = self.leaf_lo.shape[0]
            seen = np.zeros((L, K), dtype=bool)
            seen[self.leaf_s[blocked], self.k[blocked]] = True
            wall = (seen.astype(np.int64) @ near.astype(np.int64)) > 0  # [L, K]
            target = np.where(wall, np.arange(L)[:, None], target)
        return target, mean[d], mean[d + 1]

    def plan(self) -> None:
        """Value iteration for both plans, when the map changed since the last one."""
        if self.side is None or not self.changed:
            return
        t0 = time.perf_counter()
        L, K = self.leaf_lo.shape[0], self.K
        blocked = self._blocked()
        target, r_hat, d_hat = self._predictions(blocked)
        visited = np.bincount(self.leaf_s, minlength=L) > 0  # [L]
        use = np.ones(self.k.size, dtype=bool)
        if self.c.macro:
            use = ~((self.leaf_s2 == self.leaf_s) & ~blocked & ~self.done)
        self._use = use
        idx = self.leaf_s[use] * K + self.k[use]
        n_ck = np.bincount(idx, minlength=L * K).reshape(L, K)
        tried = n_ck > 0
        leaf_blocked = np.bincount(self.leaf_s[blocked], minlength=L) > 0
        lo, _ = self._bounds()
        frontier = self._frontier()
        pred_ok = (~tried) & (target >= -1) & visited[:, None]
        if self.c.exploit == "all":
            pred_exploit = pred_ok
        elif self.c.exploit == "clean":
            tgt_visited = np.where(target >= 0, visited[np.maximum(target, 0)], False)
            pred_exploit = pred_ok & ~leaf_blocked[:, None] & tgt_visited
        else:
            pred_exploit = pred_ok & ~tried.any(1)[:, None]
        self.V_explore = self._solve(self.V_explore, idx, n_ck, target, r_hat, d_hat,
                                     pred_ok, visited, frontier)  # fmt: skip
        self.V_exploit = self._solve(self.V_exploit, idx, n_ck, target, r_hat, d_hat,
                                     pred_exploit, visited, lo)  # fmt: skip
        self.Q_explore = self._q(self.V_explore, idx, n_ck, target, r_hat, d_hat, pred_ok, frontier)
        self.Q_exploit = self._q(self.V_exploit, idx, n_ck, target, r_hat, d_hat, pred_exploit, lo)
        self.changed = False
        self.stats.plans += 1
        self.stats.plan_seconds += time.perf_counter() - t0

    def _q(self, V, idx, n_ck, target, r_hat, d_hat, pred, unvisited_value) -> np.ndarray:
        L, K, g = n_ck.shape[0], self.K, self.c.gamma
        u = self._use
        backup = self.r[u] + g * (~self.done[u]) * V[self.leaf_s2[u]]
        tot = np.bincount(idx, weights=backup, minlength=L * K).reshape(L, K)
        Q = np.where(n_ck > 0, tot / np.maximum(n_ck, 1), -np.inf)
        vt = np.where(target >= 0, V[np.maximum(target, 0)], unvisited_value)
        n = self.n_steps
        gn = g**n
        return np.where(pred, r_hat * (1 - gn) / (1 - g) + gn * (1 - d_hat) * vt, Q)

    def _solve(self, V, idx, n_ck, target, r_hat, d_hat, pred, visited, unvisited_value):
        V = V.copy()
        V[~visited] = unvisited_value
        for _ in range(self.c.max_sweeps):
            Q = self._q(V, idx, n_ck, target, r_hat, d_hat, pred, unvisited_value)
            new = np.where(visited, Q.max(1), unvisited_value)
            new = np.where(np.isfinite(new), new, unvisited_value)
            self.stats.sweeps += 1
            if np.max(np.abs(new - V)) < self.c.tol:
                return new
            V = new
        return V

    # ----------------------------------------------------------------- acting
    def explore(self, s) -> int:
        """The candidate to take in training at state ``s`` (random during the warm-up)."""
        if self.side is None:
            return int(self.rng.integers(self.K))
        self.plan()
        c = int(self.locate(np.asarray(s)[None])[0])
        if c < 0:
            return int(self.rng.integers(self.K))
        n = self.c.greedy_every
        exploit = n > 0 and self.done.any() and self.episodes % n == n - 1
        q = self.Q_exploit[c] if exploit and self._knows_route(c) else self.Q_explore[c]
        best = np.flatnonzero(q >= q.max() - 1e-9)
        return int(self.rng.choice(best))

    def greedy(self, s) -> int:
        """The candidate of the exploit plan at ``s`` (no randomness; changes nothing)."""
        if self.side is None:
            return 0
        self.plan()
        c = int(self.locate(np.asarray(s)[None])[0])
        if c < 0:
            return 0
        return int(np.argmax(self.Q_exploit[c] if self._knows_route(c) else self.Q_explore[c]))

    def _knows_route(self, c: int) -> bool:
        """Whether the exploit plan values leaf ``c`` above the lower bound (a known route)."""
        lo, hi = self._bounds()
        return not self.c.fallback or self.V_exploit[c] > lo + 0.05 * (hi - lo)
