"""``Q``'s greedy return with its greedy action chosen by the average of several checkpoints'
``Q`` (issue 46, part twenty-nine).

Averaged-DQN (Anschel, Baram & Shimkin 2017) acts on the mean of the last ``K`` value
estimates, whose errors partly cancel. Here, on the agents ``research/checkpoint_actors.py
--save DIR`` keeps (``DIR/agent_STEPS.npz``, one every 500 steps), the greedy action at a
state is the agent's own rule (the best of the actions taken at the stored states nearest
it, ``greedy_actions="data"``), scored by the mean over the newest ``--k`` checkpoints of
``Q``'s posterior mean (raw units, each agent's own scaling); ``--k 1`` is ``Q`` alone
(the policy set aside) and must match ``checkpoint_actors.py``'s column ``Q alone``. The
nearest actions are the newest agent's. 10 greedy episodes, evaluation seed
``10_000 + SEED``::

    .venv/bin/python research/checkpoint_actors.py Walker2d-v5 --seed 3 --steps 3000 --save DIR
    .venv/bin/python research/averaged_q.py Walker2d-v5 DIR --seed 3 --k 2
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

EPISODES = 10


def raw_q(agent: Any, states: np.ndarray, actions: np.ndarray) -> np.ndarray:
    """``agent``'s posterior mean of ``Q`` [n] at raw ``states`` [n, d_s], ``actions`` [n, d_a]."""
    mean = agent.gp.predict(agent.inputs(states, actions))
    return agent.state.y_mean + agent.state.y_scale * mean


class AveragedGreedy:
    """Greedy actions among the newest agent's data actions, by the agents' mean ``Q``."""

    def __init__(self, agents: list[Any]):
        self.agents, self.newest = agents, agents[-1]
        self.env_id = self.newest.env_id

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        from geoq.agents.greedy_data import nearest_actions

        agent, S = self.newest, np.atleast_2d(obs)
        stored, d_s = agent.buffer.transitions(last=agent.config.window), agent.obs_dim
        scale = np.asarray(agent.scaling.scale, dtype=np.float64)[:d_s]
        lengthscales = np.broadcast_to(np.asarray(agent._lengthscale(), dtype=np.float64),
                                       (agent.scaling.dim,))[:d_s]  # fmt: skip
        actions = nearest_actions(S / scale, stored.states / scale, stored.actions,
                                  len(agent.candidates), agent.scaling.scaled_periods()[:d_s],
                                  np.ascontiguousarray(lengthscales))  # fmt: skip
        n, k, d_a = actions.shape
        flat_states, flat_actions = np.repeat(S, k, axis=0), actions.reshape(n * k, d_a)
        q = np.mean([raw_q(a, flat_states, flat_actions) for a in self.agents], axis=0)
        best = actions[np.arange(n), np.argmax(q.reshape(n, k), axis=1)]
        return (best[0] if np.ndim(obs) == 1 else best), None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("folder", type=Path, help="checkpoint_actors.py --save folder")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--k", type=int, default=2, help="checkpoints averaged")
    args = parser.parse_args()
    if args.k < 1:
        raise SystemExit("--k must be at least 1")

    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent

    steps = sorted(int(f.stem.split("_")[1]) for f in args.folder.glob("agent_*.npz"))
    agents = [GPQAgent.load(args.folder / f"agent_{t}.npz") for t in steps]
    for agent in agents:  # Q acts, as checkpoint_actors.py's Q alone
        agent.planning.feedback.acting, agent.planning.feedback.kept = False, None
    print(f"steps | Q alone | mean of the last {args.k} checkpoints' Q", flush=True)
    for i, t in enumerate(steps):
        returns = [
            float(evaluate_agent(AveragedGreedy(agents[max(0, j - k + 1) : j + 1]), args.env,
                                 EPISODES, seed=10_000 + args.seed).returns.mean())
            for j, k in ((i, 1), (i, args.k))
        ]  # fmt: skip
        print(f"{t} | {returns[0]:.1f} | {returns[1]:.1f}", flush=True)


if __name__ == "__main__":
    main()
