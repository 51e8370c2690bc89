"""The model work of every ``policy-net`` search of ``GPQAgent(env, seed=seed)`` learning.

Each search's work (the particles' model steps of every :func:`~geoq.models.soft_return`
times the model's :attr:`~geoq.models.GPDynamicsModel.step_cost`), the transitions
since the search before, their ratio, its wall time (the holdout included), the budget
it was given and whether it moved the weights, and the gate after it: the model's score
for the weights that stand, the overshoot, the mean of ``Q``'s returns the gate sets it
against (read before the search, so before a trial's verdict there), the returns of the
actor before the search, whether a policy acts and whether it went on trial though the
model's score was not above ``Q``'s mean (``blind``: the model could not tell); then the
run's totals. What ``SEARCH_WORK`` bounds (issue 46,
part fifteen), and why no policy acts on ``Walker2d-v5`` (part sixteen)::

    python research/search_work.py Reacher-v5 --seed 0 --steps 5000
    python research/search_work.py Walker2d-v5 --seed 0 --steps 3000 --chunk 500

``--chunk``: ``learn`` that many steps at a time, as the benchmark's evaluations do
(each call starts a new episode, so the searches fall where they fall there).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import geoq.agents.policy_planning as planning
import geoq.models.policy_gradient as gradient
from geoq.agents import GPQAgent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--chunk", type=int, default=0, help="learn this many at a time")
    a = parser.parse_args()
    work, rows = [0.0], []
    soft_return, search_policy = gradient._soft_return, planning.search_policy

    def counted(model, *args):  # type: ignore[no-untyped-def]
        value, grad, taken = soft_return(model, *args)
        work[0] += taken * model.step_cost
        return value, grad, taken

    def timed(model, policy, params, starts, rng, settings, branch_from=None):  # type: ignore[no-untyped-def]
        work[0], start = 0.0, time.perf_counter()
        found = search_policy(model, policy, params, starts, rng, settings, branch_from)
        moved = not np.array_equal(found[0], params)
        rows.append([work[0], time.perf_counter() - start, settings.budget, moved])
        return found

    search = planning.FeedbackPlanning.search

    def logged(self, model, n, rng, states=None):  # type: ignore[no-untyped-def]
        gap, before = n - self.searched_at, len(rows)
        q_returns = self.q_returns if self.acting else self.returns
        returns = [round(r, 1) for r in self.returns]
        search(self, model, n, rng, states)
        if len(rows) > before:
            q_mean = float(np.mean(q_returns)) if q_returns else float("nan")
            blind = self.kept is not None and self.acting and self.value - self.overshoot <= q_mean
            rows[-1] += [n, gap, self.value, self.overshoot, q_mean, returns, self.acting, blind]

    gradient._soft_return, planning.search_policy = counted, timed
    planning.FeedbackPlanning.search = logged
    agent, start = GPQAgent(a.env, seed=a.seed), time.perf_counter()
    chunk = a.chunk or a.steps
    for done in range(0, a.steps, chunk):
        agent.learn(min(chunk, a.steps - done))
    total = time.perf_counter() - start
    for w, seconds, budget, moved, n, gap, value, overshoot, q_mean, returns, acting, blind in rows:
        print(f"{n:>6} transitions (+{gap:>5}): work {w:.2e}, {w / max(gap, 1):.1e} a "
              f"transition, {seconds:6.1f} s, budget {budget:.1e}, moved {moved}; model "
              f"score {value:.1f}, overshoot {overshoot:.1f}, Q's mean {q_mean:.1f}, "
              f"returns before {returns}, policy acts {acting}, blind {blind}")  # fmt: skip
    works = [row[0] / max(row[5], 1) for row in rows]
    print(f"{a.env} seed {a.seed}: {len(rows)} searches, work {sum(r[0] for r in rows):.2e}, "
          f"at most {max(works, default=0.0):.1e} a transition, searches "
          f"{sum(r[1] for r in rows):.0f} s of learning's {total:.0f} s")  # fmt: skip


if __name__ == "__main__":
    main()
