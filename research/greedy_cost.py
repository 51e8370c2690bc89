"""Wall time of a saved agent's greedy step (``agent.predict``), in this process.

Not a ``make bench`` benchmark (it needs a saved agent): the measurement behind the
results page's greedy-step costs. It plays ``--warmup`` greedy steps from
``reset(seed=5)``, then times ``agent.predict`` on the states seen. Several copies
started at once show what processes sharing the cores cost each other::

    python research/probe_planner.py --env Reacher-v5 --seed 1 --steps 2000 --every 1000 \\
        --episodes 1 --save runs/r
    python research/greedy_cost.py runs/r/Reacher-v5_cem_s1_2000.npz
    for i in 1 2 3; do python research/greedy_cost.py runs/r/Reacher-v5_cem_s1_2000.npz & done
"""

from __future__ import annotations

import argparse
import time
import warnings

import gymnasium as gym

from geoq.agents import GPQAgent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("path")
    ap.add_argument("--env", default=None, help="Gymnasium id (default: the agent's)")
    ap.add_argument("--warmup", type=int, default=30)
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    agent = GPQAgent.load(a.path)
    env_id = a.env or agent.env_id
    env = gym.make(env_id)
    obs, _ = env.reset(seed=5)
    seen = []
    for _ in range(a.warmup):
        seen.append(obs)
        obs, *_ = env.step(agent.predict(obs)[0])
    start = time.perf_counter()
    for o in seen:
        agent.predict(o)
    per_step = 1000 * (time.perf_counter() - start) / len(seen)
    print(f"{env_id}: {per_step:.1f} ms per greedy step", flush=True)


if __name__ == "__main__":
    main()
