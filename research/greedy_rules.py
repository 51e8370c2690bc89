"""Where ``Q``'s greedy action is sought, compared on saved agents (issue 46, part nineteen).

Agents saved at each checkpoint by ``research/checkpoint_actors.py --save DIR`` are
loaded, and 10 greedy episodes (evaluation seed ``10_000 + SEED``, as the benchmark's)
are run with ``Q``'s greedy action sought:

- ``q``: among the agent's candidates (``greedy_actions="candidates"``; the default in 1-D);
- ``dense``: among the candidates and 256 more scrambled Sobol' points of the box;
- ``near``: among the actions taken at the ``K`` stored states nearest the state
  (``K`` the candidates' count), every state input counting alike (the scaled states);
- ``data``: ``greedy_actions="data"`` (:mod:`geoq.agents.greedy_data`): the same, near
  in the kernel's metric (the scaled states over the state length-scales);
- ``nn``: the action taken at the nearest stored state (``near``'s metric), ``Q`` unasked
  (part thirty-two: whether ``Q``'s choice among the neighbours' actions adds anything);
- ``target``: of ``near``'s neighbours, the action of the one whose stored target (its
  return-to-go by ``Q`` at its own state and action, not at ``obs``) is highest.

No policy acts in any of these: they are ``Q``'s alone. Learning is not involved::

    python research/checkpoint_actors.py Walker2d-v5 --seed 3 --save runs/w3
    python research/greedy_rules.py Walker2d-v5 --seed 3 --load runs/w3 --rules q,dense,near,data
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.stats

EPISODES = 10
DENSE = 8  # 2^8 further Sobol' points


class _Greedy:
    """``agent``'s ``Q`` acting greedily by ``rule`` (module docstring)."""

    def __init__(self, agent: Any, rule: str):
        self.agent, self.rule, self.env_id = agent, rule, agent.env_id
        low, high = agent.action_low, agent.action_high
        sobol = scipy.stats.qmc.Sobol(d=low.size, scramble=True, seed=0).random_base2(DENSE)
        self.dense = np.vstack([agent.candidates, low + (high - low) * sobol])
        stored = agent.buffer.transitions(last=agent.config.window)
        self.scale = np.asarray(agent.scaling.scale[: agent.obs_dim])
        self.states, self.actions = stored.states / self.scale, stored.actions
        self.targets = agent.buffer.targets(last=len(stored))

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        a, n = self.agent, obs.shape[0]
        if self.rule == "q":
            mean, _ = a.q_candidates(obs)
            return a.candidates[np.argmax(mean, axis=1)], None
        if self.rule == "dense":
            C = np.broadcast_to(self.dense, (n, *self.dense.shape))
        else:  # near, nn, target
            r2 = ((obs / self.scale)[:, None, :] - self.states[None, :, :]) ** 2
            order = np.argsort(r2.sum(axis=2), axis=1, kind="stable")[:, : len(a.candidates)]
            C = self.actions[order]
            if self.rule == "nn":
                return C[:, 0], None
            if self.rule == "target":
                return C[np.arange(n), np.argmax(self.targets[order], axis=1)], None
        k = C.shape[1]
        X = a.inputs(np.repeat(obs, k, axis=0), np.ascontiguousarray(C).reshape(n * k, -1))
        return C[np.arange(n), np.argmax(a.gp.predict(X).reshape(n, k), axis=1)], None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--load", type=Path, required=True, help="checkpoint_actors' --save")
    parser.add_argument("--rules", default="q,dense,near,data")
    args = parser.parse_args()

    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent

    rules = args.rules.split(",")
    print("steps | " + " | ".join(rules), flush=True)
    for path in sorted(args.load.glob("*.npz"), key=lambda p: int(p.stem.split("_")[-1])):
        agent = GPQAgent.load(path, env=args.env)
        agent.planning.feedback.acting, agent.planning.feedback.kept = False, None  # Q's own
        returns = []
        for rule in rules:
            if rule == "data":
                agent.config = replace(agent.config, greedy_actions="data")
            actor = agent if rule == "data" else _Greedy(agent, rule)
            episodes = evaluate_agent(actor, args.env, EPISODES, seed=10_000 + args.seed)
            returns.append(f"{episodes.returns.mean():.1f}")
            agent.config = replace(agent.config, greedy_actions="candidates")
        print(f"{path.stem.split('_')[-1]} | " + " | ".join(returns), flush=True)


if __name__ == "__main__":
    main()
