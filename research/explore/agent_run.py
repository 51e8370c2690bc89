"""``GPQAgent(env, seed=s)``, defaults only, on TwoRooms or a layout of ``layouts.py``.

The protocol of docs/exploration.md ("In the agent"): ``learn`` in calls of
``--every`` steps, after each ``--episodes`` greedy episodes from reset seeds
10,000 + i, success by ``info["is_success"]``. One line per seed: the first
checkpoint with success >= 0.9, the later checkpoints below it, the curve, the
map's size and the learning time.

    python research/explore/agent_run.py --env door-bottom --seeds 0 1 2 3 4
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from layouts import make_env

from geoq.agents import GPQAgent


def greedy_success(agent: GPQAgent, env_name: str, episodes: int) -> float:
    """Fraction of ``episodes`` greedy episodes that end in success."""
    env, wins = make_env(env_name), 0
    for ep in range(episodes):
        s, _ = env.reset(seed=10_000 + ep)
        while True:
            s, _, term, trunc, info = env.step(agent.predict(s)[0])
            if term or trunc:
                wins += bool(info.get("is_success", False))
                break
    return wins / episodes


def protocol_parser(description: str) -> argparse.ArgumentParser:
    """The protocol's options: layout, seeds, steps and steps per ``learn`` call."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--env", default="two-rooms")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    p.add_argument("--steps", type=int, default=2000)
    p.add_argument("--every", type=int, default=250)
    return p


def main(argv: list[str] | None = None) -> None:
    p = protocol_parser(__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=20)
    a = p.parse_args(argv)
    for seed in a.seeds:
        agent, curve, seconds = GPQAgent(make_env(a.env), seed=seed), [], 0.0
        for _ in range(a.steps // a.every):
            t0 = time.perf_counter()
            agent.learn(a.every)
            seconds += time.perf_counter() - t0
            curve.append(greedy_success(agent, a.env, a.episodes))
        first = next((i for i, c in enumerate(curve) if c >= 0.9), None)
        later = [] if first is None else curve[first + 1 :]
        m = agent.explorer.map
        size = "no map" if m is None else f"{m.cells.n_leaves} leaves, {int(m.done.sum())} goals"
        print(f"{a.env} seed {seed}: first >= 0.9 at "
              f"{'none' if first is None else (first + 1) * a.every}, falls back "
              f"{sum(c < 0.9 for c in later)} of {len(later)}, success "
              f"{' '.join(f'{c:.2f}' for c in curve)}; {size}; learn {seconds:.1f} s "
              f"({1000 * seconds / a.steps:.1f} ms/step)", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
