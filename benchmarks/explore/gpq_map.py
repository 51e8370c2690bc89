"""A first probe of prototype 4 inside ``GPQAgent`` (docs/exploration.md, "Route into GPQAgent").

``MapGPQAgent`` is a ``GPQAgent`` whose training actions come from a
:class:`parti_map.PartiMap` fed with every transition the agent takes (the GP keeps
learning from all of them), and whose greedy action is the map's exploit plan where
the map knows a route to a termination, the GP's greedy action elsewhere. A probe
outside the package: it overrides the private hooks ``_observe`` and ``_explore``.

    python benchmarks/explore/gpq_map.py --seeds 0 1
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from layouts import make_env
from parti_map import MapConfig, PartiMap

from geoq.agents import GPQAgent

PROTOTYPE_4 = MapConfig(blocked_cos=0.7, fallback=True, macro=True, side_scale=3.0)


class MapGPQAgent(GPQAgent):
    """``GPQAgent`` exploring with prototype 4's map (training), exploiting it where it knows."""

    def __init__(self, env: Any, seed: int, map_config: MapConfig = PROTOTYPE_4, **kw: Any):
        super().__init__(env, seed=seed, **kw)
        space = self.env.observation_space
        rng = np.random.default_rng([seed, 4])  # the map's own generator
        self.map = PartiMap(space.low, space.high, self.action_low, self.action_high,
                            map_config, rng)  # fmt: skip
        self.map.cand = np.asarray(self.candidates)  # the agent's candidates
        self.map.K = len(self.map.cand)
        self._s: np.ndarray | None = None
        self._k = 0

    def _observe(self, env, s, q):  # type: ignore[no-untyped-def]
        self._s = np.asarray(s)[0]
        step, q = super()._observe(env, s, q)
        self.map.observe(self._s, self._k, step.reward, step.next_state[0], step.terminated,
                         step.terminated or step.truncated)  # fmt: skip
        return step, q

    def _explore(self, q):  # type: ignore[no-untyped-def]
        assert self._s is not None
        self._k = self.map.explore(self._s)
        return self.map.cand[self._k][None, :]

    def predict(self, observation: Any, deterministic: bool = True):  # type: ignore[no-untyped-def]
        m = self.map
        if deterministic and m.side is not None and m.done.any():
            s = np.asarray(observation, dtype=np.float64).reshape(-1)
            m.plan()
            c = int(m.locate(s[None])[0])
            if c >= 0 and m.V_exploit[c] > m._bounds()[0] + 0.05 * np.ptp(m._bounds()):
                return m.cand[int(np.argmax(m.Q_exploit[c]))], None
        return super().predict(observation, deterministic)


def evaluate(agent: GPQAgent, env_name: str, episodes: int) -> float:
    env = make_env(env_name)
    wins = 0
    for ep in range(episodes):
        s, _ = env.reset(seed=10_000 + ep)
        while True:
            s, _, term, trunc, info = env.step(agent.predict(s)[0])
            if term or trunc:
                wins += bool(info.get("is_success", False))
                break
    return wins / episodes


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="two-rooms")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    p.add_argument("--steps", type=int, default=2000)
    p.add_argument("--every", type=int, default=250)
    p.add_argument("--episodes", type=int, default=20)
    p.add_argument("--max-bv", type=int, default=None)
    a = p.parse_args(argv)
    for seed in a.seeds:
        agent = MapGPQAgent(make_env(a.env), seed=seed, max_bv=a.max_bv)
        curve, t_learn = [], 0.0
        for _ in range(a.steps // a.every):
            t0 = time.perf_counter()
            agent.learn(a.every)
            t_learn += time.perf_counter() - t0
            curve.append(evaluate(agent, a.env, a.episodes))
        goals = int(agent.map.done.sum())
        print(f"seed {seed}: goals {goals}, success {' '.join(f'{c:.2f}' for c in curve)}, "
              f"learn {t_learn:.1f} s ({1000 * t_learn / a.steps:.1f} ms/step), "
              f"map plan {agent.map.stats.plan_seconds:.1f} s", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
