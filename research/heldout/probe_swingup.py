"""Why ``planner="policy-net"`` stops short on the held-out cart-pole swing-up (issue 46).

On ``heldout/CartPoleSwingUp-v0`` (``cartpole_swingup.py``) the default agent and ``Q``
alone both end at returns of 100-135 out of about 185: a policy that spins the pole
through the top rather than balancing it. This probe takes one agent (learned with
defaults for ``--steps`` steps, saved to ``--agent`` and reused from there) and asks
where the barrier is:

- ``search``: the smooth return (``geoq.models.policy_gradient``) along a search's
  Adam steps from the acting weights, with the settings given as ``key=value`` pairs
  (e.g. ``learning_rate=0.001 horizon=60``; the budget is lifted), then the found
  weights' model return and their greedy return on 10 real episodes;
  ``--no-halt`` searches with the support's halt switched off;
- ``mpc``: model-predictive control through the agent's model (the cross-entropy
  method over ``--horizon`` steps of its means; ``--samples`` sequences, 200, refitted
  ``--iterations`` times, 5, to the best tenth)
  on ``--episodes`` real episodes, and with ``--true-dynamics`` through the task's own
  step instead (the bound a perfect model gives this planner);
- ``branch``: ``--rounds`` searches of 400 Adam steps each, one after the other, up
  the return of 30-step roll-outs branched from the agent's stored states (part
  fourteen's search, the agent's default since), from the acting weights (``--fresh``:
  from new ones), each judged over the whole episode as the agent judges it; the
  weights' model return and greedy return after each;
- ``distill``: ``--rounds`` rounds of DAgger (Ross et al. 2011): the network fitted by
  least squares to the model-MPC's actions at the states the student (the MPC itself
  in round 0) visits, its greedy return after each round.

    .venv/bin/python research/heldout/probe_swingup.py mpc --seed 2 --steps 2500
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cartpole_swingup as cp  # (registers the task)

CEM = {"samples": 200, "iterations": 5, "elites": 20, "init_std": 6.0, "min_std": 0.1}


def load_agent(path: Path, seed: int, steps: int) -> Any:
    from geoq.agents import GPQAgent

    if path.exists():
        return GPQAgent.load(path)
    agent = GPQAgent(cp.CARTPOLE_SWING_UP_ID, seed=seed)
    agent.learn(steps)
    agent.save(path)
    return agent


def greedy_return(agent: Any, weights: np.ndarray, episodes: int = 10) -> float:
    """The mean greedy return of ``weights`` acting in the agent's place."""
    from geoq.experiments.control.evaluation import evaluate_agent

    fb = agent.planning.feedback
    saved = fb.gains, fb.acting, fb.kept
    fb.gains, fb.acting, fb.kept = weights, True, None
    try:
        return float(evaluate_agent(agent, cp.CARTPOLE_SWING_UP_ID, episodes, 77).returns.mean())
    finally:
        fb.gains, fb.acting, fb.kept = saved


