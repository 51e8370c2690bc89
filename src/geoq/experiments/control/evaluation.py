"""Evaluating control: deterministic episodes, and learning with evaluation checkpoints.

Shared by the GP agent's benchmark (:mod:`geoq.experiments.control.benchmark`) and the
baselines (:mod:`geoq.experiments.control.baselines`), so that every learner is trained
in the same chunks and evaluated the same way.

* :func:`evaluate_agent`: deterministic episodes from the env's default reset,
  run in lockstep so that each step is one batched ``predict``.
* :func:`learn_with_checkpoints`: learn in chunks of ``eval_every`` steps of a
  :class:`ControlCell`, evaluating after each.
* :class:`EvalCallback`: greedy evaluations while an agent learns in one call, through
  :meth:`GPQAgent.learn`'s episode callback (Stable-Baselines3's ``EvalCallback``);
  ``geoq train`` plots them beside the training returns.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import gymnasium
import numpy as np

from geoq.experiments.stats import mean_interval
from geoq.tasks import KNOWN_TASKS

__all__ = [
    "EVAL_COLUMNS",
    "Actor",
    "ControlCell",
    "EvalCallback",
    "Evaluation",
    "evaluate_agent",
    "evaluation_success",
    "learn_with_checkpoints",
]


@dataclass(frozen=True)
class Evaluation:
    """Deterministic evaluation episodes of an agent.

    Attributes
    ----------
    returns : undiscounted return of each episode ``[n]``.
    successes : ``info["is_success"]`` at each episode's end (1/0), NaN where unreported.
    """

    returns: np.ndarray
    successes: np.ndarray

    @property
    def success_rate(self) -> float:
        """Fraction of successful episodes (NaN if the env reports no success)."""
        s = self.successes[np.isfinite(self.successes)]
        return float(np.mean(s)) if s.size else float("nan")

    def summary(self) -> str:
        ci = mean_interval(self.returns)
        rate = self.success_rate
        rate_text = "n/a" if math.isnan(rate) else f"{rate:.2f}"
        return (
            f"mean return {ci.mean:.2f} (95% interval [{ci.low:.2f}, {ci.high:.2f}], "
            f"{len(self.returns)} episodes); success rate {rate_text}"
        )


class Actor(Protocol):
    """Anything that acts like an agent: :class:`GPQAgent`, a baseline, a fixed controller."""

    env_id: str

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[Any, None]: ...


def evaluate_agent(
    agent: Actor, env_id: str | None = None, n_episodes: int = 20, seed: int = 0
) -> Evaluation:
    """Run ``n_episodes`` deterministic (greedy) episodes from the env's default reset.

    Episode ``i`` starts from ``reset(seed=SeedSequence(seed).spawn(n)[i])``; all
    episodes advance in lockstep, one batched ``predict`` per step.
    """
    if n_episodes < 1:
        raise ValueError(f"n_episodes must be >= 1, got {n_episodes}")
    env_id = env_id or agent.env_id
    if not env_id:
        raise ValueError("the agent has no registered env id; pass env_id=")
    envs = [gymnasium.make(env_id) for _ in range(n_episodes)]
    seeds = np.random.SeedSequence(seed).spawn(n_episodes)
    obs = np.stack(
        [e.reset(seed=int(s.generate_state(1)[0]))[0] for e, s in zip(envs, seeds, strict=True)]
    )
    returns = np.zeros(n_episodes)
    successes = np.full(n_episodes, np.nan)
    active = np.ones(n_episodes, dtype=bool)
    while np.any(active):
        idx = np.flatnonzero(active)
        actions, _ = agent.predict(obs[idx].astype(np.float64), deterministic=True)
        for j, i in enumerate(idx):
            o, r, terminated, truncated, info = envs[i].step(
                actions[j].astype(envs[i].action_space.dtype)
            )
            obs[i] = o
            returns[i] += float(r)
            if terminated or truncated:
                active[i] = False
                if "is_success" in info:
                    successes[i] = float(bool(info["is_success"]))
    for e in envs:
        e.close()
    return Evaluation(returns=returns, successes=successes)


def evaluation_success(ev: Evaluation, env_id: str) -> float:
    """The success of one evaluation: its episodes' success rate if the env reports
    ``info["is_success"]``, else (a task with a ``success_return``, e.g.
    MountainCarContinuous: 90) 1.0 when the mean return reaches the threshold, else 0.0."""
    rate = ev.success_rate
    known = KNOWN_TASKS.get(env_id)
    if math.isnan(rate) and known is not None and known.success_return is not None:
        return float(np.mean(ev.returns) >= known.success_return)
    return rate


@dataclass(frozen=True)
class ControlCell:
    """One benchmark run: an agent's settings and a seed, learning for ``timesteps`` steps."""

    env_id: str
    kernel: str
    seed: int
    timesteps: int
    eval_every: int
    eval_episodes: int
    config: Mapping[str, Any] = field(default_factory=dict)
    """Other :class:`~geoq.agents.GPQConfig` fields (e.g. ``exploration``)."""

    @property
    def label(self) -> str:
        extra = ",".join(f"{k}={v}" for k, v in sorted(self.config.items()))
        return self.kernel + (f"[{extra}]" if extra else "")


