"""``GPQAgent(planner="cem")`` with a longer look-ahead: does planning at acting time learn
a task the policy search stalls on? (issue 46, part thirteen)

The agent's ``cem`` planner (:class:`geoq.models.CEMPlanner`, training and greedy
actions alike) with its :class:`~geoq.models.PlannerSettings` replaced: ``--horizon``
model steps, ``--samples`` sequences a refit, ``--iterations`` refits, an eighth of the
samples as elites; everything else as the agent's defaults. It learns ``--steps``
steps in chunks of ``--every`` and prints, at each checkpoint, the mean greedy return
of ``--episodes`` episodes (evaluation seed ``10_000 + seed``) and the seconds spent
learning and evaluating.

    PYTHONPATH=research/heldout .venv/bin/python research/probe_cem_horizon.py \\
        cartpole_swingup:heldout/CartPoleSwingUp-v0 --seed 0 --horizon 30 --samples 100

(an env of one's own named ``module:Id``, as ``gymnasium.make`` names it).
"""

from __future__ import annotations

import argparse
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--every", type=int, default=1000)
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--horizon", type=int, default=30)
    parser.add_argument("--samples", type=int, default=100)
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--planner", choices=("cem", "cem-q"), default="cem")
    args = parser.parse_args()

    import geoq.agents.model_planning as model_planning
    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent
    from geoq.models import PlannerSettings

    elites = max(1, args.samples // 8)
    settings = PlannerSettings(horizon=args.horizon, samples=args.samples,
                               iterations=args.iterations, elites=elites)  # fmt: skip
    model_planning.PlannerSettings = lambda: settings  # type: ignore[assignment,misc]
    agent = GPQAgent(args.env, seed=args.seed, planner=args.planner)
    print(f"{settings}", flush=True)
    learning = 0.0
    for done in range(args.every, args.steps + 1, args.every):
        start = time.perf_counter()
        agent.learn(args.every)
        learning += time.perf_counter() - start
        start = time.perf_counter()
        ev = evaluate_agent(agent, args.env, args.episodes, seed=10_000 + args.seed)
        each = " / ".join(f"{r:.1f}" for r in ev.returns)
        print(f"{done}: greedy {ev.returns.mean():.1f} ({each}); "
              f"learning {learning:.0f} s, evaluation {time.perf_counter() - start:.0f} s",
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
