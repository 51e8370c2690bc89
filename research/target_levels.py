"""How far ``Q``'s fitted-Q targets stand above what the data and the greedy policy earn
(issue 46, part twenty-two).

On agents saved at each checkpoint by ``research/checkpoint_actors.py --save DIR``,
prints per checkpoint (medians over the stored transitions whose episode ended by a
termination, where a return is known; over every stored transition where no episode
terminated, ``HalfCheetah-v5``'s, with ``MC`` then ``nan``):

- ``MC``: the behaviour's discounted return from each transition to its episode's end;
- ``eval``: the fixed point of ``y = r + gamma Q_y(s', a')`` with ``a'`` the action taken
  at ``s'`` (policy evaluation of the behaviour, on the agent's own basis and kernel):
  whether the GP's smoother, without the max, holds the targets near ``MC``;
- ``targets``: the agent's own targets, ``r + gamma max_a' Q(s', a')`` (fitted-Q);
- ``hi``: their upper clip, the most reward seen over ``1 - gamma``;
- ``greedy Q(s0)`` and ``greedy G0``: over 5 greedy episodes (evaluation seed
  ``10_000 + SEED`` on), ``Q``'s mean at the first state and action, against the
  discounted return the episode then earned.

With ``--noise V``, each agent's GP is first rebuilt from its stored transitions with
observation-noise variance ``V`` and one fitted-Q phase run on it (what a refit of the
length-scales does, at another noise; ``V`` its own noise gives the rebuilt agent at the
noise it learned with); otherwise nothing in the agents is changed::

    python research/checkpoint_actors.py Walker2d-v5 --seed 3 --save runs/w3
    python research/target_levels.py Walker2d-v5 --seed 3 --load runs/w3
    python research/target_levels.py Walker2d-v5 --seed 3 --load runs/w3 --noise 0.1
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

EPISODES = 5


def _returns_to_go(
    rewards: np.ndarray, ends: np.ndarray, terminal: np.ndarray, gamma: float
) -> np.ndarray:
    """Discounted return from each transition to the end of its episode ``[N]``; NaN where
    the episode did not end by a termination (its return is not known)."""
    G = np.full(len(rewards), np.nan)
    acc, known = 0.0, False
    for i in range(len(rewards) - 1, -1, -1):
        if ends[i]:
            acc, known = 0.0, bool(terminal[i])
        acc = rewards[i] + gamma * acc
        G[i] = acc if known else np.nan
    return G


def _policy_evaluation(agent: Any, stored: Any, next_actions: np.ndarray) -> np.ndarray:
    """Targets ``[N]`` at the fixed point of ``y = r + gamma c Q_y(s', a')`` on the agent's
    basis (``a'`` given), from the agent's targets, clipped to its value bounds."""
    from geoq.agents.fitted_q import DenseCandidates, fitted_q_sweeps

    gp, st = agent.gp, agent.state
    system = gp.projected_system(agent.inputs(stored.states, stored.actions))
    K_next = gp.kernel.to_basis(agent.inputs(stored.next_states, next_actions), gp.basis_vectors)
    bounds = agent.value_bounds()
    result = fitted_q_sweeps(
        system, DenseCandidates(K_next, 1), stored.rewards,
        1.0 - stored.terminated.astype(np.float64), agent.config.gamma,
        np.clip(agent.buffer.targets(last=len(stored)), *bounds), y_mean=st.y_mean,
        y_scale=st.y_scale, max_sweeps=2000, tol=agent.config.sweep_tol * st.y_scale,
        bounds=bounds, n_active=None,
    )  # fmt: skip
    return result.targets


def _greedy_levels(agent: Any, env_id: str, seed: int) -> tuple[float, float]:
    """Mean over :data:`EPISODES` greedy episodes of ``Q(s0, a0)`` and of the discounted
    return earned from ``s0``."""
    import gymnasium as gym

    env, gamma = gym.make(env_id), agent.config.gamma
    q0, g0 = [], []
    for e in range(EPISODES):
        obs, _ = env.reset(seed=10_000 + seed + e)
        first, rewards, done = None, [], False
        while not done:
            action, _ = agent.predict(obs, deterministic=True)
            if first is None:
                first = agent.inputs(obs[None, :], np.asarray(action)[None, :])
            obs, r, terminated, truncated, _ = env.step(action)
            rewards.append(float(r))
            done = terminated or truncated
        q0.append(agent.state.y_mean + agent.state.y_scale * float(agent.gp.predict(first)[0]))
        g0.append(float(np.polyval(rewards[::-1], gamma)))
    env.close()
    return float(np.mean(q0)), float(np.mean(g0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--load", type=Path, required=True, help="checkpoint_actors' --save")
    parser.add_argument("--noise", type=float, default=None, help="rebuild the GP at this noise")
    args = parser.parse_args()

    from geoq.agents import GPQAgent

    print("steps | MC | eval | targets | hi | greedy Q(s0) | greedy G0", flush=True)
    for path in sorted(args.load.glob("*.npz"), key=lambda p: int(p.stem.split("_")[-1])):
        agent = GPQAgent.load(path, env=args.env)
        agent.planning.feedback.acting, agent.planning.feedback.kept = False, None  # Q's own
        if args.noise is not None:
            agent.config = replace(agent.config, noise=args.noise)
            agent.phase.config = agent.config
            agent._restream()  # the GP rebuilt from the stored transitions
            agent._train()
        stored = agent.buffer.transitions(last=agent.config.window)
        S, S2 = stored.states, stored.next_states
        follows = np.zeros(len(S), dtype=bool)
        follows[:-1] = np.all(S[1:] == S2[:-1], axis=1)  # the next transition goes on from s'
        ends = np.ones(len(S), dtype=bool)
        ends[:-1] = ~follows[:-1]
        # The action taken at s' where the episode went on; at an end the stored action
        # stands in (unused after a termination; after a truncation, a stand-in).
        taken = stored.actions
        next_actions = np.where(follows[:, None], np.roll(taken, -1, axis=0), taken)
        G = _returns_to_go(stored.rewards, ends, stored.terminated, agent.config.gamma)
        known = ~np.isnan(G)
        evaluated = _policy_evaluation(agent, stored, next_actions)
        targets = agent.buffer.targets(last=len(stored))
        q0, g0 = _greedy_levels(agent, args.env, args.seed)
        over = known if known.any() else np.ones_like(known)  # no termination: all of them
        mc = float(np.median(G[known])) if known.any() else float("nan")
        ev, tg = (float(np.median(v[over])) for v in (evaluated, targets))
        print(
            f"{path.stem.split('_')[-1]} | {mc:.1f} | {ev:.1f} | {tg:.1f}"
            f" | {agent.value_bounds()[1]:.1f} | {q0:.1f} | {g0:.1f}  ({known.sum()} of"
            f" {len(G)} transitions with a known return)",
            flush=True,
        )


if __name__ == "__main__":
    main()
