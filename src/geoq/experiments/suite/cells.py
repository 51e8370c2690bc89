"""The cells of ``geoq suite`` (:mod:`geoq.experiments.suite.run`): one sweep cell per
hyper-parameter fit, seed's ground truth, learner and value map, each a frozen
dataclass that identifies its computation (seeds included) and a module-level
function that computes its row."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from geoq._typing import FloatArray
from geoq.evaluation.metrics import mse
from geoq.evaluation.monte_carlo import MCEstimate, mc_q_values, sample_evaluation_pairs
from geoq.experiments.paper.fig3 import load_truth, score_learner
from geoq.experiments.paper.seeding import STREAM, rng_for
from geoq.experiments.paper.tuning import evidence_config, select_by_validation
from geoq.gp import NumericalWarning
from geoq.learners import GPQFunction, QGPConfig
from geoq.rollouts import Rollout, collect_rollouts
from geoq.tasks.suite import SUITE_TASK_IDS, SuiteTask, observe_rollouts, suite_task

__all__ = [
    "SUITE_STREAM",
    "BudgetCell",
    "MapCell",
    "TruthCell",
    "TuneCell",
    "budget_cell",
    "map_cell",
    "task_rng",
    "task_rollouts",
    "truth_cell",
    "tune_cell",
]

#: Run-wide stream of the suite: ``rng_for(root, SUITE_STREAM, task_no, ...)``, disjoint
#: from every stream of ``geoq reproduce``.
SUITE_STREAM = 2_000_000


def task_rng(root_seed: int, task_id: str, *key: int) -> np.random.Generator:
    """Stream ``key`` of task ``task_id``: ``rng_for(root_seed, SUITE_STREAM, task_no, *key)``,
    ``task_no`` the task's index in :data:`~geoq.tasks.suite.SUITE_TASK_IDS`."""
    return rng_for(root_seed, SUITE_STREAM, SUITE_TASK_IDS.index(task_id), *key)


def task_rollouts(task: SuiteTask, n: int, rng: np.random.Generator) -> list[Rollout]:
    """``n`` roll-outs of the task's evaluation policy from its start distribution."""
    return collect_rollouts(
        n,
        task.rollout_steps,
        task.policy,
        rng,
        gamma=task.gamma,
        start=task.sample_starts,
        step=task.step,
    )


def _base_learner(task: SuiteTask, learner: dict[str, Any]) -> QGPConfig:
    return QGPConfig.from_dict(learner).replace(scaling=task.scaling)


# --------------------------------------------------------------------------- cells
@dataclass(frozen=True)
class TuneCell:
    """Hyper-parameters of one kernel on one task (``euclidean``: evidence; else validation,
    which starts from the evidence's prior variance and noise in ``shared``)."""

    task: str
    kernel: str
    root_seed: int
    tune_pairs: int
    tune_mc_rollouts: int
    tune_max_bv: int
    eval_rollouts: int
    graph_eps: tuple[float, ...]
    learner: dict[str, Any]
    shared: dict[str, Any] | None = None


def tune_cell(cell: TuneCell) -> dict[str, Any]:
    """``{"config": chosen QGPConfig dict, "evidence" | "validation": the evidence}``.

    Repairs of the indefinite geodesic Gram matrices (:class:`NumericalWarning`) are
    expected while scanning the grid and are not shown (the evidence records its own).
    """
    with warnings.catch_warnings(), np.errstate(over="ignore"):
        warnings.simplefilter("ignore", NumericalWarning)
        return _tune_cell(cell)


def _pairs_with_truth(
    task: SuiteTask,
    n_pairs: int,
    n_pair_rollouts: int,
    pair_rng: np.random.Generator,
    mc_rollouts: int,
    mc_rng: np.random.Generator,
) -> tuple[FloatArray, FloatArray, MCEstimate]:
    """State-action pairs from roll-outs of the task's policy and their Monte-Carlo ``Q^pi``."""
    states, actions = sample_evaluation_pairs(
        n_pairs,
        task.policy,
        pair_rng,
        n_rollouts=n_pair_rollouts,
        steps=task.rollout_steps,
        start=task.sample_starts,
        step=task.step,
    )
    mc = mc_q_values(
        states, actions, task.policy, mc_rng, n_rollouts=mc_rollouts, gamma=task.gamma,
        step=task.step,
    )  # fmt: skip
    return states, actions, mc


