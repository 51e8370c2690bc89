"""Goals 1-2 of issue 46 at their last checkpoint: ``GPQAgent(env, seed=s, planner=P)``
(``--planner``, ``cem`` by default) after 5,000 learning steps, the mean greedy return
of 10 episodes (:func:`geoq.experiments.control.evaluation.evaluate_agent`, seed
10,000), one line per ``ENV:SEED`` job, with the learning's and the evaluation's wall
time::

    python research/planner_5k.py InvertedPendulum-v5:0 Reacher-v5:0 ... [--planner policy]

Needs the ``mujoco`` extra for Gymnasium's MuJoCo tasks.
"""

from __future__ import annotations

import argparse
import time
import warnings

from geoq.agents import GPQAgent
from geoq.experiments.control.evaluation import evaluate_agent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("jobs", nargs="*", metavar="ENV:SEED")
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--episodes", type=int, default=10)
    ap.add_argument("--planner", default="cem")
    a = ap.parse_args()
    warnings.simplefilter("ignore")  # the evidence fits' bound warnings
    for job in a.jobs:
        env_id, seed = job.rsplit(":", 1)
        start = time.perf_counter()
        agent = GPQAgent(env_id, seed=int(seed), planner=a.planner)
        agent.learn(a.steps)
        learned = time.perf_counter()
        ev = evaluate_agent(agent, env_id, a.episodes, seed=10_000)
        print(f"{env_id} seed {seed}: mean greedy return {ev.returns.mean():.2f} ({ev.summary()}); "
              f"learning {learned - start:.0f} s, evaluation {time.perf_counter() - learned:.0f} s",
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
