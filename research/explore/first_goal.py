"""When training first sees a termination, and whether the map halved its leaves before.

The protocol of ``agent_run.py`` (``learn`` in calls of ``--every`` steps), stopped
at the first call after which the map holds a termination or has halved its leaves
(``StateMap.halvings``). The halving can fire only before a termination is seen, so
a seed that sees one with no halving trains, and evaluates, exactly as it did before
the halving existed: only the seeds this reports as halved need ``agent_run.py``
again.

    python research/explore/first_goal.py --env four-rooms --seeds 0 1 2 --steps 3000
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from agent_run import protocol_parser
from layouts import make_env

from geoq.agents import GPQAgent


def main(argv: list[str] | None = None) -> None:
    a = protocol_parser(__doc__.splitlines()[0]).parse_args(argv)
    for seed in a.seeds:
        agent, steps = GPQAgent(make_env(a.env), seed=seed), 0
        while steps < a.steps:
            agent.learn(a.every)
            steps += a.every
            m = agent.explorer.map
            if m is not None and (m.done.any() or m.halvings):
                break
        m = agent.explorer.map
        seen = m is not None and bool(m.done.any())
        halvings = 0 if m is None else m.halvings
        print(f"{a.env} seed {seed}: stopped after {steps} steps, termination seen {seen}, "
              f"halvings {halvings}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
