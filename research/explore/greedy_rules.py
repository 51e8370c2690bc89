"""Greedy success on a layout under both ``greedy_actions`` rules, one learning run per seed.

``GPQAgent(env, seed=s)`` with defaults learns ``--steps`` steps in calls of ``--every``
(the protocol of ``agent_run.py``); after each, ``--episodes`` greedy episodes are run
with ``Q``'s greedy action sought among the data's actions near the state
(``greedy_actions="data"``) and among the candidates (``"candidates"``). Greedy episodes
change nothing the agent learns, so both curves come from the same run. Where the
exploration map knows a route its plan acts under either rule (issue 46, part twenty)::

    python research/explore/greedy_rules.py --env three-walls --steps 4000 --seeds 0 1 2
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from agent_run import greedy_success, protocol_parser
from layouts import make_env

from geoq.agents import GPQAgent

RULES = ("data", "candidates")


def main(argv: list[str] | None = None) -> None:
    p = protocol_parser(__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=20)
    a = p.parse_args(argv)
    for seed in a.seeds:
        agent = GPQAgent(make_env(a.env), seed=seed)
        curves: dict[str, list[float]] = {rule: [] for rule in RULES}
        for _ in range(a.steps // a.every):
            agent.learn(a.every)
            config = agent.config
            for rule, curve in curves.items():
                agent.config = replace(config, greedy_actions=rule)
                curve.append(greedy_success(agent, a.env, a.episodes))
            agent.config = config
        for rule, curve in curves.items():
            first = next((i for i, c in enumerate(curve) if c >= 0.9), None)
            later = [] if first is None else curve[first + 1 :]
            print(f"{a.env} seed {seed} {rule}: first >= 0.9 at "
                  f"{'none' if first is None else (first + 1) * a.every}, falls back "
                  f"{sum(c < 0.9 for c in later)} of {len(later)}, success "
                  f"{' '.join(f'{c:.2f}' for c in curve)}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