def cem_first_action(score: Any, mean: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The CEM's mean action sequence ``[H]`` for ``score`` (sequences ``[P, H]`` -> ``[P]``)."""
    std = np.full(mean.shape, CEM["init_std"])
    for _ in range(CEM["iterations"]):
        A = np.clip(mean + std * rng.standard_normal((CEM["samples"], len(mean))), -cp.FORCE,
                    cp.FORCE)  # fmt: skip
        elites = A[np.argsort(-score(A))[: CEM["elites"]]]
        mean, std = elites.mean(axis=0), elites.std(axis=0) + CEM["min_std"]
    return mean


def model_score(model: Any, o: np.ndarray) -> Any:
    d = model.obs_dim

    def score(A: np.ndarray) -> np.ndarray:
        S, ret, alive = np.repeat(o[None], len(A), axis=0), np.zeros(len(A)), np.ones(len(A))
        for h in range(A.shape[1]):
            m = model.predict_mean(S, A[:, h : h + 1])
            S = S + m[:, :d]
            ret += alive * m[:, d]
            alive *= m[:, d + 1] < 0.5
        return ret

    return score


def true_score(z: np.ndarray) -> Any:
    def score(A: np.ndarray) -> np.ndarray:
        Z, ret, alive = np.repeat(z[None], len(A), axis=0), np.zeros(len(A)), np.ones(len(A))
        for h in range(A.shape[1]):
            Z = cp.cartpole_step(Z, A[:, h])
            alive *= np.abs(Z[:, 0]) <= cp.RAIL
            ret += alive * cp.reward(Z)
        return ret

    return score


def episode(act: Any, rng: np.random.Generator) -> tuple[float, list[np.ndarray]]:
    """One real episode from a noisy hanging start; ``act(z, o)`` gives the force."""
    z = np.array([0.0, 0.0, np.pi, 0.0]) + rng.normal(0.0, 0.05, 4)
    total, seen = 0.0, []
    for _ in range(cp.MAX_STEPS):
        seen.append(cp.observe(z))
        z = cp.cartpole_step(z, float(act(z, seen[-1])))
        total += float(cp.reward(z))
        if abs(z[0]) > cp.RAIL:
            break
    return total, seen


def run_search(agent: Any, specs: list[str], halt: bool) -> None:
    import geoq.models.policy_gradient as pg
    from geoq.models import search_policy

    fb, model = agent.planning.feedback, agent.planning.model
    support, soft = model.support, pg._soft_return
    values: list[float] = []

    def logged(*args: Any) -> Any:
        out = soft(*args)
        values.append(out[0])
        return out

    pg._soft_return = logged
    if not halt:
        support.distance = lambda s: np.zeros(len(s))
        support.distance_gradient = lambda s: (np.zeros(len(s)), np.zeros_like(s))
    print(f"acting weights: model {fb.value:.1f}, greedy {greedy_return(agent, fb.gains):.1f}")
    for spec in specs or [""]:
        kw = {k: type(getattr(fb.gradient_settings, k))(v) for k, v in
              (item.split("=") for item in spec.split(",") if item)}  # fmt: skip
        settings = dataclasses.replace(fb.gradient_settings, budget=1e14, **kw)
        values.clear()
        w, v = search_policy(model, fb.policy, fb.gains, fb.starts, np.random.default_rng(5),
                             settings)  # fmt: skip
        trace = [round(x, 1) for x in values[:: max(1, len(values) // 8)]]
        moved = not np.array_equal(w, fb.gains)
        print(f"{spec or 'defaults'}: smooth returns {trace}, best {max(values):.1f}; found: "
              f"model {v:.1f}, greedy {greedy_return(agent, w):.1f}, moved {moved}")  # fmt: skip


def run_mpc(agent: Any, episodes: int, horizon: int, true_dynamics: bool) -> None:
    rng = np.random.default_rng(0)
    for k in range(episodes):
        plan, start = np.zeros(horizon), time.perf_counter()

        def act(z: np.ndarray, o: np.ndarray) -> float:
            nonlocal plan
            score = true_score(z) if true_dynamics else model_score(agent.planning.model, o)
            plan = cem_first_action(score, plan, rng)
            first, plan = plan[0], np.r_[plan[1:], 0.0]
            return first

        total, seen = episode(act, rng)
        print(f"episode {k}: return {total:.1f} over {len(seen)} steps "
              f"({time.perf_counter() - start:.0f} s)", flush=True)  # fmt: skip


def run_branch(agent: Any, rounds: int, fresh: bool) -> None:
    from dataclasses import replace

    from geoq.agents.policy_planning import BRANCH
    from geoq.models import search_policy

    fb, model = agent.planning.feedback, agent.planning.model
    states = agent.buffer.arrays()[0]
    rng = np.random.default_rng(0)
    w = fb.policy.initial(rng) if fresh else fb.gains
    settings = replace(BRANCH, horizon=fb.horizon, budget=1e14)  # the agent's, 400 Adam steps
    print(f"start: greedy {greedy_return(agent, w):.1f}", flush=True)
    for k in range(rounds):
        start = time.perf_counter()
        found, value = search_policy(model, fb.policy, w, fb.starts, rng, settings, states)
        kept = np.array_equal(found, w)
        w = found
        print(f"search {k}: model {value:.1f}, greedy {greedy_return(agent, w):.1f}, "
              f"{'kept' if kept else 'moved'} ({time.perf_counter() - start:.0f} s)",
              flush=True)  # fmt: skip


def run_distill(agent: Any, rounds: int, horizon: int) -> None:
    from scipy.optimize import minimize

    fb, model = agent.planning.feedback, agent.planning.model
    policy = fb.policy
    rng, X, U, w = np.random.default_rng(0), [], [], fb.gains

    def loss(weights: np.ndarray) -> tuple[float, np.ndarray]:
        S, target = np.array(X), np.array(U)[:, None]
        actions, cache = policy.forward(weights, S)
        r = actions - target
        return float((r**2).mean()), policy.backward(weights, cache, 2 * r / len(S))[0]

    for k in range(rounds):
        plan = np.zeros(horizon)

        def act(z: np.ndarray, o: np.ndarray, k: int = k, w: np.ndarray = w) -> float:
            nonlocal plan
            plan = cem_first_action(model_score(model, o), plan, rng)
            X.append(o)
            U.append(plan[0])
            teacher, plan = plan[0], np.r_[plan[1:], 0.0]
            return teacher if k == 0 else float(policy.act(w, o[None])[0, 0])

        total, _ = episode(act, rng)
        w = minimize(loss, w, jac=True, method="L-BFGS-B", options={"maxiter": 2000}).x
        print(f"round {k}: roll-out return {total:.1f}; fitted on {len(X)} states, greedy "
              f"{greedy_return(agent, w):.1f}", flush=True)  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("probe", choices=["search", "mpc", "branch", "distill"])
    parser.add_argument("specs", nargs="*", help="search: settings as key=value[,key=value]")
    parser.add_argument("--seed", type=int, default=2)
    parser.add_argument("--steps", type=int, default=2500)
    parser.add_argument("--agent", type=Path, default=None, help="default /tmp/cps_SEED_STEPS.npz")
    parser.add_argument("--no-halt", action="store_true")
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--horizon", type=int, default=40)
    parser.add_argument("--true-dynamics", action="store_true")
    parser.add_argument("--samples", type=int, default=CEM["samples"])
    parser.add_argument("--iterations", type=int, default=CEM["iterations"])
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--fresh", action="store_true", help="branch: from new weights")
    args = parser.parse_args()
    path = args.agent or Path(f"/tmp/cps_{args.seed}_{args.steps}.npz")
    CEM.update(samples=args.samples, iterations=args.iterations,
               elites=max(2, args.samples // 10))  # fmt: skip
    agent = load_agent(path, args.seed, args.steps)
    if args.probe == "search":
        run_search(agent, args.specs, halt=not args.no_halt)
    elif args.probe == "mpc":
        run_mpc(agent, args.episodes, args.horizon, args.true_dynamics)
    elif args.probe == "branch":
        run_branch(agent, args.rounds, args.fresh)
    else:
        run_distill(agent, args.rounds, args.horizon)


if __name__ == "__main__":
    main()
