"""Who a checkpoint measures, and what the others would have returned there (issue 46).

``GPQAgent(ENV, seed=SEED)`` with defaults (or ``--config``'s settings) learns
``--steps`` steps in ``learn(500)`` chunks (the control-suite protocol's checkpoints).
At each checkpoint it prints the mean greedy return of 10 episodes (evaluation seed
``10_000 + SEED``, as the benchmark measures) of:

- the agent, as the checkpoint measures it (the policy where it acts, else ``Q``);
- ``Q``'s own greedy actions (the candidates' best posterior mean), policy or not;
- ``Q``'s candidates scored by ``mean - std`` instead (a pessimistic greedy: whether
  the greedy returns' swings come from where ``Q`` is unsure of its actions);
- the weights the last search found (a policy through the model), acting or not;
- ``Q`` alone: a copy of the agent with the policy set aside, so ``Q`` acts as it would
  with no planner (its greedy actions by the agent's own rule: the data's, the actor's);

and how many evidence fits ran, and how many of them ran again on more points
(``evidence_points_blind``). ``--config FILE`` takes a JSON file of ``GPQConfig``
settings, as ``geoq bench-control --config`` does.

None of these evaluations changes what the agent learns (greedy actions draw nothing
from its generator), so the agent's own column is the benchmark's curve::

    .venv/bin/python research/checkpoint_actors.py Walker2d-v5 --seed 3
    .venv/bin/python research/checkpoint_actors.py HalfCheetah-v5 --seed 3 --config b1000.json

``--save DIR`` saves the agent at each checkpoint as ``DIR/agent_STEPS.npz`` (what
``research/greedy_rules.py`` reads).
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

CHUNK = 500
EPISODES = 10


class _QGreedy:
    """``Q``'s greedy actions by the candidates' ``mean + k std`` (no policy)."""

    def __init__(self, agent: Any, k: float):
        self.agent, self.k, self.env_id = agent, k, agent.env_id

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        mean, std = self.agent.q_candidates(obs)
        return self.agent.candidates[np.argmax(mean + self.k * std, axis=1)], None


class _Weights:
    """The policy with the weights the last search found."""

    def __init__(self, agent: Any):
        self.feedback, self.env_id = agent.planning.feedback, agent.env_id

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        return self.feedback.policy.act(self.feedback.gains, obs), None


def _q_alone(agent: Any) -> Any:
    """A copy of ``agent`` whose policy neither acts nor is on trial: ``Q`` acts."""
    alone = copy.deepcopy(agent)
    alone.planning.feedback.acting = False
    alone.planning.feedback.kept = None
    return alone


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--save", type=Path, default=None, help="folder for the agents")
    parser.add_argument("--config", type=Path, default=None, help="JSON file of settings")
    args = parser.parse_args()
    if args.save is not None:
        args.save.mkdir(parents=True, exist_ok=True)

    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent

    def greedy(actor: Any) -> float:
        return float(evaluate_agent(actor, args.env, EPISODES, seed=10_000 + args.seed)
                     .returns.mean())  # fmt: skip

    settings = json.loads(args.config.read_text()) if args.config is not None else {}
    agent = GPQAgent(args.env, seed=args.seed, **settings)
    print("steps | agent | Q | Q, mean - std | weights found | policy acts | Q alone | fits "
          "(run again)", flush=True)  # fmt: skip
    start = time.perf_counter()
    for k in range(args.steps // CHUNK):
        agent.learn(CHUNK)
        if args.save is not None:
            agent.save(args.save / f"agent_{(k + 1) * CHUNK}.npz")
        feedback = agent.planning.feedback
        found = greedy(_Weights(agent)) if feedback.policy is not None else float("nan")
        fits = agent.log.evidence_fits
        print(f"{(k + 1) * CHUNK} | {greedy(agent):.1f} | {greedy(_QGreedy(agent, 0.0)):.1f} | "
              f"{greedy(_QGreedy(agent, -1.0)):.1f} | {found:.1f} | "
              f"{feedback.greedy_weights is not None} | {greedy(_q_alone(agent)):.1f} | "
              f"{len(fits)} ({sum('first_fit' in fit for fit in fits)})  "
              f"({time.perf_counter() - start:.0f} s)", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
