"""The exploration map's cost on TwoRooms (issue 28): what ``explore_map`` adds to ``learn``.

In one process, same seed: ``learn`` for the same number of steps with
``explore_map="off"`` (the GP's UCB) and ``"auto"`` (a map is built after 64 steps),
and the map alone: the ``auto`` run's own transitions replayed into a fresh
:class:`~geoq.agents.state_map.StateMap`, ``observe`` and ``plan`` at every step as in
``learn``. Goal (issue 28): 2,000 TwoRooms steps in <= 60 s.

    python benchmarks/run.py explore_map
"""

from __future__ import annotations

import time
import warnings

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
