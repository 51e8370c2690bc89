"""Why the default agent's greedy episodes fail on a layout: one line per checkpoint.

The protocol of ``agent_run.py`` (``learn`` in calls of ``--every`` steps, greedy
episodes from reset seeds 10,000 + i); at each checkpoint every failed episode is
classed by how it ended:

- ``stuck(tried n, blocked b)``: its last step did not move; the greedy candidate had
  been tried ``n`` times from that leaf in training, ``b`` of them blocked (``n > 0,
  b = 0``: a leaf that straddles a wall, the move tried only from the open part;
  ``n = 0``: a predicted move);
- ``loop(L leaves)``: still moving at the time limit, among ``L`` leaves in its last
  40 steps;
- ``+gp``: somewhere on the way the map knew no route and the GP chose.

    python research/explore/why_fail.py --env door-bottom --seed 3
"""

from __future__ import annotations

import argparse
import collections
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from layouts import make_env

from geoq.agents import GPQAgent
from geoq.agents.state_map import StateMap


def failure(agent: GPQAgent, m: StateMap, path: np.ndarray, gp_chose: bool) -> str:
    """The class of one failed episode that visited ``path`` ``[T + 1, d]``."""
    leaves = m.cells.locate(path[-40:])
    a = agent.predict(path[-1])[0]
    k = int(np.argmin(np.linalg.norm(m.candidates - a, axis=1)))
    if np.array_equal(path[-1], path[-2]):
        tried = (m.leaf_s == leaves[-1]) & (m.k == k)
        kind = f"stuck(tried {tried.sum()}, blocked {m._blocked()[tried].sum()})"
    else:
        kind = f"loop({np.unique(leaves).size} leaves)"
    return kind + ("+gp" if gp_chose else "")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="two-rooms")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--steps", type=int, default=2000)
    p.add_argument("--every", type=int, default=250)
    p.add_argument("--episodes", type=int, default=20)
    a = p.parse_args(argv)
    agent, env = GPQAgent(make_env(a.env), seed=a.seed), make_env(a.env)
    for checkpoint in range(a.every, a.steps + 1, a.every):
        agent.learn(a.every)
        m = agent.explorer.map
        if m is None:
            print(f"{checkpoint}: no map")
            continue
        kinds: collections.Counter[str] = collections.Counter()
        for ep in range(a.episodes):
            s, _ = env.reset(seed=10_000 + ep)
            path, gp_chose = [s], False
            while True:
                gp_chose |= not bool(m.greedy(s[None])[1][0])
                s, _, term, trunc, info = env.step(agent.predict(s)[0])
                path.append(s)
                if term or trunc:
                    break
            if not info.get("is_success", False):
                kinds[failure(agent, m, np.array(path), gp_chose)] += 1
        wins = a.episodes - sum(kinds.values())
        print(f"{checkpoint}: success {wins / a.episodes:.2f} {dict(kinds)}", flush=True)


if __name__ == "__main__":
    main()
