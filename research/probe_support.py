"""Probe (issue 46, part four): a model of random transitions, its support and a network
policy searched through it, on one task.

Not a speed benchmark: the measurement behind the design notes' part four. It takes
``--steps`` transitions of uniformly random actions (episodes reset from the
generator ``--seed``), fits a :class:`geoq.models.GPDynamicsModel` (``--model``:
:class:`geoq.models.ModelSettings` fields as JSON), and prints

- each output's one-step error on 500 held-out random transitions, relative to the
  output's std (and the same over the best 95% of them: where the jumps are);
- how far the held-out next states lie from the seen ones, in the support's spacings
  (above 1, a roll-out there starts to halt);
- ``--rounds`` searches of a :class:`geoq.models.MLPFeedback` from random weights
  (:func:`geoq.models.search_policy`, ``--search``: :class:`PolicyGradientSettings`
  fields as JSON, horizon the task's time limit by default), each followed by the
  policy's mean return on 10 real episodes (reset seeds 10,000-10,009)::

    python research/probe_support.py Reacher-v5 --model '{"standardised_support": true}'
    python research/probe_support.py Reacher-v5 --model '{"standardised_support": true, \\
        "support_holdout": 0.2, "outlier_mads": 6}'

Needs the ``mujoco`` extra for Gymnasium's MuJoCo tasks.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import gymnasium as gym
import numpy as np

from geoq.models import (
    GPDynamicsModel,
    MLPFeedback,
    ModelSettings,
    PolicyGradientSettings,
    search_policy,
)


def collect(env: gym.Env, n: int, rng: np.random.Generator) -> tuple[list, np.ndarray]:
    """``n`` transitions of random actions ``[S, A, R, S2, T]`` and the episodes' starts."""
    rows: list[list] = [[], [], [], [], []]
    s, _ = env.reset(seed=int(rng.integers(2**31)))
    starts = [s]
    while len(rows[0]) < n:
        a = rng.uniform(env.action_space.low, env.action_space.high)
        s2, r, terminated, truncated, _ = env.step(a)
        for column, v in zip(rows, (s, a, r, s2, terminated), strict=True):
            column.append(v)
        s = s2
        if terminated or truncated:
            s, _ = env.reset(seed=int(rng.integers(2**31)))
            starts.append(s)
    return [np.asarray(c, dtype=np.float64) for c in rows], np.array(starts)


def real_return(env: gym.Env, act, episodes: int = 10) -> float:  # type: ignore[no-untyped-def]
    """Mean return of ``act(states [1, d_s]) -> actions [1, d_a]`` on held-out episodes."""
    returns = []
    for e in range(episodes):
        s, _ = env.reset(seed=10_000 + e)
        total, done = 0.0, False
        while not done:
            s, r, terminated, truncated, _ = env.step(act(s[None])[0])
            total, done = total + float(r), terminated or truncated
        returns.append(total)
    return float(np.mean(returns))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("env")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--model", default="{}", help="ModelSettings fields as JSON")
    ap.add_argument("--search", default="{}", help="PolicyGradientSettings fields as JSON")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    warnings.simplefilter("ignore")  # the evidence fits' bound warnings
    env, rng = gym.make(a.env), np.random.default_rng(a.seed)
    data, starts = collect(env, a.steps, rng)
    test, _ = collect(env, 500, rng)
    d = data[0].shape[1]
    model = GPDynamicsModel(d, data[1].shape[1], ModelSettings(**json.loads(a.model)))
    model.fit(*data, rng)
    true = np.column_stack([test[3] - test[0], test[2]])
    error = model.predict_mean(test[0], test[1])[:, : d + 1] - true
    spread = np.maximum(true.std(axis=0), 1e-12)
    print("one-step error / std, per output:", np.round(np.sqrt((error**2).mean(0)) / spread, 3))
    small = np.abs(error).max(axis=1) / spread.max() < np.quantile(
        np.abs(error).max(axis=1) / spread.max(), 0.95
    )
    print("  the best 95%:", np.round(np.sqrt((error[small] ** 2).mean(0)) / spread, 3))
    print(f"  transitions left out of the state changes' GPs: {model.n_outliers}")
    dist = model.support.distance(test[3])
    print(f"held-out next states, spacings from the seen: median {np.median(dist):.2f}, "
          f"90% {np.quantile(dist, 0.9):.2f}; beyond 1: {np.mean(dist > 1):.1%}")  # fmt: skip
    horizon = env.spec.max_episode_steps if env.spec and env.spec.max_episode_steps else 300
    search = PolicyGradientSettings(**({"horizon": horizon} | json.loads(a.search)))
    policy = MLPFeedback(env.action_space.low, env.action_space.high, model.x_mean[:d],
                         model.x_scale[:d])  # fmt: skip
    params = policy.initial(rng)
    centre = real_return(env, lambda s: policy.act(params, s))
    print(f"the first weights (the box's centre): {centre:.2f}")
    for k in range(a.rounds):
        start = time.perf_counter()
        params, value = search_policy(model, policy, params, starts, rng, search)
        real = real_return(env, lambda s: policy.act(params, s))  # noqa: B023
        print(f"search {k + 1}: model {value:.2f}, real {real:.2f} "
              f"({time.perf_counter() - start:.1f} s)", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
