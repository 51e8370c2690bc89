"""One fitted-Q phase re-run on saved agents, another way (issue 46, parts twenty-two, twenty-four).

On agents saved at each checkpoint by ``research/checkpoint_actors.py --save DIR``,
prints per checkpoint the stored targets' median and ``Q``'s greedy return (10
episodes, evaluation seed ``10_000 + SEED``, ``greedy_actions="data"``, no policy)
before and after one phase run as ``--variant`` says:

- ``converge``: the agent's own phase with ``max_sweeps`` raised to ``--max-sweeps``
  (whether the greedy returns follow where a non-converged phase stopped). Run with
  ``research/variants/data_targets.patch`` applied and ``GEOQ_TARGETS_DATA=1``, it is
  that prototype's phase (the targets' max over the actions taken near ``s'``).
- ``twins``: clipped double Q on the agent's basis (Fujimoto et al. 2018): two posteriors
  from the even and the odd episodes, every target ``r + gamma min(Q_A, Q_B)(s', a*)``
  at the candidate ``a*`` best by their mean, swept up to ``--max-sweeps`` times; the
  agent is then refit to those targets.
- ``pessimism``: lower-confidence targets ``r + gamma max_k (Q - beta std)(s', a_k)``,
  ``std`` ``Q``'s posterior std at each next state x candidate (in the targets' standard
  units; it does not depend on the targets, so it is computed once), ``beta`` from
  ``--beta``, swept up to ``--max-sweeps`` times; the agent is then refit to them
  (part twenty-four).

::

    python research/checkpoint_actors.py Walker2d-v5 --seed 3 --save runs/w3
    python research/phase_variants.py Walker2d-v5 --seed 3 --load runs/w3 --variant twins
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

EPISODES = 10


def _twins(agent: Any, max_sweeps: int) -> tuple[int, float]:
    """Clipped double-Q targets (module docstring) installed in ``agent``; the sweeps run
    and the last sweep's largest change."""
    from geoq.agents.fitted_q import standardisation
    from geoq.gp._resync import _system

    stored = agent.buffer.transitions(last=agent.config.window)
    N, inp, gp = len(stored), agent._phase_inputs(stored), agent.gp
    system = gp.projected_system(inp.inputs(stored))
    K_next, slots = agent.phase.next_state_covariances(inp, stored.next_states, N)
    new = np.ones(N, dtype=bool)
    new[1:] = ~np.all(stored.states[1:] == stored.next_states[:-1], axis=1)
    odd = np.cumsum(new) % 2 == 1
    halves = [
        _system(system.basis, system.R, system.V[:, mask], system.noise, system.config)
        for mask in (odd, ~odd)
    ]  # fmt: skip
    gamma, y_mean, y_scale, (lo, hi) = agent.config.gamma, inp.y_mean, inp.y_scale, inp.bounds
    continues = 1.0 - stored.terminated.astype(np.float64)
    y, rows, change, sweeps = inp.targets.copy(), np.arange(N), np.inf, 0
    weights = [np.zeros(K_next.n_columns), np.zeros(K_next.n_columns)]
    while sweeps < max_sweeps and change > agent.config.sweep_tol * y_scale:
        for w, half, mask in zip(weights, halves, (odd, ~odd), strict=True):
            w[slots] = half.mean_weights((y[mask] - y_mean) / y_scale)
        qa, qb = K_next.q(weights[0]), K_next.q(weights[1])
        best = np.argmax(qa + qb, axis=1)
        value = np.minimum(qa[rows, best], qb[rows, best])
        y_new = np.clip(stored.rewards + gamma * continues * (y_mean + y_scale * value), lo, hi)
        change, y, sweeps = float(np.max(np.abs(y_new - y))), y_new, sweeps + 1
    mean, scale = standardisation(y, inp.bounds, agent.config.prior)
    gp.refit_projected(system, (y - mean) / scale)
    agent.buffer.set_targets(y)
    agent.state.y_mean, agent.state.y_scale = mean, scale
    return sweeps, change


