"""Probe (issue 46): what a saved planning agent's greedy plans do with another model or value.

Not a speed benchmark: the measurements behind the design notes' section "Planning
through a learned GP model", part two (why the plans drift to InvertedPendulum's rail).
It loads an agent saved by ``probe_planner.py --save DIR`` and runs ``--episodes``
greedy episodes (reset seeds ``10_000 + 100 seed + episode``) with its greedy planner,
changing one thing at a time:

* ``--refit JSON``: the model refitted on the agent's transitions with these
  :class:`geoq.models.ModelSettings` fields (``--refit-seed``, ``--fit-range a:b``);
* ``--value``: the plans' terminal value. ``none`` (as ``planner="cem"``); ``q`` (the
  agent's Q, as ``"cem-q"``); ``knn`` (the behaviour's value: kernel-smoothed TD(0) on the
  stored transitions, ``V = r + gamma (1 - term) mean_kNN V(s')``, solved exactly);
  ``mvi`` (fitted value iteration *under the model* on the stored states, Gordon's
  averagers: ``V(s_i) = max_k r + gamma V(s'_ik)`` over the candidate actions, a
  successor off the support worth the least reward for ever);
* ``--events``: a GP on the model's outlier flags (the transitions its state changes
  leave out, ``outlier_mads`` 6 when the refit sets none), read as a probability of a
  break: the roll-outs halt with it (``--events-dp-only``: only the value iteration
  does), and ``--support-events`` adds its length-scales to the support's metric.

Plans are scored on the model's mean roll-outs (``--sampled``: one draw of the model
per particle and step, as the agent's plans). ``--diagnose`` prints the model's
length-scales and its one-step errors on the outliers and on the rest::

    python research/probe_planner.py --env InvertedPendulum-v5 --seed 1 --steps 2000 \\
        --every 1000 --episodes 3 --save runs/ip
    python research/probe_model_fixes.py runs/ip/InvertedPendulum-v5_cem_s1_2000.npz \\
        --seed 1 --refit '{"outlier_mads": 6}' --value mvi --diagnose
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from scipy import sparse
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from geoq.agents import GPQAgent
from geoq.gp import SparseOnlineGP
from geoq.gp.evidence import fit_squared_exponential
from geoq.kernels.stationary import SquaredExponential
from geoq.models import GPDynamicsModel, ModelSettings, PlannerSettings, model_returns
from geoq.models.support import StateSupport

Array = np.ndarray


class KnnValue:
    """The behaviour's value on the stored transitions: ``V = r + gamma (1 - term) W V`` with
    ``W`` the mean over the ``k`` stored states nearest each ``s'`` (solved exactly)."""

    def __init__(self, S: Array, R: Array, S2: Array, T: Array, scale: Array, gamma: float,
                 k: int) -> None:  # fmt: skip
        self.scale, self.k = scale, k
        self.tree = cKDTree(S / scale)
        _, idx = self.tree.query(S2 / scale, k=k)
        n = len(R)
        W = sparse.csr_array(
            (np.full(n * k, 1.0 / k), (np.repeat(np.arange(n), k), idx.ravel())), shape=(n, n)
        )
        A = sparse.eye(n, format="csr") - gamma * sparse.diags(1.0 - T) @ W
        self.V = spsolve(A.tocsc(), R)
        self.floor = float(self.V.min())

    def __call__(self, S: Array, A: Array | None = None) -> Array:
        return self.V[self.tree.query(S / self.scale, k=self.k)[1]].mean(axis=1)


class ModelValue:
    """Fitted value iteration under the model on the stored states (module docstring)."""

    def __init__(self, model: GPDynamicsModel, S: Array, candidates: Array, gamma: float,
                 k: int = 8, sweeps: int = 500,
                 event: Callable[[Array, Array], Array] | None = None,
                 soft: bool = False) -> None:  # fmt: skip
        d, N, K = model.obs_dim, len(S), len(candidates)
        self.scale, self.k = model.x_scale[:d], k
        SS, AA = np.repeat(S, K, axis=0), np.tile(candidates, (N, 1))
        mean = np.vstack([model.predict_mean(SS[i : i + 4096], AA[i : i + 4096])
                          for i in range(0, len(SS), 4096)])  # fmt: skip
        S2 = SS + mean[:, :d]
        reward, ends = mean[:, d], mean[:, d + 1] > 0.5
        off = (model.support.distance(S2) > 1.0).astype(float)
        if event is not None:  # a predicted break: the least reward for ever, as off the data
            off = np.maximum(off, event(SS, AA) if soft else (event(SS, AA) > 0.5))
        self.floor = float(model.reward_range[0]) / (1 - gamma)
        self.tree = cKDTree(S / self.scale)
        idx = self.tree.query(S2 / self.scale, k=k)[1]
        going = np.where(ends, 0.0, 1.0 - off)
        tail = np.where(ends, 0.0, off * gamma * self.floor)
        V = np.full(N, self.floor)
        for self.sweeps in range(1, sweeps + 1):
            new = (reward + tail + gamma * going * V[idx].mean(axis=1)).reshape(N, K).max(axis=1)
            change, V = np.max(np.abs(new - V)), new
            if change < 1e-6:
                break
        self.V = V

    def __call__(self, S: Array, A: Array | None = None) -> Array:
        return self.V[self.tree.query(S / self.scale, k=self.k)[1]].mean(axis=1)


