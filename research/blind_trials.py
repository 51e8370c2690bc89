"""Which runs the blind trial of issue 46's part seventeen can change, and where it acts.

The rule (``geoq.agents.policy_planning``, module docstring) can put a policy on trial
only while ``Q`` acts and no policy has yet replaced it. So a run of
``GPQAgent(env, seed=seed)`` whose first policy goes in by the model's score is the run
of the code before, step for step, and one whose first policy goes in blind is not.
For each seed this learns 500 steps at a time, as the benchmark does, until a policy
first replaces ``Q`` (or ``--steps``), and prints where, and whether blind::

    python research/blind_trials.py Walker2d-v5 --seeds 5 -j 2
    python research/blind_trials.py cartpole_swingup:heldout/CartPoleSwingUp-v0 --seeds 5

(the held-out swing-up with ``research/heldout`` on ``PYTHONPATH``).
"""

from __future__ import annotations

import argparse

from joblib import Parallel, delayed

import geoq.agents.policy_planning as planning
from geoq.agents import GPQAgent


class _Replaced(Exception):
    """A policy has replaced ``Q``: the rest of the run is the code before's, or not."""


def first_trial(env: str, seed: int, steps: int) -> str:
    """Where a policy first replaced ``Q`` in the run of ``seed``, and whether blind."""
    feedback, asked = planning.FeedbackPlanning, []
    search, undecided = feedback.search, feedback._undecided

    def asking(self, model, q_mean):  # type: ignore[no-untyped-def]
        answer = undecided(self, model, q_mean)
        asked.append(answer)
        return answer

    def watched(self, model, n, rng, states=None):  # type: ignore[no-untyped-def]
        asked.clear()
        search(self, model, n, rng, states)
        if self.q_returns:
            raise _Replaced(f"{n} transitions, {'blind' if any(asked) else 'by the model'}")

    feedback.search, feedback._undecided = watched, asking  # type: ignore[method-assign]
    agent = GPQAgent(env, seed=seed)
    try:
        for _ in range(steps // 500):
            agent.learn(500)
    except _Replaced as replaced:
        return f"{env} seed {seed}: a policy first replaced Q at {replaced}"
    return f"{env} seed {seed}: no policy replaced Q in {steps} steps"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("-j", "--jobs", type=int, default=1)
    a = parser.parse_args()
    lines = Parallel(n_jobs=a.jobs)(
        delayed(first_trial)(a.env, seed, a.steps) for seed in range(a.seeds)
    )
    print("\n".join(lines))


if __name__ == "__main__":
    main()
