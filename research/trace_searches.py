"""Every ``policy-net`` search of one agent as it learns, and its greedy returns (issue 46).

``GPQAgent(ENV, seed=SEED)`` with defaults learns ``--steps`` steps in ``learn(500)``
chunks (the control-suite protocol's checkpoints). Each search prints the transitions
stored, its seconds, who acts before and after, the model's score before and after,
the returns on record of the actor before, ``Q``'s returns on record and whether an actor
is on trial. Each checkpoint prints the greedy return of 10 episodes (evaluation seed
``10_000 + SEED``), who acts, and, where a policy acts, ``Q``'s greedy return with the
policy switched off for the evaluation.

    .venv/bin/python research/trace_searches.py Walker2d-v5 --seed 3

An env of one's own is named ``module:Id``, as ``gymnasium.make`` names it, e.g.
``PYTHONPATH=research/heldout ... cartpole_swingup:heldout/CartPoleSwingUp-v0``.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

CHUNK = 500


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=5000)
    args = parser.parse_args()

    from geoq.agents import GPQAgent
    from geoq.agents.policy_planning import FeedbackPlanning
    from geoq.experiments.control.evaluation import evaluate_agent

    search, seconds = FeedbackPlanning.search, {"search": 0.0}

    def traced(
        self: FeedbackPlanning, model: Any, n: int, rng: np.random.Generator, states: Any = None
    ) -> None:
        before = (self.acting, self.value, np.round(self.returns, 1).tolist(),
                  np.round(self.q_returns, 1).tolist())  # fmt: skip
        start = time.perf_counter()
        search(self, model, n, rng, states)
        took = time.perf_counter() - start
        seconds["search"] += took
        print(f"  search at {n}: {took:.1f} s, acting {before[0]} -> {self.acting}, score "
              f"{before[1]:.1f} -> {self.value:.1f}, returns {before[2]}, Q's {before[3]}, "
              f"on trial {self.kept is not None}", flush=True)  # fmt: skip

    FeedbackPlanning.search = traced  # type: ignore[method-assign]
    agent = GPQAgent(args.env, seed=args.seed)
    print("planner", agent.config.planner, flush=True)
    start = time.perf_counter()
    for k in range(args.steps // CHUNK):
        agent.learn(CHUNK)
        fb = agent.planning.feedback
        greedy = evaluate_agent(agent, args.env, 10, seed=10_000 + args.seed).returns.mean()
        q_greedy = None
        if fb.acting:  # Q's own greedy actions: no policy acting, none on trial
            kept, fb.acting, fb.kept = fb.kept, False, None
            q_greedy = evaluate_agent(agent, args.env, 10, seed=10_000 + args.seed).returns.mean()
            fb.acting, fb.kept = True, kept
        print(f"{(k + 1) * CHUNK}: greedy {greedy:.1f}, policy acting {fb.acting}, Q's greedy "
              f"{q_greedy}; learning {time.perf_counter() - start:.0f} s, searches "
              f"{seconds['search']:.0f} s", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
