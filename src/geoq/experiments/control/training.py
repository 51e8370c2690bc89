"""``geoq train``: learn one task online with periodic greedy evaluations, then write
``learning_curve.csv``, ``evaluations.csv``, ``learning_curve.png``, ``visits.png``,
``agent.npz`` and ``config.json`` atomically (an earlier run is replaced whole).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from geoq import __version__
from geoq._io import atomic_write_json, check_run_dir, staged_run
from geoq.agents import GPQAgent
from geoq.experiments.control.evaluation import EVAL_COLUMNS, EvalCallback
from geoq.experiments.control.plotting import (
    plot_learning_curve,
    plot_training_with_evaluations,
    plot_visits,
)
from geoq.experiments.control.visits import visit_map
from geoq.experiments.outputs import save_figure, write_csv

__all__ = ["CURVE_COLUMNS", "TRAIN_FILES", "train"]

#: Columns of ``learning_curve.csv``.
CURVE_COLUMNS = ("timesteps", "episode", "return", "success")
#: The files of a ``geoq train`` run (written together; an earlier run is replaced whole).
TRAIN_FILES = (
    "learning_curve.csv", "evaluations.csv", "learning_curve.png", "visits.png", "agent.npz",
    "config.json",
)  # fmt: skip


def _curve_rows(agent: GPQAgent) -> list[dict[str, Any]]:
    return [
        {"timesteps": e.timesteps, "episode": e.episode, "return": e.ret,
         "success": "" if math.isnan(e.success) else int(e.success)}
        for e in agent.episodes
    ]  # fmt: skip


def train(
    env_id: str,
    out: str | Path,
    *,
    kernel: str = "euclidean",
    timesteps: int = 2_000,
    seed: int = 0,
    progress: bool = False,
    eval_every: int = 250,
    eval_episodes: int = 10,
    overwrite: bool = False,
    **config: Any,
) -> GPQAgent:
    """Learn with a fresh :class:`GPQAgent` and write its outputs into ``out``.

    Every ``eval_every`` steps (at the end of the episode that reaches them) and after
    the last step, ``eval_episodes`` greedy episodes (:class:`EvalCallback`, resets
    from ``10_000 + seed`` as in the benchmark); ``eval_every=0``: none. They do not
    change what the agent learns.

    Writes ``learning_curve.csv`` (``timesteps, episode, return, success`` per
    training episode), ``evaluations.csv`` (:data:`EVAL_COLUMNS` per evaluation),
    ``learning_curve.png`` (both curves), for a task with a 2-D observation ``visits.png``
    (the training states' visitation map and one greedy route from the reset of seed
    ``10_000 + seed``: :mod:`geoq.experiments.control.visits`), ``agent.npz`` and ``config.json``
    (:data:`TRAIN_FILES`), together (:func:`geoq._io.staged_run`): a failure writes
    nothing. ``out`` must not hold an earlier run unless ``overwrite`` (then that run is
    replaced whole); this, and that ``out`` can be written, is checked before learning.
    Returns the agent.
    """

    out = Path(out)
    check_run_dir(out, TRAIN_FILES, overwrite)
    agent = GPQAgent(env_id, kernel=kernel, seed=seed, **config)  # type: ignore[arg-type]
    evals = EvalCallback(agent, eval_every, eval_episodes, 10_000 + seed) if eval_every else None
    agent.learn(timesteps, progress_bar=progress, callback=evals)
    if evals is not None:
        evals.finish()
    rows = _curve_rows(agent)
    ts = np.array([r["timesteps"] for r in rows], dtype=np.float64)
    rets = np.array([r["return"] for r in rows], dtype=np.float64)
    with staged_run(out, TRAIN_FILES, overwrite=overwrite) as staging:
        write_csv(staging / "learning_curve.csv", rows, CURVE_COLUMNS)
        if evals is not None:
            write_csv(staging / "evaluations.csv", evals.rows, EVAL_COLUMNS)
            figure = plot_training_with_evaluations(ts, rets, evals.rows, env_id)
        else:
            figure = plot_learning_curve({kernel: (ts[None, :], rets[None, :])}, env_id)
        save_figure(figure, staging / "learning_curve.png")
        visits = visit_map(agent, gymnasium.make(env_id), 10_000 + seed)
        if visits is not None:
            save_figure(plot_visits(visits, env_id), staging / "visits.png")
        agent.save(staging / "agent.npz")
        atomic_write_json(
            staging / "config.json",
            {"env": env_id, "seed": seed, "timesteps": timesteps, "geoq_version": __version__,
             "eval_every": eval_every, "eval_episodes": eval_episodes,
             "agent": agent.config.as_dict(), "scaling": agent.scaling.as_dict()},
        )  # fmt: skip
    return agent