def _tune_cell(cell: TuneCell) -> dict[str, Any]:
    task = suite_task(cell.task)
    rollouts = observe_rollouts(
        task, task_rollouts(task, task.train_rollouts, task_rng(cell.root_seed, cell.task, 0))
    )
    if cell.kernel == "euclidean":
        shared, evidence = evidence_config(
            rollouts, _base_learner(task, cell.learner), task_rng(cell.root_seed, cell.task, 1)
        )
        return {"config": shared.replace(kernel="euclidean").as_dict(), "evidence": evidence}
    assert cell.shared is not None
    shared = QGPConfig.from_dict(cell.shared)
    shared = shared.replace(lengthscale=QGPConfig.from_dict(cell.learner).lengthscale)
    states, actions, mc = _pairs_with_truth(
        task,
        cell.tune_pairs,
        max(2, cell.eval_rollouts // 2),
        task_rng(cell.root_seed, cell.task, 2),
        cell.tune_mc_rollouts,
        task_rng(cell.root_seed, cell.task, 3),
    )
    truth = mc.mean
    best, records = select_by_validation(
        cell.kernel,
        rollouts,
        task.observed(states),
        actions,
        truth,
        shared,
        cell.graph_eps,
        cell.tune_max_bv,
    )
    return {"config": best.as_dict(), "validation": records}


@dataclass(frozen=True)
class TruthCell:
    """Evaluation pairs and Monte-Carlo ``Q^pi`` of one seed of one task."""

    task: str
    seed: int
    root_seed: int
    eval_pairs: int
    eval_rollouts: int
    mc_rollouts: int


def truth_cell(cell: TruthCell) -> dict[str, Any]:
    """Internal states, actions, Monte-Carlo mean and standard error at the evaluation pairs."""
    task = suite_task(cell.task)
    states, actions, mc = _pairs_with_truth(
        task,
        cell.eval_pairs,
        cell.eval_rollouts,
        task_rng(cell.root_seed, cell.task, cell.seed, STREAM["eval_pairs"]),
        cell.mc_rollouts,
        task_rng(cell.root_seed, cell.task, cell.seed, STREAM["monte_carlo"]),
    )
    return {
        "states": states.tolist(),
        "actions": actions.tolist(),
        "mc_mean": mc.mean.tolist(),
        "mc_stderr": mc.stderr.tolist(),
    }


@dataclass(frozen=True)
class BudgetCell:
    """One learner (kernel, budget) on one seed's data of one task."""

    task: str
    kernel: str
    max_bv: int
    seed: int
    root_seed: int
    learner: dict[str, Any]
    truth_dir: str = field(metadata={"key": False})  # where, not what: relocatable keys
    truth: dict[str, Any] = field(default_factory=dict)


def budget_cell(cell: BudgetCell) -> dict[str, Any]:
    """Fit and score one learner (:func:`geoq.experiments.paper.fig3.score_learner`)."""
    task = suite_task(cell.task)
    truth = load_truth(cell.truth_dir, cell.truth)
    internal = np.asarray(truth["states"], dtype=np.float64)
    states = task.observed(internal)
    actions = np.asarray(truth["actions"], dtype=np.float64)
    config = QGPConfig.from_dict(cell.learner).replace(kernel=cell.kernel, max_bv=cell.max_bv)
    rollouts = observe_rollouts(
        task,
        task_rollouts(
            task,
            task.train_rollouts,
            task_rng(cell.root_seed, cell.task, cell.seed, STREAM["train"]),
        ),
    )
    row: dict[str, Any] = {
        "task": cell.task,
        "kernel": cell.kernel,
        "max_bv": cell.max_bv,
        "seed": cell.seed,
    }
    row.update(
        score_learner(
            config,
            rollouts,
            states,
            actions,
            np.asarray(truth["mc_mean"], dtype=np.float64),
            np.asarray(truth["mc_stderr"]),
            focus=None if task.focus is None else task.focus(internal),
        )
    )
    return row


@dataclass(frozen=True)
class MapCell:
    """Value maps ``Q(s, f(s))`` of one task with a 2-D state: truth and one GP per kernel."""

    task: str
    root_seed: int
    grid: int
    mc_rollouts: int
    learners: dict[str, dict[str, Any]]


def map_cell(cell: MapCell) -> dict[str, Any]:
    """Monte-Carlo and GP maps on a ``grid x grid`` lattice of the task's ``map_box``."""
    task = suite_task(cell.task)
    assert task.map_box is not None
    (x0, x1), (y0, y1) = task.map_box
    # Cell centres, so that no state lies on a boundary (a wall line, a clipped edge).
    xs = x0 + (np.arange(cell.grid) + 0.5) * (x1 - x0) / cell.grid
    ys = y0 + (np.arange(cell.grid) + 0.5) * (y1 - y0) / cell.grid
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    states = np.column_stack([X.ravel(), Y.ravel()])  # [G G, 2]
    actions = task.mean_action(states)
    truth = mc_q_values(
        states,
        actions,
        task.policy,
        task_rng(cell.root_seed, cell.task, 4),
        n_rollouts=cell.mc_rollouts,
        gamma=task.gamma,
        step=task.step,
    )
    rollouts = observe_rollouts(
        task,
        task_rollouts(
            task, task.train_rollouts, task_rng(cell.root_seed, cell.task, 0, STREAM["train"])
        ),
    )
    maps = {"monte_carlo": truth.mean.tolist()}
    errors: dict[str, float] = {}
    basis: dict[str, list[list[float]]] = {}
    with warnings.catch_warnings(), np.errstate(over="ignore"):
        warnings.simplefilter("ignore", NumericalWarning)
        for name, learner in cell.learners.items():
            q = GPQFunction(QGPConfig.from_dict(learner)).fit(rollouts)
            mean = q.predict(task.observed(states), actions)
            maps[name] = np.asarray(mean).tolist()
            errors[name] = mse(mean, truth.mean)
            assert q.gp_ is not None
            basis[name] = q.config.scaling.inverse(q.gp_.basis_vectors)[:, :2].tolist()
    return {
        "x": xs.tolist(),
        "y": ys.tolist(),
        "maps": maps,
        "mse": errors,
        "basis": basis,
        "train_states": np.vstack([ro.states[:, :2] for ro in rollouts]).tolist(),
    }