def event_model(model: GPDynamicsModel, data: tuple[Array, ...], rng: np.random.Generator,
                ) -> tuple[Callable[[Array, Array], Array], Array]:  # fmt: skip
    """A GP on the model's outlier flags (6 MADs when its settings test none): the
    probability ``[P]`` that a step breaks the smooth model, and its length-scales."""
    X, Y = model._outputs(*data)
    Xs = (X - model.x_mean) / model.x_scale
    if model.settings.outlier_mads <= 0:
        tester = GPDynamicsModel(model.obs_dim, model.action_dim, ModelSettings(outlier_mads=6.0))
        tester.fit(*data, rng)
        flags = tester._outliers(Xs, Y).astype(float)
    else:
        flags = model._outliers(Xs, Y).astype(float)
    mean, std = flags.mean(), max(flags.std(), 1e-12)
    fit = fit_squared_exponential(Xs, (flags - mean) / std, max_points=300, n_restarts=1, rng=rng)
    kernel = SquaredExponential(fit.kernel.lengthscale, variance=float(fit.kernel.variance))
    gp = SparseOnlineGP(kernel, noise=max(float(fit.noise), 1e-6 * float(kernel.variance)),
                        max_bv=200).fit(Xs, (flags - mean) / std)  # fmt: skip
    print(f"events: {int(flags.sum())} of {len(flags)}")

    def probability(S: Array, U: Array) -> Array:
        x = (np.hstack([S, U]) - model.x_mean) / model.x_scale
        return np.asarray(np.clip(mean + std * gp.predict(x), 0.0, 1.0))

    return probability, np.broadcast_to(kernel.lengthscale, (Xs.shape[1],))


def event_returns(
    model: GPDynamicsModel, s0: Array, U: Array, gamma: float, value: Any, floor: float,
    event: Callable[[Array, Array], Array],
) -> Array:  # fmt: skip
    """``model_returns`` with a predicted break halting a roll-out like leaving the data."""
    P, H1, _ = U.shape
    d, H, least = model.obs_dim, H1 - 1, float(model.reward_range[0])
    S, alive, total = np.repeat(s0[None, :], P, axis=0), np.ones(P), np.zeros(P)
    after = gamma**H * floor if value is not None else 0.0
    for t in range(H):
        mean, breaks = model.predict_mean(S, U[:, t]), event(S, U[:, t])
        S = S + mean[:, :d]
        ends = mean[:, d + 1] > 0.5
        off = np.clip(model.support.distance(S) - 1.0, 0.0, 1.0)
        unknown = np.where(ends, 0.0, np.maximum(off, breaks))
        rest = sum(gamma**k for k in range(t + 1, H)) * least + after
        total += alive * (gamma**t * mean[:, d] + unknown * rest)
        alive = alive * ~ends * (1.0 - unknown)
    if value is not None:
        total += gamma**H * alive * value(S, U[:, -1])
    return total


