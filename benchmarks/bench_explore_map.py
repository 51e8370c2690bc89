"""The exploration map's cost on TwoRooms (issue 28): what ``explore_map`` adds to ``learn``.

In one process, same seed: ``learn`` for the same number of steps with
``explore_map="off"`` (the GP's UCB) and ``"auto"`` (a map is built after 64 steps),
and the map alone: the ``auto`` run's own transitions replayed into a fresh
:class:`~geoq.agents.state_map.StateMap`, ``observe`` and ``plan`` at every step as in
``learn``. Goal (issue 28): 2,000 TwoRooms steps in <= 60 s.

Hostile observation spaces (issue 45), ``explore_map="on"`` against ``"off"``, 100
steps each: TwoRooms declared in a box of +-1e5 (goal: under 2 s) and TwoRooms with 48
constant features (goal: at most 5x the cost without the map). Before the sparse grid
the first raised ``MemoryError`` and the second took minutes.

    python benchmarks/run.py explore_map
"""

from __future__ import annotations

import time
import warnings

import gymnasium
import numpy as np
from gymnasium.wrappers import TransformObservation

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent
from geoq.agents.state_map import StateMap
from geoq.envs import TWO_ROOMS_ID


def _map_alone(agent: GPQAgent) -> float:
    """Seconds the map takes over ``agent``'s transitions, from the decision to the end."""
    explorer, space = agent.explorer, agent.env.observation_space  # type: ignore[union-attr]
    s, a, r, s2, term = agent.buffer.arrays()
    k, n0 = explorer.choices(a), explorer.decide_after
    assert explorer.map is not None and len(r) > n0
    start = time.perf_counter()
    m = StateMap(space.low, space.high, agent.candidates, agent.config.gamma,
                 s[:n0], k[:n0], r[:n0], s2[:n0], term[:n0])  # fmt: skip
    for i in range(n0, len(r)):
        m.plan()
        m.observe(s[i], int(k[i]), float(r[i]), s2[i], bool(term[i]))
    m.plan()
    return time.perf_counter() - start


def _hostile(extra: int, bound: float) -> gymnasium.Env:
    """TwoRooms observed with ``extra`` constant features, in a declared box of +-``bound``."""
    box = gymnasium.spaces.Box(-bound, bound, shape=(2 + extra,), dtype=np.float64)
    grow = lambda o: np.concatenate([o, np.full(extra, 0.5)])  # noqa: E731
    return TransformObservation(gymnasium.make(TWO_ROOMS_ID), grow, box)


def _hostile_table(steps: int) -> None:
    for name, extra, bound in (("+-1e5 box", 0, 1e5), ("48 constant features", 48, 1.0)):
        seconds = {}
        for mode in ("off", "on"):
            start = time.perf_counter()
            GPQAgent(_hostile(extra, bound), seed=0, explore_map=mode).learn(steps)
            seconds[mode] = time.perf_counter() - start
        print(f"{name:22} {steps} steps: off {seconds['off']:5.2f} s, on {seconds['on']:5.2f} s, "
              f"on / off {seconds['on'] / seconds['off']:.2f}x")  # fmt: skip


def main(quick: bool = False) -> None:
    """``quick``: tiny sizes, figures of no meaning (``benchmarks/run.py --quick``)."""
    warnings.simplefilter("ignore")
    steps = 150 if quick else 2_000
    GPQAgent(TWO_ROOMS_ID, seed=0, max_bv=20).learn(80)  # compiled code and imports, once
    seconds = {}
    for mode in ("off", "auto"):
        agent = GPQAgent(TWO_ROOMS_ID, seed=0, explore_map=mode)
        start = time.perf_counter()
        agent.learn(steps)
        seconds[mode] = time.perf_counter() - start
        print(f"explore_map={mode!r:7} learn {steps} steps: {seconds[mode]:6.1f} s "
              f"({1e3 * seconds[mode] / steps:5.1f} ms/step)")  # fmt: skip
    alone, m = _map_alone(agent), agent.explorer.map
    leaves = m.cells.n_leaves if m is not None else 0
    print(f"the map alone (observe + plan, replayed): {alone:.1f} s "
          f"({1e3 * alone / steps:.1f} ms/step), {leaves} leaves")  # fmt: skip
    print(f"ratios: auto / off {seconds['auto'] / seconds['off']:.2f}x; "
          f"map / auto learn {alone / seconds['auto']:.2f}")  # fmt: skip
    _hostile_table(100)
