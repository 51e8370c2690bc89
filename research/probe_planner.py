"""Probe (issue 46): ``GPQAgent(planner="cem")`` on a task, greedy returns as it learns.

Not a speed benchmark: the measurement behind the design notes' section "Planning
through a learned GP model in the agent". The agent is ``GPQAgent(env_id, seed=seed,
planner=mode)`` (``--mode cem``, ``cem-q``, ``policy`` or ``policy-net``) with every
other setting its default; ``--planner`` overrides fields of
:class:`geoq.models.PlannerSettings` (for both the training and the greedy plans),
``--model`` those of :class:`geoq.models.ModelSettings`;
``--save DIR`` keeps the agent of every checkpoint (for ``probe_model_fixes.py``).
Every ``--every`` steps it prints the mean greedy return of ``--episodes`` episodes
(reset seeds ``10_000 + 100 seed + episode``, held out from training), the learning's
wall time so far and the greedy plan's time per step.

    python research/probe_planner.py --env InvertedPendulum-v5 --seed 0 --steps 2000 \\
        --every 500 --episodes 3 [--planner '{"horizon": 15, "samples": 128}']

Needs the ``mujoco`` extra for Gymnasium's MuJoCo tasks.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np

from geoq.agents import GPQAgent
from geoq.models import GPDynamicsModel, ModelSettings, PlannerSettings


def greedy_returns(agent: GPQAgent, env_id: str, seed: int, episodes: int) -> tuple[list, int]:
    """Each held-out episode's return, and the steps they took."""
    env, returns, steps = gym.make(env_id), [], 0
    for e in range(episodes):
        obs, _ = env.reset(seed=10_000 + 100 * seed + e)
        total, done = 0.0, False
        while not done:
            obs, r, terminated, truncated, _ = env.step(agent.predict(obs)[0])
            total, done, steps = total + float(r), terminated or truncated, steps + 1
        returns.append(round(total, 1))
    return returns, steps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--every", type=int, default=500)
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--planner", default="{}", help="PlannerSettings fields as JSON")
    ap.add_argument("--mode", default="cem", choices=["cem", "cem-q", "policy", "policy-net"])
    ap.add_argument("--save", default=None, help="save the agent at each checkpoint in DIR")
    ap.add_argument("--model", default="{}", help="ModelSettings fields as JSON")
    a = ap.parse_args()
    warnings.simplefilter("ignore")  # the evidence fits' bound warnings, one per output
    agent = GPQAgent(a.env, seed=a.seed, planner=a.mode)
    if json.loads(a.model):  # else the agent's own (``policy``'s differs from the default)
        agent.planning.model = GPDynamicsModel(agent.obs_dim, agent.action_dim,
                                               ModelSettings(**json.loads(a.model)))  # fmt: skip
    settings = PlannerSettings(**json.loads(a.planner))
    for planner in (agent.planning.training, agent.planning.greedy):
        planner.settings = settings
    learning, done = 0.0, 0
    while done < a.steps:
        t0 = time.perf_counter()
        agent.learn(a.every)
        learning += time.perf_counter() - t0
        done += a.every
        if a.save:
            Path(a.save).mkdir(parents=True, exist_ok=True)
            agent.save(Path(a.save) / f"{a.env.replace('/', '-')}_{a.mode}_s{a.seed}_{done}.npz")
        t1 = time.perf_counter()
        returns, steps = greedy_returns(agent, a.env, a.seed, a.episodes)
        per_step = 1000 * (time.perf_counter() - t1) / steps
        print(
            f"{a.env} seed {a.seed} {a.mode} {a.planner} {a.model} step {done}: "
            f"greedy {np.mean(returns):.1f} {returns}; learning {learning:.0f} s; "
            f"greedy plan {per_step:.1f} ms/step",
            flush=True,
        )


if __name__ == "__main__":
    main()
