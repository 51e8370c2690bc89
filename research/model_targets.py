"""One fitted-Q phase with the model's one-step transitions beside the stored ones (issue 46).

MBPO (Janner et al. 2019) trains its value function on short roll-outs of a learned model
branched from stored states. This probe asks whether ``Q`` learns from more than its own
greedy neighbourhood that way. On agents saved at each checkpoint by
``research/checkpoint_actors.py --save DIR``, it prints per checkpoint ``Q``'s greedy
return (10 episodes, evaluation seed ``10_000 + SEED``, no policy) before any phase,
after one more phase of the agent's own (the control), and after one phase whose sweeps
and refit also hold imagined transitions:

- from ``--per-state`` copies of each stored state in the window, an action drawn (the
  stored action plus ``--noise`` half-ranges of Gaussian noise, clipped to the box; or,
  ``--actions uniform``, uniform over the box; or, ``--actions greedy``, ``Q``'s greedy
  action there plus that noise, MBPO's current policy; or, ``--actions copy``, no model:
  the stored transitions themselves a second time, the control for the rows' count);
- the model's mean one step on (``agent.planning.model``, refit on the window first):
  next state, reward, and termination where its predicted probability is above 1/2;
- kept only where the next state lies among the data (``model.support`` distance at most
  1: MOReL's halt, Kidambi et al. 2020).

The phase is the agent's (:class:`geoq.agents.fitted_q.FittedQPhase`: the same sweeps on
the same basis), except that the GP is refit to every row, imagined ones included;
``--refit stored`` refits it to the stored rows only, as the agent's ``replay="graph"``
does (the imagined rows then shape the stored targets only). ``--greedy candidates`` acts
on the candidates' best, where the data's rule seeks only among actions taken.
``--fit-only`` runs no phase: it prints, per checkpoint, how well the refit model
reproduces the window's own transitions (the reward's RMSE against its std, the state
change's RMSE over its std averaged over the state's inputs, and the terminations whose
predicted probability is above 1/2, at them and elsewhere)::

    python research/checkpoint_actors.py Walker2d-v5 --seed 3 --save runs/w3
    python research/model_targets.py Walker2d-v5 --seed 3 --load runs/w3
"""

from __future__ import annotations

import argparse
import copy
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

EPISODES = 10


def imagine(agent: Any, per_state: int, noise: float, actions: str,
            rng: np.random.Generator) -> Any:  # fmt: skip
    """Imagined one-step transitions from the window's states (module docstring)."""
    from geoq.agents.buffer import Transitions

    stored = agent.buffer.transitions(last=agent.config.window)
    if actions == "copy":
        return stored, np.ones(len(stored), dtype=bool)
    model = agent.planning.model
    agent.planning._fit(agent.buffer, rng)
    S = np.repeat(stored.states, per_state, axis=0)
    lo, hi = agent.action_low, agent.action_high
    if actions == "uniform":
        A = rng.uniform(lo, hi, size=(S.shape[0], lo.shape[0]))
    else:
        A = stored.actions if actions == "noise" else greedy(agent, stored.states)
        A = np.repeat(A, per_state, axis=0)
        A = np.clip(A + noise * 0.5 * (hi - lo) * rng.standard_normal(A.shape), lo, hi)
    mean = model.predict_mean(S, A)
    d = agent.obs_dim
    S2, R, ends = S + mean[:, :d], mean[:, d], mean[:, d + 1] > 0.5
    inside = model.support.distance(S2) <= 1.0
    return Transitions(S[inside], A[inside], R[inside], S2[inside], ends[inside]), inside


def fit_report(agent: Any, rng: np.random.Generator) -> str:
    """How the refit model reproduces the window's transitions (``--fit-only``)."""
    stored, d = agent.buffer.transitions(last=agent.config.window), agent.obs_dim
    agent.planning._fit(agent.buffer, rng)
    model = agent.planning.model
    mean = model.predict_mean(stored.states, stored.actions)
    change = stored.next_states - stored.states
    rel = np.sqrt(
        np.mean((mean[:, :d] - change) ** 2, axis=0) / np.maximum(change.var(axis=0), 1e-12)
    )
    ends, said = stored.terminated.astype(bool), mean[:, d + 1] > 0.5
    return (
        f"reward RMSE {np.sqrt(np.mean((mean[:, d] - stored.rewards) ** 2)):.3f} (std "
        f"{stored.rewards.std():.3f}) | state change RMSE / std {rel.mean():.3f} | ends "
        f"{ends.sum()}: said at {np.sum(said & ends)}, elsewhere {np.sum(said & ~ends)}"
    )


