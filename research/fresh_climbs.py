"""Whether a saved agent's policy search is held in a local optimum: climbs from fresh
weights beside climbs from the acting ones (issue 46, part twenty-nine).

On an agent saved by ``research/checkpoint_actors.py --save DIR`` whose ``policy-net``
search has stopped finding better weights, this runs ``--searches`` searches in a row
(:func:`geoq.models.search_policy` with the agent's own model, settings, starts and
branch states, each search's whole budget) from the acting weights, and the same from
``--restarts`` fresh draws of initial weights (``MLPFeedback.initial``, as a first
search draws them), each chain's weights then measured on the task: 10 greedy episodes,
evaluation seed ``10_000 + SEED``, beside the model's score. Draws from
``numpy.random.default_rng(--rng)``; the agent itself is not changed::

    PYTHONPATH=research/heldout .venv/bin/python research/checkpoint_actors.py \\
        cartpole_swingup:heldout/CartPoleSwingUp-v0 --seed 8 --steps 1000 --save DIR
    PYTHONPATH=research/heldout .venv/bin/python research/fresh_climbs.py \\
        cartpole_swingup:heldout/CartPoleSwingUp-v0 DIR/agent_1000.npz --seed 8
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

EPISODES = 10


class _Weights:
    """A policy of fixed weights, as the evaluation calls an agent."""

    def __init__(self, policy: Any, params: np.ndarray, env_id: str):
        self.policy, self.params, self.env_id = policy, params, env_id

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        return self.policy.act(self.params, obs), None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("agent", type=Path, help="an agent saved with a policy-net search")
    parser.add_argument("--seed", type=int, default=0, help="the agent's seed (evaluation)")
    parser.add_argument("--searches", type=int, default=3)
    parser.add_argument("--restarts", type=int, default=4)
    parser.add_argument("--rng", type=int, default=0)
    args = parser.parse_args()

    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent
    from geoq.models import search_policy

    agent = GPQAgent.load(args.agent)
    planning, rng = agent.planning, np.random.default_rng(args.rng)
    feedback, model = planning.feedback, planning.model
    if feedback.policy is None:
        raise SystemExit(f"{args.agent} has searched no policy yet")
    states = agent.buffer.arrays(last=planning.window)[0]

    def chain(params: np.ndarray) -> tuple[np.ndarray, list[float]]:
        scores = []
        for _ in range(args.searches):
            params, value = search_policy(model, feedback.policy, params, feedback.starts, rng,
                                          feedback.gradient_settings, states)  # fmt: skip
            scores.append(value)
        return params, scores

    def task(params: np.ndarray) -> float:
        actor = _Weights(feedback.policy, params, args.env)
        return float(evaluate_agent(actor, args.env, EPISODES, seed=10_000 + args.seed)
                     .returns.mean())  # fmt: skip

    print(f"acting weights: task {task(feedback.gains):.1f}, model {feedback.value:.1f}")
    starts = [("acting", feedback.gains)] + [
        (f"fresh {k}", feedback.policy.initial(rng)) for k in range(args.restarts)
    ]
    for name, params in starts:
        found, scores = chain(params)
        print(f"{name}: model after each search {' / '.join(f'{v:.1f}' for v in scores)}; "
              f"task {task(found):.1f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
