"""How well a linear policy can do on a task, searched on the task itself (no model).

The cross-entropy method over ``a = tanh(K [s, 1])`` (actions in ``[-1, 1]``; raw
observations), each candidate scored by its mean return over ``--episodes`` episodes of
fresh seeds, the mean's return over 20 held-out episodes printed every 5 iterations::

    python research/linear_ceiling.py Reacher-v5 --iterations 40

Backs the design notes' "a linear policy does not reach around an arm" (issue 46, part
three). Needs the ``mujoco`` extra for Gymnasium's MuJoCo tasks.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np


def mean_return(env: gym.Env, gains: np.ndarray, seeds: np.ndarray) -> float:
    """Mean undiscounted return of the policy ``gains`` [d_a, d_s + 1] over ``seeds``."""
    total = 0.0
    for seed in seeds:
        s, _ = env.reset(seed=int(seed))
        done = False
        while not done:
            s, r, terminated, truncated, _ = env.step(np.tanh(gains @ np.append(s, 1.0)))
            total, done = total + float(r), terminated or truncated
    return total / len(seeds)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("env")
    ap.add_argument("--iterations", type=int, default=40)
    ap.add_argument("--candidates", type=int, default=40)
    ap.add_argument("--episodes", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    env, rng = gym.make(a.env), np.random.default_rng(a.seed)
    shape = (env.action_space.shape[0], env.observation_space.shape[0] + 1)
    mean, std = np.zeros(shape), np.ones(shape)
    held_out = np.arange(1000, 1020)
    for it in range(a.iterations):
        seeds = rng.integers(1_000_000, size=a.episodes)
        candidates = mean + std * rng.standard_normal((a.candidates, *shape))
        candidates[0] = mean
        values = np.array([mean_return(env, c, seeds) for c in candidates])
        elite = candidates[np.argsort(-values)[:6]]
        mean, std = elite.mean(axis=0), elite.std(axis=0) + 0.02
        if it % 5 == 4:
            print(f"iteration {it + 1}: best {values.max():.2f}, the mean on 20 held-out "
                  f"episodes {mean_return(env, mean, held_out):.2f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