def learn_with_checkpoints(
    cell: ControlCell, learn: Callable[[int], object], actor: Actor
) -> dict[str, Any]:
    """``learn(n)`` in chunks of ``cell.eval_every`` steps, evaluating ``actor`` after each.

    Returns the part of a benchmark row every learner shares: label, kernel,
    seed, checkpoints, mean evaluation return and success rate at each, the
    wall time spent in ``learn`` and its cost per step.
    """
    checkpoints: list[int] = []
    eval_returns: list[float] = []
    eval_success: list[float] = []
    learn_seconds, done = 0.0, 0
    while done < cell.timesteps:
        step = min(cell.eval_every, cell.timesteps - done)
        t0 = time.perf_counter()
        learn(step)
        learn_seconds += time.perf_counter() - t0
        done += step
        ev = evaluate_agent(actor, cell.env_id, cell.eval_episodes, seed=10_000 + cell.seed)
        checkpoints.append(done)
        eval_returns.append(float(np.mean(ev.returns)))
        eval_success.append(evaluation_success(ev, cell.env_id))
    return {
        "label": cell.label,
        "kernel": cell.kernel,
        "seed": cell.seed,
        "checkpoints": checkpoints,
        "eval_return": eval_returns,
        "eval_success": eval_success,
        "learn_seconds": learn_seconds,
        "ms_per_step": 1e3 * learn_seconds / max(done, 1),
    }


#: Columns of :attr:`EvalCallback.rows` (``evaluations.csv`` of ``geoq train``).
EVAL_COLUMNS = ("timesteps", "mean_return", "return_low", "return_high", "success", "episodes")


class LearningAgent(Actor, Protocol):
    """An :class:`Actor` that counts its steps (:class:`~geoq.agents.GPQAgent`)."""

    @property
    def num_timesteps(self) -> int: ...


class EvalCallback:
    """Greedy evaluations while an agent learns, like Stable-Baselines3's ``EvalCallback``.

    Pass it as ``agent.learn(n, callback=cb)``, then call :meth:`finish`. After the
    first finished episode at or past each multiple of ``eval_every`` steps (the
    agent's callback runs between episodes, after the episode's fitted-Q phase), and
    once more by :meth:`finish` after the last step, it runs
    :func:`evaluate_agent` with ``n_episodes`` deterministic episodes from the
    same resets each time (``seed``). Greedy actions draw nothing from the agent's
    generator and the episodes run on envs of their own, so learning goes exactly as
    without the evaluations.

    Attributes
    ----------
    rows : one dict per evaluation, keys :data:`EVAL_COLUMNS`: the agent's step count,
        the mean return with its Student-t 95% interval, the success as in
        :func:`evaluation_success`, the number of episodes.
    """

    def __init__(
        self,
        agent: LearningAgent,
        eval_every: int,
        n_episodes: int = 10,
        seed: int = 0,
        env_id: str | None = None,
    ) -> None:
        if eval_every < 1 or n_episodes < 1:
            raise ValueError(
                f"eval_every and n_episodes must be >= 1, got {eval_every} and {n_episodes}"
            )
        self.agent = agent
        self.env_id = env_id or agent.env_id
        self.eval_every = int(eval_every)
        self.n_episodes = int(n_episodes)
        self.seed = int(seed)
        self.rows: list[dict[str, Any]] = []
        self._next = (agent.num_timesteps // self.eval_every + 1) * self.eval_every

    def __call__(self, record: object) -> None:
        """The episode callback: evaluate if a multiple of ``eval_every`` was passed."""
        if self.agent.num_timesteps >= self._next:
            self.evaluate()

    def finish(self) -> None:
        """Evaluate after the last step, unless that was just done."""
        if not self.rows or self.rows[-1]["timesteps"] != self.agent.num_timesteps:
            self.evaluate()

    def evaluate(self) -> Evaluation:
        """One evaluation now; appends a row and returns it."""
        ev = evaluate_agent(self.agent, self.env_id, self.n_episodes, self.seed)
        ci = mean_interval(ev.returns)
        t = int(self.agent.num_timesteps)
        self.rows.append(
            {"timesteps": t, "mean_return": ci.mean, "return_low": ci.low,
             "return_high": ci.high, "success": evaluation_success(ev, self.env_id),
             "episodes": self.n_episodes}
        )  # fmt: skip
        self._next = (t // self.eval_every + 1) * self.eval_every
        return ev