def _pessimism(agent: Any, beta: float, max_sweeps: int) -> tuple[int, float]:
    """Lower-confidence targets ``r + gamma max_k (Q - beta std)(s', a_k)`` on the agent's
    basis, with the posterior std of ``Q`` (fixed within a phase: it does not depend on
    the targets) at every next state x candidate; the agent is then refit to them."""
    from geoq.agents.fitted_q import standardisation

    stored = agent.buffer.transitions(last=agent.config.window)
    N, inp, gp = len(stored), agent._phase_inputs(stored), agent.gp
    system = gp.projected_system(inp.inputs(stored))
    y_mean, y_scale, (lo, hi) = inp.y_mean, inp.y_scale, inp.bounds
    gp.refit_projected(system, (inp.targets - y_mean) / y_scale)  # the std on this data
    cands = inp.candidates
    std = np.empty((N, cands.shape[0]))
    for k in range(cands.shape[0]):
        X = inp.scaling.transform_pairs(stored.next_states, cands[k : k + 1])
        std[:, k] = gp.predict(X, return_std=True)[1]
    K_next, slots = agent.phase.next_state_covariances(inp, stored.next_states, N)
    gamma, continues = agent.config.gamma, 1.0 - stored.terminated.astype(np.float64)
    y, change, sweeps = inp.targets.copy(), np.inf, 0
    weights = np.zeros(K_next.n_columns)
    while sweeps < max_sweeps and change > agent.config.sweep_tol * y_scale:
        weights[slots] = system.mean_weights((y - y_mean) / y_scale)
        value = np.max(K_next.q(weights) - beta * std, axis=1)
        y_new = np.clip(stored.rewards + gamma * continues * (y_mean + y_scale * value), lo, hi)
        change, y, sweeps = float(np.max(np.abs(y_new - y))), y_new, sweeps + 1
    print(
        f"  std: median {np.median(std):.3f}, of the smallest per next state "
        f"{np.median(np.min(std, axis=1)):.3f}",
        flush=True,
    )
    mean, scale = standardisation(y, inp.bounds, agent.config.prior)
    gp.refit_projected(system, (y - mean) / scale)
    agent.buffer.set_targets(y)
    agent.state.y_mean, agent.state.y_scale = mean, scale
    return sweeps, change


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--load", type=Path, required=True, help="checkpoint_actors' --save")
    parser.add_argument("--variant", choices=("converge", "twins", "pessimism"), required=True)
    parser.add_argument("--max-sweeps", type=int, default=1000)
    parser.add_argument("--beta", type=float, default=1.0, help="pessimism's std multiple")
    args = parser.parse_args()

    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent

    print("steps | targets before -> after | sweeps, last change | greedy before -> after")
    for path in sorted(args.load.glob("*.npz"), key=lambda p: int(p.stem.split("_")[-1])):
        agent = GPQAgent.load(path, env=args.env)
        agent.planning.feedback.acting, agent.planning.feedback.kept = False, None  # Q's own
        agent.config = replace(agent.config, greedy_actions="data", max_sweeps=args.max_sweeps)
        agent.phase.config = agent.config

        def greedy(agent: Any = agent) -> float:
            result = evaluate_agent(agent, args.env, EPISODES, seed=10_000 + args.seed)
            return float(result.returns.mean())

        before, g_before = np.median(agent.buffer.targets()), greedy()
        if args.variant == "twins":
            sweeps, change = _twins(agent, args.max_sweeps)
        elif args.variant == "pessimism":
            sweeps, change = _pessimism(agent, args.beta, args.max_sweeps)
        else:
            sweeps = agent._train()
            change = agent.log.fitted_q_residuals[-1]
        after = np.median(agent.buffer.targets())
        print(
            f"{path.stem.split('_')[-1]} | {before:.1f} -> {after:.1f} | {sweeps}, {change:.3f}"
            f" | {g_before:.1f} -> {greedy():.1f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