def diagnose(model: GPDynamicsModel, data: tuple[Array, ...], rng: np.random.Generator) -> None:
    """Length-scales per output, and one-step errors on the outliers and on the rest."""
    D = model.obs_dim + model.action_dim
    for j, gp in enumerate(model.gps):
        if gp is not None:
            ls = np.broadcast_to(gp.kernel.lengthscale, (D,))
            print(f"  output {j}: length-scales {np.round(ls, 2)}, variance "
                  f"{float(gp.kernel.variance):.3g}, {gp.n_bv} basis vectors")  # fmt: skip
    S, A, _, S2, _ = data
    X, Y = model._outputs(*data)
    tester = GPDynamicsModel(model.obs_dim, model.action_dim, ModelSettings(outlier_mads=6.0))
    flags = tester.fit(*data, rng)._outliers((X - tester.x_mean) / tester.x_scale, Y)
    error = np.abs(S + model.predict_mean(S, A)[:, : model.obs_dim] - S2)
    print(f"  one-step |error| on the {flags.sum()} outliers: {np.round(error[flags].mean(0), 5)}; "
          f"on the rest: {np.round(error[~flags].mean(0), 5)}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("path")
    ap.add_argument("--env", default=None, help="Gymnasium id (default: the agent's)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--max-steps", type=int, default=1000)
    ap.add_argument("--planner", default="{}", help="PlannerSettings fields as JSON")
    ap.add_argument("--refit", default=None, help="ModelSettings fields as JSON")
    ap.add_argument("--refit-seed", type=int, default=0)
    ap.add_argument("--fit-range", default=None, help="a:b, the stored rows the refit uses")
    ap.add_argument("--value", default="none", choices=["none", "q", "knn", "mvi"])
    ap.add_argument("--k", type=int, default=8, help="neighbours of knn and mvi")
    ap.add_argument("--events", action="store_true")
    ap.add_argument("--events-dp-only", action="store_true")
    ap.add_argument("--support-events", action="store_true")
    ap.add_argument("--soft-events", action="store_true", help="mvi: a break's probability")
    ap.add_argument("--diagnose", action="store_true")
    ap.add_argument("--sampled", action="store_true", help="sampled roll-outs (the agent's)")
    a = ap.parse_args()
    warnings.simplefilter("ignore")  # the evidence fits' bound warnings
    agent = GPQAgent.load(a.path)
    env_id = a.env or agent.env_id
    planning, gamma = agent.planning, agent.config.gamma
    planning.greedy.settings = PlannerSettings(**json.loads(a.planner))
    data = agent.buffer.arrays(last=agent.config.window)
    if a.fit_range:
        data = tuple(c[slice(*(int(v) for v in a.fit_range.split(":")))] for c in data)
    rng = np.random.default_rng(a.refit_seed)
    if a.refit is not None:
        settings = ModelSettings(**json.loads(a.refit))
        planning.model = GPDynamicsModel(agent.obs_dim, agent.action_dim, settings)
        planning.model.fit(*data, rng)
    model = planning.model
    if a.diagnose:
        diagnose(model, data, rng)
    event = None
    if a.events:
        event, event_ls = event_model(model, data, rng)
        if a.support_events:
            d = model.obs_dim
            relevance = [np.broadcast_to(gp.kernel.lengthscale, (len(event_ls),))[:d]
                         for gp in model.gps if gp] + [event_ls[:d]]  # fmt: skip
            scale = model.x_scale[:d] * np.min(relevance, axis=0)
            model.support = StateSupport(np.vstack([data[0], data[3]]), scale, rng)
    value: Any = None
    floor = 0.0
    if a.value == "knn":
        value = KnnValue(data[0], data[2], data[3], data[4].astype(float),
                         model.support.scale, gamma, a.k)  # fmt: skip
    elif a.value == "mvi":
        value = ModelValue(model, data[0], agent.candidates, gamma, k=a.k, event=event,
                           soft=a.soft_events)  # fmt: skip
    elif a.value == "q":
        lo, hi = agent.value_bounds()

        def value(S: Array, A: Array) -> Array:
            m = agent.gp.predict(agent.inputs(S, A))
            return np.clip(agent.state.y_mean + agent.state.y_scale * m, lo, hi)

        floor = lo
    if isinstance(value, KnnValue | ModelValue):
        floor = value.floor
        print(f"value {a.value}: V in [{value.V.min():.1f}, {value.V.max():.1f}]")

    def action(agent_: GPQAgent, s: Array, rng_: np.random.Generator | None) -> Array:
        plan_rng = np.random.default_rng([agent_.seed or 0, agent_.num_timesteps])

        def score(U: Array) -> Array:
            if event is not None and not a.events_dp_only:
                return event_returns(model, s[0], U, gamma, value, floor, event)
            return model_returns(model, s[0], U, gamma=gamma, value=value, value_floor=floor,
                                 rng=plan_rng if a.sampled else None)  # fmt: skip

        return planning.greedy.plan(score, plan_rng)[None, :]

    planning.action = action  # type: ignore[method-assign]
    env, returns, ends, steps, start = gym.make(env_id), [], [], 0, time.perf_counter()
    for e in range(a.episodes):
        planning.greedy.reset()
        obs, _ = env.reset(seed=10_000 + 100 * a.seed + e)
        total, done, n = 0.0, False, 0
        while not done and n < a.max_steps:
            obs, r, terminated, truncated, _ = env.step(agent.predict(obs)[0])
            total, done, n = total + float(r), terminated or truncated, n + 1
        steps += n
        returns.append(round(total, 1))
        ends.append(np.round(obs[:2], 2).tolist())
    print(f"{a.path.rsplit('/', 1)[-1]} refit={a.refit} value={a.value} events={a.events} "
          f"sampled={a.sampled} "
          f"{a.planner}: greedy {np.mean(returns):.1f} {returns}, last states {ends}; "
          f"{1000 * (time.perf_counter() - start) / steps:.1f} ms/step")  # fmt: skip


if __name__ == "__main__":
    main()
