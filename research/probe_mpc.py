"""Probe (issue 33): model-predictive control on learned GP models of a task's dynamics.

Not part of the package and not a speed benchmark: the measurement behind the design
notes' section "A learned dynamics model instead of values" (issue 33). It asks whether
the anchor the issue names (PILCO's ARD GP per output, Deisenroth & Rasmussen 2011)
gets InvertedPendulum and Reacher further than the GP Q agent.

Models, refitted when the data doubles (at most every 1,000 steps): the next-state
difference per output, the reward and (where the task has terminated) the termination,
each an exact GP mean on 300 of the transitions with ARD length-scales, amplitude and
noise from :func:`geoq.gp.evidence.fit_squared_exponential` on 400, inputs standardised
by the data. Away from the data the reward's prior is the least reward seen and the
termination's is 1 (pessimistic); ``--unknown K`` also halts a predicted roll-out at a
state-action farther from every transition than ``K`` x the 99th percentile of the
data's nearest-neighbour distances (MOReL's unknown-state detector, Kidambi et al.
2020); ``--local K`` adds back each model's residuals at the ``K`` nearest transitions
(Nadaraya-Watson at that spacing, shrunk to 0 where few are near): what the smooth
models miss at rare, non-smooth events (a rail, a joint's stop); ``--value`` scores a
plan's last state by a GP of the discounted returns-to-go seen from states. Actions: the
cross-entropy method over action sequences of ``--horizon`` steps (64 samples, 3
iterations, 8 elites, warm-started from the last plan), scored by the return the models
predict, weighted by the predicted survival. The first 200 steps act
uniformly at random. Nothing is set per task.

    python research/probe_mpc.py --env InvertedPendulum-v5 --seed 0 --steps 3000 \\
        --every 1000 --episodes 3 --unknown 2 [--horizon 50] [--local 10] [--value]

Each checkpoint prints the mean greedy return of ``--episodes`` episodes and each
episode's last observation (its first four entries). Needs the ``mujoco`` extra.
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from geoq.gp import NumericalWarning
from geoq.gp.evidence import fit_squared_exponential


@dataclass(frozen=True)
class Settings:
    horizon: int = 25
    unknown: float = 0.0
    """Halt at ``unknown`` x the data's spacing (0: never)."""
    local: int = 0
    """Correct each model by its residuals at the ``local`` nearest transitions (0: never)."""
    value: bool = False
    """Score a plan's last state by a GP of the discounted returns-to-go seen from states."""
    samples: int = 64
    iterations: int = 3
    elites: int = 8
    gamma: float = 0.99


class OutputGP:
    """Exact GP mean of one output on ``m`` points, hyper-parameters by the evidence."""

    def __init__(self, X, y, rng, prior_mean=None, fit_points=400, m=300):
        self.mu = float(y.mean()) if prior_mean is None else float(prior_mean)
        self.sd = float(np.sqrt(np.mean((y - self.mu) ** 2)))
        self.constant = self.sd < 1e-9
        if self.constant:
            return
        z = (y - self.mu) / self.sd
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalWarning)
            fit = fit_squared_exponential(X, z, max_points=fit_points, n_restarts=1, rng=rng)
        self.lengthscale = np.broadcast_to(fit.kernel.lengthscale, (X.shape[1],)).astype(float)
        self.variance = float(fit.kernel.variance)
        idx = rng.choice(len(X), size=min(m, len(X)), replace=False)
        self.points = X[idx] / self.lengthscale
        K = self.variance * np.exp(-0.5 * cdist(self.points, self.points, "sqeuclidean"))
        K[np.diag_indices_from(K)] += max(float(fit.noise), 1e-6)
        self.alpha = cho_solve(cho_factor(K, lower=True), z[idx])

    def __call__(self, Xq):
        if self.constant:
            return np.full(len(Xq), self.mu)
        d2 = cdist(Xq / self.lengthscale, self.points, "sqeuclidean")
        return self.mu + self.sd * (self.variance * np.exp(-0.5 * d2) @ self.alpha)


