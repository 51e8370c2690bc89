"""An actor trained on ``Q`` at saved checkpoints (issue 46, a probe).

On agents saved at each checkpoint by ``research/checkpoint_actors.py --save DIR``, in
step order, an :class:`~geoq.models.MLPFeedback` actor climbs the mean of ``Q(s, pi(s))``
over the stored states (Adam, ``--steps`` steps of ``--batch`` states per checkpoint,
warm-started from the previous checkpoint's weights, DDPG's actor update on the GP's
posterior mean; the action gradient by central differences of ``Q``'s mean). Prints per
checkpoint ``Q``'s greedy return and the actor's (10 episodes, evaluation seed
``10_000 + SEED``, no policy), and ``Q``'s mean at the actor's actions against its mean at
its own greedy actions, over the stored states. ``--bc ALPHA`` adds TD3+BC's pull to the
stored actions (Fujimoto & Gu 2021): the actor climbs ``ALPHA Q / mean|Q|`` less the
squared distance to the stored action, in half-ranges.

::

    python research/checkpoint_actors.py Walker2d-v5 --seed 3 --save runs/w3
    python research/actor_on_q.py Walker2d-v5 --seed 3 --load runs/w3
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

EPISODES = 10


class _ActorOnQ:
    """``predict`` of the actor, for :func:`evaluate_agent`."""

    def __init__(self, policy: Any, params: np.ndarray, env_id: str) -> None:
        self.policy, self.params, self.env_id = policy, params, env_id

    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        return self.policy.act(self.params, np.atleast_2d(obs)), None


def q_mean(agent: Any, S: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``Q``'s posterior mean ``[P]`` (standardised units) at the pairs ``(S[i], A[i])``."""
    return agent.gp.predict(agent.scaling.transform(np.hstack([S, A])))


def action_gradient(agent: Any, S: np.ndarray, A: np.ndarray, h: float) -> np.ndarray:
    """``dQ/da`` ``[P, d_a]`` by central differences of step ``h`` (action units)."""
    P, d_a = A.shape
    shifted = np.repeat(A[None], 2 * d_a, axis=0)  # [2 d_a, P, d_a]
    for j in range(d_a):
        shifted[2 * j, :, j] += h
        shifted[2 * j + 1, :, j] -= h
    q = q_mean(agent, np.tile(S, (2 * d_a, 1)), shifted.reshape(-1, d_a)).reshape(2 * d_a, P)
    return ((q[0::2] - q[1::2]) / (2 * h)).T


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--load", type=Path, required=True, help="checkpoint_actors' --save")
    parser.add_argument("--steps", type=int, default=300, help="Adam steps per checkpoint")
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--lr", type=float, default=3e-3)
    parser.add_argument("--hidden", type=int, default=32)
    parser.add_argument(
        "--bc",
        type=float,
        default=0.0,
        help="TD3+BC's alpha (Fujimoto & Gu 2021): the actor climbs alpha Q / mean|Q| less "
        "the squared distance to the stored action, in half-ranges (0: Q alone)",
    )
    args = parser.parse_args()

    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent
    from geoq.models import MLPFeedback

    rng = np.random.default_rng(args.seed)
    params = policy = None
    m = v = None
    t = 0
    print("steps | Q greedy | actor | Q at actor's actions vs at Q's greedy (median, z)")
    for path in sorted(args.load.glob("*.npz"), key=lambda p: int(p.stem.split("_")[-1])):
        agent = GPQAgent.load(path, env=args.env)
        agent.planning.feedback.acting, agent.planning.feedback.kept = False, None  # Q's own
        agent.config = replace(agent.config, greedy_actions="data")
        stored = agent.buffer.transitions(last=agent.config.window)
        S, A_data = stored.states, stored.actions
        low, high = agent.action_low, agent.action_high
        if policy is None:
            center, scale = S.mean(axis=0), np.maximum(S.std(axis=0), 1e-6)
            policy = MLPFeedback(low, high, center, scale, hidden=args.hidden)
            params = policy.initial(rng)
            m, v = np.zeros_like(params), np.zeros_like(params)
        h = 1e-3 * float(np.max(high - low))
        for _ in range(args.steps):
            rows = rng.integers(0, len(S), args.batch)
            batch = S[rows]
            A, cache = policy.forward(params, batch)
            g = action_gradient(agent, batch, A, h)
            if args.bc > 0:
                lam = args.bc / max(float(np.mean(np.abs(q_mean(agent, batch, A)))), 1e-6)
                g = lam * g - 2.0 * (A - A_data[rows]) / policy.half**2
            grad, _ = policy.backward(params, cache, g)
            grad = -grad / len(batch)  # ascent
            t += 1
            m = 0.9 * m + 0.1 * grad
            v = 0.999 * v + 0.001 * grad**2
            params = params - args.lr * (m / (1 - 0.9**t)) / (np.sqrt(v / (1 - 0.999**t)) + 1e-8)
        probe = S[rng.integers(0, len(S), 512)]
        at_actor = q_mean(agent, probe, policy.act(params, probe))
        at_greedy = q_mean(agent, probe, agent.predict(probe, deterministic=True)[0])
        q_ret = evaluate_agent(agent, args.env, EPISODES, seed=10_000 + args.seed)
        a_ret = evaluate_agent(
            _ActorOnQ(policy, params, args.env), args.env, EPISODES, seed=10_000 + args.seed
        )
        print(
            f"{path.stem.split('_')[-1]} | {q_ret.returns.mean():.1f} | "
            f"{a_ret.returns.mean():.1f} | {np.median(at_actor):.3f} vs "
            f"{np.median(at_greedy):.3f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
