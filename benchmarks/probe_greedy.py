"""What the greedy policy does while the agent learns: return, action size, prior.

Not a speed benchmark (``run.py`` does not run it): the probe behind the design notes'
section on tasks with more than three inputs. At each checkpoint it runs the greedy
evaluation of the control benchmark (:func:`geoq.experiments.control_eval.evaluate_agent`,
reset seeds from 10,000 + seed) and reports, over every greedy step taken:

- ``return``: the mean greedy return;
- ``|a|``: the mean absolute action in action half-ranges, ``sat`` the fraction of
  components within 5% of a bound;
- ``prior``: the fraction of steps whose chosen action's posterior std is >= 99% of the
  prior's, i.e. where the GP knows nothing of the (state, action) it acts on.

    python benchmarks/probe_greedy.py --env Reacher-v5 --seed 0 --steps 3000 --every 1000
    python benchmarks/probe_greedy.py --env Reacher-v5 --config '{"hyperparameters": "evidence"}'
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import gymnasium
import numpy as np

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent
from geoq.experiments.control_eval import evaluate_agent


class _Recorder:
    """The agent's greedy policy, recording what it chose and how much the GP knew."""

    def __init__(self, agent: GPQAgent) -> None:
        self.agent, self.env_id = agent, agent.env_id
        self.actions: list[np.ndarray] = []
        self.prior_fraction: list[np.ndarray] = []

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[np.ndarray, None]:
        agent = self.agent
        actions, _ = agent.predict(observation, deterministic=True)
        mean, std = agent.q_candidates(np.atleast_2d(observation))
        chosen = std[np.arange(len(std)), np.argmax(mean, axis=1)]
        prior_std = agent.state.y_scale * np.sqrt(agent.config.amplitude)
        self.actions.append(np.atleast_2d(actions))
        self.prior_fraction.append(chosen >= 0.99 * prior_std)
        return actions, None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="Reacher-v5")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=3_000)
    parser.add_argument("--every", type=int, default=1_000)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--config", default="{}", help="JSON object of GPQConfig fields")
    args = parser.parse_args()
    agent = GPQAgent(gymnasium.make(args.env), seed=args.seed, **json.loads(args.config))
    half = 0.5 * (agent.action_high - agent.action_low)
    centre = 0.5 * (agent.action_high + agent.action_low)
    print(f"{args.env} seed {args.seed} {args.config} max_bv {agent.max_bv}")
    done, learn_s = 0, 0.0
    while done < args.steps:
        t0 = time.perf_counter()
        agent.learn(args.every)
        learn_s += time.perf_counter() - t0
        done += args.every
        rec = _Recorder(agent)
        ev = evaluate_agent(rec, args.env, args.episodes, seed=10_000 + args.seed)
        size = np.abs(np.concatenate(rec.actions) - centre) / half
        ls = agent.state.fitted_lengthscale
        prior = np.mean(np.concatenate(rec.prior_fraction))
        print(
            f"{done:6d} return {np.mean(ev.returns):9.2f}  |a| {size.mean():.2f}  "
            f"sat {np.mean(size >= 0.95):.2f}  prior {prior:.2f}"
            f"  {1e3 * learn_s / done:.1f} ms/step"
            + ("" if ls is None else f"  lengthscales {np.round(ls, 2).tolist()}"),
            flush=True,
        )


if __name__ == "__main__":
    main()