class Models:
    """Dynamics, reward and termination of the transitions ``(S, A, R, S2, D)``."""

    def __init__(self, S, A, R, S2, D, rng, unknown, local=0, ends=None, gamma=0.99):
        X = np.hstack([S, A])
        self.x_mean, self.x_std = X.mean(0), X.std(0) + 1e-8
        Xs = (X - self.x_mean) / self.x_std
        self.dynamics = [OutputGP(Xs, (S2 - S)[:, j], rng) for j in range(S.shape[1])]
        self.reward = OutputGP(Xs, R, rng, prior_mean=R.min())
        self.done = OutputGP(Xs, D.astype(float), rng, prior_mean=1.0) if D.any() else None
        self.unknown, self.local, self.r_min = unknown, local, float(R.min())
        self.tree = cKDTree(Xs) if unknown > 0 or local > 0 else None
        if self.tree is not None:
            probe = Xs[rng.choice(len(Xs), min(500, len(Xs)), replace=False)]
            self.spacing = float(np.quantile(self.tree.query(probe, k=2)[0][:, 1], 0.99))
        self.value = None
        if ends is not None:
            # Monte-Carlo returns-to-go within each episode (no bootstrap at its end).
            G, later = np.empty(len(R)), 0.0
            for i in range(len(R) - 1, -1, -1):
                later = R[i] + (0.0 if ends[i] or i == len(R) - 1 else gamma * later)
                G[i] = later
            d = S.shape[1]
            self.value = OutputGP(Xs[:, :d], G, rng, prior_mean=G.min())
        if local > 0:
            # What the smooth models miss at each transition (rare, non-smooth events).
            targets = np.column_stack([S2 - S, R, D.astype(float)])
            self.residuals = targets - self._smooth(Xs)

    def _smooth(self, Xs):
        out = [g(Xs) for g in self.dynamics] + [self.reward(Xs)]
        out.append(np.zeros(len(Xs)) if self.done is None else self.done(Xs))
        return np.column_stack(out)

    def step(self, S, A):
        """Predicted next states, rewards and termination probabilities of ``[P]`` pairs."""
        Xs = (np.hstack([S, A]) - self.x_mean) / self.x_std
        out = self._smooth(Xs)
        if self.tree is not None:
            dist, idx = self.tree.query(Xs, k=max(1, self.local))
            dist, idx = dist.reshape(len(Xs), -1), idx.reshape(len(Xs), -1)
            if self.local > 0:
                # Nadaraya-Watson on the residuals at the data's own spacing, shrunk to 0
                # where few transitions are that near.
                w = np.exp(-0.5 * (dist / self.spacing) ** 2)
                out += np.einsum("pk,pkj->pj", w, self.residuals[idx]) / (w.sum(1) + 1.0)[:, None]
        d = S.shape[1]
        S2, r, p = S + out[:, :d], out[:, d], np.clip(out[:, d + 1], 0.0, 1.0)
        if self.unknown > 0:
            unknown = dist[:, 0] > self.unknown * self.spacing
            r, p = np.where(unknown, self.r_min, r), np.where(unknown, 1.0, p)
        return S2, r, p


def plan_action(models, s, low, high, rng, plan, cfg):
    """The cross-entropy method's first action and the plan shifted by one step."""
    k, H, P = len(low), cfg.horizon, cfg.samples
    mean = plan if plan is not None else np.zeros((H, k))
    std = np.full((H, k), 0.5)
    for _ in range(cfg.iterations):
        U = np.clip(mean + std * rng.standard_normal((P, H, k)), -1.0, 1.0)
        U[0] = mean
        A = low + (U + 1.0) * 0.5 * (high - low)
        S, ret, alive = np.repeat(s[None], P, axis=0), np.zeros(P), np.ones(P)
        for t in range(H):
            S, r, p = models.step(S, A[:, t])
            ret += cfg.gamma**t * alive * r
            alive *= 1.0 - p
        if models.value is not None:
            d = len(s)
            ret += cfg.gamma**H * alive * models.value((S - models.x_mean[:d]) / models.x_std[:d])
        best = U[np.argsort(-ret)[: cfg.elites]]
        mean, std = best.mean(0), best.std(0) + 0.05
    return low + (mean[0] + 1.0) * 0.5 * (high - low), np.vstack([mean[1:], mean[-1:]])


def evaluate(env_id, models, seed, episodes, cfg):
    """Mean return of ``episodes`` planned episodes and each one's last observation."""
    env = gym.make(env_id)
    low, high = env.action_space.low.astype(float), env.action_space.high.astype(float)
    rng = np.random.default_rng(10_000 + seed)
    returns, ends = [], []
    for ep in range(episodes):
        s, _ = env.reset(seed=10_000 * (seed + 1) + ep)
        plan, total, done = None, 0.0, False
        while not done:
            a, plan = plan_action(models, s.astype(float), low, high, rng, plan, cfg)
            s, r, term, trunc, _ = env.step(a)
            total, done = total + float(r), term or trunc
        returns.append(total)
        ends.append(np.round(s[:4], 2).tolist())
    return float(np.mean(returns)), ends


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--every", type=int, default=1000)
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--unknown", type=float, default=0.0)
    ap.add_argument("--horizon", type=int, default=25)
    ap.add_argument("--local", type=int, default=0)
    ap.add_argument("--value", action="store_true")
    a = ap.parse_args()
    cfg = Settings(horizon=a.horizon, unknown=a.unknown, local=a.local, value=a.value)
    env = gym.make(a.env)
    rng = np.random.default_rng(a.seed)
    low, high = env.action_space.low.astype(float), env.action_space.high.astype(float)
    data: list[list] = [[], [], [], [], [], []]
    s, _ = env.reset(seed=a.seed)
    models, plan, next_fit, start = None, None, 200, time.time()
    for step in range(1, a.steps + 1):
        if models is None:
            act = rng.uniform(low, high)
        else:
            act, plan = plan_action(models, s.astype(float), low, high, rng, plan, cfg)
        s2, r, term, trunc, _ = env.step(act)
        for column, value in zip(data, (s, act, r, s2, term, term or trunc), strict=True):
            column.append(value)
        s = s2
        if term or trunc:
            (s, _), plan = env.reset(), None
        if step >= next_fit:
            arrays = [np.asarray(c, dtype=float) for c in data[:4]]
            done = np.asarray(data[4], dtype=bool)
            ends = np.asarray(data[5], dtype=bool) if cfg.value else None
            models = Models(*arrays, done, rng, cfg.unknown, cfg.local, ends, cfg.gamma)
            next_fit = min(2 * step, step + 1000)
        if step % a.every == 0 and models is not None:
            ret, ends = evaluate(a.env, models, a.seed, a.episodes, cfg)
            print(
                f"{a.env} seed {a.seed} step {step}: greedy return {ret:.1f} "
                f"({time.time() - start:.0f} s); last observations {ends}",
                flush=True,
            )


if __name__ == "__main__":
    main()
