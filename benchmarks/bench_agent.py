"""GPQAgent speed: one environment step (act + online update), a fitted-Q phase, predict,
and the cost of each replay mode per episode.

Goals (issue 9): one step of ``learn`` (act + update, amortised fitted-Q phases
included) <= 2 ms at 200 BVs; ``predict`` <= 1 ms; 10,000 steps in under a
minute. Replay (issue 11): a phase with ``replay="graph"`` against ``"uniform"``
on the same stored transitions, per 250-step episode (goal: graph replay under 1 s
per episode at 200 BVs). Baselines in the same process: the GP's own ``predict`` on the same
candidate batch and ``update`` of one point (the floor an agent step cannot go
below), and the raw swing-up env step.

Per-step figures are of a warm process: a short run first loads the compiled
functions (numba's on-disk cache) and the lazily imported modules, a one-off cost
printed on its own ("start-up") and not spread over the steps measured.
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import gymnasium
import numpy as np

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent

ENV = "geoq/PendulumSwingUp-v0"


def _per_call(fn, repeat: int) -> float:  # type: ignore[no-untyped-def]
    fn()
    start = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - start) / repeat


def _warm_up(steps: int) -> None:
    """Run every compiled path once (both replays) and print what the first run cost
    beyond an identical second one: the process's one-off start-up."""
    times = []
    for _ in range(2):
        start = time.perf_counter()
        for replay in ("uniform", "graph"):
            GPQAgent(ENV, max_bv=20, seed=0, replay=replay).learn(steps)
        times.append(time.perf_counter() - start)
    print(f"start-up (imports, compiled-code cache loads): {times[0] - times[1]:.2f} s, once")


def main(quick: bool = False) -> None:
    """``quick``: tiny sizes, figures of no meaning (``benchmarks/run.py --quick``)."""
    warnings.simplefilter("ignore")
    _warm_up(60 if quick else 300)
    env = gymnasium.make(ENV)
    env.reset(seed=0)
    t_env = _per_call(lambda: env.step(np.array([1.0])), 20 if quick else 2_000)
    print(f"raw env step: {1e6 * t_env:.0f} us")
    print(f"{'max_bv':>6} {'learn ms/step':>14} {'of which fitted-Q (phases)':>26} "
          f"{'predict ms':>11} {'GP predict+update ms':>21} {'agent / GP':>10}")  # fmt: skip
    repeat = 3 if quick else 300
    for max_bv in (20,) if quick else (200, 400):
        agent = GPQAgent(ENV, max_bv=max_bv, seed=0)
        n = 100 if quick else 1_500
        start = time.perf_counter()
        agent.learn(n)
        t_learn = (time.perf_counter() - start) / n
        phases = len(agent.log.fitted_q_sweeps)
        t_train = agent.log.train_seconds / n  # the phases learn() ran, per step
        obs = np.array([0.3, -1.0])
        t_predict = _per_call(lambda: agent.predict(obs), repeat)  # noqa: B023
        X = agent.scaling.transform_pairs(obs[None, :], agent.candidates)
        x = agent.inputs(obs[None, :], np.array([[1.0]]))[0]
        t_gp = _per_call(lambda: agent.gp.predict(X, return_std=True), repeat)  # noqa: B023
        t_gp += _per_call(lambda: agent.gp.update(x, 0.0), repeat)  # noqa: B023
        print(
            f"{max_bv:>6} {1e3 * t_learn:>14.2f} {1e3 * t_train:>17.2f} ({phases:>3} phases) "
            f"{1e3 * t_predict:>11.2f} {1e3 * t_gp:>21.2f} {t_learn / t_gp:>10.1f}x"
        )
        replay_costs = []
        default = agent.config
        for replay in ("none", "uniform", "graph"):  # same transitions, same basis
            agent.config = dataclasses.replace(default, replay=replay)
            replay_costs.append(_per_call(agent.train, 2))
        agent.config = default
        print(
            f"{'':>6} one phase on all {n} transitions: none "
            f"{replay_costs[0]:.2f} s, uniform {replay_costs[1]:.2f} s, graph "
            f"{replay_costs[2]:.2f} s ({replay_costs[2] / replay_costs[1]:.1f}x uniform)"
        )
    if quick:
        _replay_cost_per_episode(max_bv=20, episodes=1, steps=50)
    else:
        _replay_cost_per_episode()


def _replay_cost_per_episode(max_bv: int = 200, episodes: int = 6, steps: int = 250) -> None:
    """Fitted-Q + replay seconds per 250-step swing-up episode while learning, each replay
    mode from the same seed (the replay issue's goal: graph under 1 s at 200 BVs)."""
    for replay in ("uniform", "graph"):
        agent = GPQAgent(ENV, max_bv=max_bv, seed=0, replay=replay)
        per_episode = []
        for _ in range(episodes):
            before = agent.log.train_seconds
            agent.learn(steps)
            per_episode.append(agent.log.train_seconds - before)
        print(
            f"{max_bv:>6} {replay:>7} replay while learning: fitted-Q + replay s per episode "
            + " ".join(f"{t:.2f}" for t in per_episode)
            + f" (max {max(per_episode):.2f}, {len(agent.log.fitted_q_sweeps)} phases)"
        )


if __name__ == "__main__":
    main()
