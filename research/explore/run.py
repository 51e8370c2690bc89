"""Measure prototype 4 (docs/exploration.md): one line per seed, then a summary.

Examples (each table row of docs/exploration.md names its command)::

    python research/explore/run.py --seeds 0 1
    python research/explore/run.py --seeds 0 1 --exploit clean
    python research/explore/run.py --seeds 0 1 --no-split
    python research/explore/run.py --env door-bottom --seeds 0 1

Protocol: ``--steps`` training steps (default 2,000) from ``env.reset(seed=seed)``;
every ``--every`` steps, greedy success on ``--episodes`` episodes from the default
reset (reset seeds 10,000 + episode), ``info["is_success"]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from layouts import make_env
from parti_map import MapConfig, PartiMap


def evaluate(agent: PartiMap, env_name: str, episodes: int) -> float:
    """Greedy success rate over ``episodes`` episodes from reset seeds 10,000 + episode."""
    env = make_env(env_name)
    wins = 0
    for ep in range(episodes):
        s, _ = env.reset(seed=10_000 + ep)
        while True:
            s, _, term, trunc, info = env.step(agent.cand[agent.greedy(s)])
            if term or trunc:
                wins += bool(info.get("is_success", False))
                break
    return wins / episodes


def run_seed(env_name: str, seed: int, config: MapConfig, steps: int, every: int, episodes: int):
    env = make_env(env_name)
    rng = np.random.default_rng(seed)
    agent = PartiMap(env.observation_space.low, env.observation_space.high,
                     env.action_space.low, env.action_space.high, config, rng)  # fmt: skip
    s, _ = env.reset(seed=seed)
    goals, first_goal, curve = 0, None, []
    t_train, t0 = 0.0, time.perf_counter()
    for t in range(1, steps + 1):
        t1 = time.perf_counter()
        k = agent.explore(s)
        s2, r, term, trunc, _ = env.step(agent.cand[k])
        agent.observe(s, k, r, s2, term, term or trunc)
        t_train += time.perf_counter() - t1
        if term:
            goals += 1
            first_goal = first_goal or t
        s = env.reset()[0] if term or trunc else s2
        if t % every == 0:
            curve.append(evaluate(agent, env_name, episodes))
    total = time.perf_counter() - t0
    return {
        "seed": seed,
        "first_goal": first_goal,
        "goals": goals,
        "curve": curve,
        "train_s": t_train,
        "total_s": total,
        "plans": agent.stats.plans,
        "sweeps": agent.stats.sweeps,
        "plan_s": agent.stats.plan_seconds,
        "leaves": agent.leaf_lo.shape[0] if agent.side is not None else 0,
        "splits": agent.stats.splits,
        "side": agent.side,
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--env", default="two-rooms", help="two-rooms or a layouts.LAYOUTS name")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    p.add_argument("--steps", type=int, default=2000)
    p.add_argument("--every", type=int, default=250)
    p.add_argument("--episodes", type=int, default=20)
    p.add_argument("--exploit", default="tried", choices=["tried", "clean", "all"])
    p.add_argument("--frontier-after-goal", default="goal", choices=["goal", "lo", "hi"])
    p.add_argument(
        "--blocked-cos",
        type=float,
        default=None,
        help="predict an untried move blocked next to a blocked one this close",
    )
    p.add_argument(
        "--greedy-every",
        type=int,
        default=0,
        help="after a goal, every n-th training episode follows the exploit plan",
    )
    p.add_argument(
        "--fallback",
        action="store_true",
        help="act by the explore plan where the exploit plan knows no route",
    )
    p.add_argument("--quantile", type=float, default=0.9, help="the cell side's quantile")
    p.add_argument("--side-scale", type=float, default=1.0, help="the cell side times this")
    p.add_argument("--macro", action="store_true", help="moves inside a leaf repeat to its exit")
    p.add_argument("--no-split", action="store_true", help="the fixed data-sized grid")
    a = p.parse_args(argv)
    config = MapConfig(
        exploit=a.exploit,
        frontier_after_goal=a.frontier_after_goal,
        split=not a.no_split,
        blocked_cos=a.blocked_cos,
        greedy_every=a.greedy_every,
        fallback=a.fallback,
        quantile=a.quantile,
        side_scale=a.side_scale,
        macro=a.macro,
    )
    print(f"# {a.env} {config}")
    firsts = []
    for seed in a.seeds:
        o = run_seed(a.env, seed, config, a.steps, a.every, a.episodes)
        curve = o["curve"]
        hit = [(i + 1) * a.every for i, c in enumerate(curve) if c >= 0.9]
        first = hit[0] if hit else None
        firsts.append(first if first is not None else np.inf)
        after = curve[(hit and (hit[0] // a.every)) or len(curve) :]
        falls = sum(c < 0.9 for c in after)
        print(
            f"seed {seed}: first goal {o['first_goal']}, goals {o['goals']}, "
            f"success {' '.join(f'{c:.2f}' for c in curve)}, first >=0.9 at {first}, "
            f"falls back {falls}/{len(after)}; leaves {o['leaves']} splits {o['splits']} "
            f"side {np.round(o['side'], 4)}; plans {o['plans']} sweeps {o['sweeps']} "
            f"plan {o['plan_s']:.1f} s, train {o['train_s']:.1f} s "
            f"({1000 * o['train_s'] / a.steps:.1f} ms/step), total {o['total_s']:.1f} s",
            flush=True,
        )
    print(f"median first step with success >= 0.9: {np.median(firsts)}  ({firsts})")


if __name__ == "__main__":
    main()