def greedy(agent: Any, states: Any) -> Any:
    """``Q``'s greedy actions ``[n, d_a]`` at ``states`` by the agent's own rule."""
    from geoq.agents.greedy_data import greedy_in_data

    mean = agent.gp.predict(agent._scaled_candidate_inputs(states))  # standardised: same order
    best = agent.candidates[np.argmax(mean.reshape(states.shape[0], -1), axis=1)]
    return greedy_in_data(agent, states, best) if agent.config.greedy_actions == "data" else best


def model_phase(agent: Any, imagined: Any, refit_all: bool) -> int:
    """The agent's phase with ``imagined`` after the stored rows, the GP refit to all of
    them (``refit_all``) or to the stored ones."""
    from geoq.agents.fitted_q import fitted_q_sweeps, standardisation

    c, stored = agent.config, agent.buffer.transitions(last=agent.config.window)
    inp = agent._phase_inputs(stored)
    data, N = stored.then(imagined), len(stored)
    y_im = inp.y_mean + inp.y_scale * agent.gp.predict(inp.inputs(imagined))
    y0 = np.concatenate([inp.targets, np.clip(y_im, *inp.bounds)])
    system = agent.gp.projected_system(inp.inputs(data))
    K_next, slots = agent.phase.next_state_covariances(inp, data.next_states, N)
    result = fitted_q_sweeps(
        system, K_next, data.rewards, 1.0 - data.terminated.astype(np.float64), c.gamma, y0,
        y_mean=inp.y_mean, y_scale=inp.y_scale, max_sweeps=c.max_sweeps,
        tol=c.sweep_tol * inp.y_scale, bounds=inp.bounds, slots=slots,
    )  # fmt: skip
    mean, scale = standardisation(result.targets[:N], inp.bounds, c.prior)
    y = result.targets if refit_all else result.targets[:N]
    agent.gp.refit_projected(system if refit_all else system.head(N), (y - mean) / scale)
    agent.buffer.set_targets(result.targets[:N])
    agent.state.y_mean, agent.state.y_scale = mean, scale
    return result.sweeps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--load", type=Path, required=True, help="checkpoint_actors' --save")
    parser.add_argument("--per-state", type=int, default=1)
    parser.add_argument("--noise", type=float, default=0.3)
    parser.add_argument(
        "--actions", choices=("noise", "uniform", "greedy", "copy"), default="noise"
    )
    parser.add_argument("--refit", choices=("all", "stored"), default="all")
    parser.add_argument("--fit-only", action="store_true")
    parser.add_argument("--greedy", choices=("data", "candidates"), default="data")
    args = parser.parse_args()

    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent

    print("steps | the model on the window's transitions" if args.fit_only else
          "steps | greedy before | after a phase | after a phase with the model | "
          "imagined kept of drawn | sweeps")  # fmt: skip
    for path in sorted(args.load.glob("*.npz"), key=lambda p: int(p.stem.split("_")[-1])):
        agent = GPQAgent.load(path, env=args.env)
        agent.planning.feedback.acting, agent.planning.feedback.kept = False, None  # Q's own
        agent.config = replace(agent.config, greedy_actions=args.greedy)
        agent.phase.config = agent.config

        if args.fit_only:
            report = fit_report(agent, np.random.default_rng(args.seed))
            print(f"{path.stem.split('_')[-1]} | {report}", flush=True)
            continue

        def returns(actor: Any) -> float:
            result = evaluate_agent(actor, args.env, EPISODES, seed=10_000 + args.seed)
            return float(result.returns.mean())

        before = returns(agent)
        control = copy.deepcopy(agent)
        control._train()
        rng = np.random.default_rng(args.seed)
        imagined, inside = imagine(agent, args.per_state, args.noise, args.actions, rng)
        sweeps = model_phase(agent, imagined, args.refit == "all")
        print(
            f"{path.stem.split('_')[-1]} | {before:.1f} | {returns(control):.1f} | "
            f"{returns(agent):.1f} | {len(imagined)} of {len(inside)} | {sweeps}",
            flush=True,
        )


if __name__ == "__main__":
    main()
