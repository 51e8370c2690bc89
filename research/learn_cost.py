"""Wall time of ``GPQAgent(env, seed=seed)`` learning, chunk by chunk, evaluations off.

Not a ``make bench`` benchmark (a run takes minutes): the measurement behind issue
46's goal 4 on the results page (5,000 learning steps within ten minutes on one core).
It calls ``learn(chunk)`` until ``steps`` and prints each chunk's wall time (a chunk
that fits the model or searches a policy stands out) and the total. Pin it to one
core of an idle machine, with one BLAS thread::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 taskset -c 0 \\
        python research/learn_cost.py HalfCheetah-v5 --seed 3
"""

from __future__ import annotations

import argparse
import time

from geoq.agents import GPQAgent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("env", help="Gymnasium id")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--chunk", type=int, default=500, help="steps per learn() call")
    a = ap.parse_args()
    agent, total, done = GPQAgent(a.env, seed=a.seed), 0.0, 0
    while done < a.steps:
        step = min(a.chunk, a.steps - done)
        start = time.perf_counter()
        agent.learn(step)
        seconds = time.perf_counter() - start
        total, done = total + seconds, done + step
        print(f"{done:>7} steps: chunk {seconds:7.1f} s, total {total:7.1f} s", flush=True)
    print(f"learning, {done} steps, evaluations off: {total:.1f} s")


if __name__ == "__main__":
    main()
