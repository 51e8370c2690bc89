"""What the greedy policy does while the agent learns: return, action size, prior.

Not a speed benchmark (``run.py`` does not run it): the probe behind the design notes'
section on tasks with more than three inputs. At each checkpoint it runs the greedy
evaluation of the control benchmark (:func:`geoq.experiments.control.evaluation.evaluate_agent`,
reset seeds from 10,000 + seed) and reports, over every greedy step taken:

- ``return``: the mean greedy return;
- ``|a|``: the mean absolute action in action half-ranges, ``sat`` the fraction of
  components within 5% of a bound;
- ``prior``: the fraction of steps whose chosen action's posterior std is >= 99% of the
  prior's, i.e. where the GP knows nothing of the (state, action) it acts on;
- ``gap``: the median over greedy steps of the spread of the posterior mean over the
  candidates (``max_k - min_k``, return units: how much the action matters to the
  values learned), ``std`` the median posterior std of the chosen action, beside the
  fitted-Q targets' std (``y_scale`` under ``prior="empirical"``);
- ``kept``: the fraction of the basis vectors that were basis vectors at the previous
  checkpoint, ``rescales`` the input rescalings so far (each rebuilds the GP);
- ``phases``: the fitted-Q phases since the previous checkpoint, ``stuck`` those that
  stopped at ``max_sweeps`` unconverged; ``da``: the mean absolute change of the greedy
  action (half-ranges) at (about 500 of) the previous checkpoint's evaluation states;
- ``bv``: the GP's basis vectors; with ``hyperparameters="evidence"``, ``fits`` the
  evidence fits so far and the transitions of the last, and the length-scales in use.

    python research/probe_greedy.py --env Reacher-v5 --seed 0 --steps 3000 --every 1000
    python research/probe_greedy.py --env Reacher-v5 --config '{"hyperparameters": "evidence"}'
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import gymnasium
import numpy as np

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent
from geoq.experiments.control.evaluation import evaluate_agent


class _Recorder:
    """The agent's greedy policy, recording what it chose and how much the GP knew."""

    def __init__(self, agent: GPQAgent) -> None:
        self.agent, self.env_id = agent, agent.env_id
        self.actions: list[np.ndarray] = []
        self.observations: list[np.ndarray] = []
        self.prior_fraction: list[np.ndarray] = []
        self.gap: list[np.ndarray] = []
        self.std: list[np.ndarray] = []

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[np.ndarray, None]:
        agent = self.agent
        actions, _ = agent.predict(observation, deterministic=True)
        mean, std = agent.q_candidates(np.atleast_2d(observation))
        chosen = std[np.arange(len(std)), np.argmax(mean, axis=1)]
        prior_std = agent.state.y_scale * np.sqrt(agent.config.amplitude)
        self.actions.append(np.atleast_2d(actions))
        self.observations.append(np.atleast_2d(observation))
        self.prior_fraction.append(chosen >= 0.99 * prior_std)
        self.gap.append(np.ptp(mean, axis=1))
        self.std.append(chosen)
        return actions, None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="Reacher-v5")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=3_000)
    parser.add_argument("--every", type=int, default=1_000)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--config", default="{}", help="JSON object of GPQConfig fields")
    args = parser.parse_args()
    agent = GPQAgent(gymnasium.make(args.env), seed=args.seed, **json.loads(args.config))
    half = 0.5 * (agent.action_high - agent.action_low)
    centre = 0.5 * (agent.action_high + agent.action_low)
    print(f"{args.env} seed {args.seed} {args.config} max_bv {agent.max_bv}")
    done, learn_s = 0, 0.0
    basis, phases = np.zeros((0, agent.scaling.dim)), 0
    states: np.ndarray | None = None
    previous = np.zeros((0, agent.action_dim))
    while done < args.steps:
        t0 = time.perf_counter()
        agent.learn(args.every)
        learn_s += time.perf_counter() - t0
        done += args.every
        churn = ""  # the greedy policy's change at the last checkpoint's states
        if states is not None:
            churn = f"  da {np.mean(np.abs(agent.predict(states)[0] - previous) / half):.2f}"
        sweeps = agent.log.fitted_q_sweeps[phases:]
        phases = len(agent.log.fitted_q_sweeps)
        bv = agent.scaling.inverse(agent.gp.basis_vectors)
        kept = np.mean([np.any(np.all(np.isclose(b, basis), axis=1)) for b in bv])
        basis = bv
        rec = _Recorder(agent)
        ev = evaluate_agent(rec, args.env, args.episodes, seed=10_000 + args.seed)
        size = np.abs(np.concatenate(rec.actions) - centre) / half
        prior = np.mean(np.concatenate(rec.prior_fraction))
        stuck = sum(n >= agent.config.max_sweeps for n in sweeps)
        states = np.concatenate(rec.observations)
        states = states[:: max(1, len(states) // 500)]  # at most ~500: a batched prediction
        previous = agent.predict(states)[0]
        print(
            f"{done:6d} return {np.mean(ev.returns):9.2f}  |a| {size.mean():.2f}  "
            f"sat {np.mean(size >= 0.95):.2f}  prior {prior:.2f}"
            f"  gap {np.median(np.concatenate(rec.gap)):.3g} std "
            f"{np.median(np.concatenate(rec.std)):.3g} (targets' std {agent.state.y_scale:.3g})"
            f"  {1e3 * learn_s / done:.1f} ms/step  bv {agent.gp.n_bv} kept {kept:.2f}"
            f"  rescales {agent.log.rescales}  phases {len(sweeps)} stuck {stuck}{churn}"
            + _fits(agent),
            flush=True,
        )


def _fits(agent: GPQAgent) -> str:
    """The evidence fits so far and the length-scales in use ("" without fits)."""
    fits = agent.log.evidence_fits
    if not fits:
        return ""
    kernel = agent.gp.kernel
    return (
        f"  fits {len(fits)} (last at {fits[-1]['transitions']})"
        f"  lengthscales {np.round(kernel.lengthscale, 2).tolist()}"
    )


if __name__ == "__main__":
    main()
