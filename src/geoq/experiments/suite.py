"""``geoq suite``: the Fig. 3 protocol on every task of the suite (:mod:`geoq.tasks.suite`).

Pipeline per task (every step a sweep of :func:`geoq.experiments.sweep.run_sweep`,
so the run is parallel and resumable, one file per finished cell)::

    evidence (SE)        one cell per task          cells/tune/
    validation           one cell per graph kernel  cells/tune/
    ground truth         one cell per seed          cells/truth/
    budget cells         kernel x max_bv x seed     cells/fig3/
    value map (2-D)      one cell per task          cells/maps/
    ->  <task>/fig3.csv, fig3.png, fig3_refit.png, tuning.csv, value_map.csv/png,
        suite.csv (every row, with a task column), SUITE.md, config.json

* **Hyper-parameters.** Squared exponential: length-scales (one per input),
  prior variance and noise by maximum exact-GP evidence on a subsample of at
  most 500 training pairs (:func:`geoq.experiments.tuning.evidence_config`);
  the prior variance and noise are then shared by every kernel. Graph kernels
  (``nearest``, ``interpolated``, ``resistance``): their own parameters by
  held-out validation MSE against Monte-Carlo ``Q^pi``, after a refit
  (:func:`geoq.experiments.tuning.select_by_validation`; the same grids as
  ``geoq reproduce``). Tuning data come from the task's own streams, disjoint
  from every seed's.
* **One cell's protocol** is :func:`geoq.experiments.fig3.score_learner`, the
  same code as ``geoq reproduce``'s Fig. 3: train on the seed's roll-outs of the
  evaluation policy; MSE against Monte-Carlo ``Q^pi`` at pairs drawn from
  held-out roll-outs, normalised variance; online, refitted at the end, and
  refitted after every roll-out.
* **Ground truth** is Monte-Carlo ``Q^pi`` from the task's *internal* state
  (Pendulum-v1's ``[theta, theta_dot]``); the GP sees the observation.
"""

from __future__ import annotations

import platform
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import geoq
from geoq._io import atomic_write_json, atomic_write_text
from geoq.evaluation.metrics import mse
from geoq.evaluation.monte_carlo import mc_q_values, sample_evaluation_pairs
from geoq.experiments.fig3 import FIG3_COLUMNS, load_truth, score_learner
from geoq.experiments.plotting import plot_budget_curves
from geoq.experiments.seeding import STREAM, rng_for
from geoq.experiments.suite_report import (
    focus_note,
    plot_task_value_map,
    render_suite_report,
)
from geoq.experiments.sweep import cell_spec, run_sweep
from geoq.experiments.tuning import TUNING_COLUMNS, evidence_config, select_by_validation
from geoq.gp import NumericalWarning
from geoq.learners import KERNEL_NAMES, GPQFunction, QGPConfig
from geoq.rollouts import Rollout, collect_rollouts
from geoq.tasks.suite import SUITE_TASK_IDS, SuiteTask, observe_rollouts, suite_task

__all__ = [
    "SUITE_COLUMNS",
    "SUITE_SCALES",
    "SuiteConfig",
    "run_suite",
    "suite_config",
    "task_slug",
]

#: Run-wide stream of the suite: ``rng_for(root, SUITE_STREAM, task_no, ...)``, disjoint
#: from every stream of ``geoq reproduce``.
SUITE_STREAM = 2_000_000

#: Columns of the per-task ``fig3.csv`` and of ``suite.csv``.
SUITE_COLUMNS: tuple[str, ...] = (
    "task",
    *(c for c in FIG3_COLUMNS if c != "mse_td"),
    "mse_focus",
    "mse_refit_focus",
)


@dataclass(frozen=True)
class SuiteConfig:
    """Everything that defines one run of ``geoq suite`` (per-task settings live in
    :class:`geoq.tasks.suite.SuiteTask`)."""

    scale: str = "quick"
    """Name of the preset."""
    root_seed: int = 2012
    """Root of every random stream."""
    seeds: int = 3
    """Independent repetitions per task (training roll-outs, evaluation pairs, truth)."""
    budgets: tuple[int, ...] = (10, 25, 50, 100)
    """``max_bv`` values."""
    eval_pairs: int = 100
    """Evaluation state-action pairs per seed, drawn from held-out roll-outs."""
    eval_rollouts: int = 10
    """Held-out roll-outs the evaluation pairs are drawn from."""
    mc_rollouts: int = 30
    """Monte-Carlo roll-outs per evaluation pair."""
    tune_pairs: int = 60
    """Held-out validation pairs for the graph kernels' hyper-parameters."""
    tune_mc_rollouts: int = 20
    """Monte-Carlo roll-outs per validation pair."""
    tune_max_bv: int = 50
    """Basis budget while validating."""
    graph_eps: tuple[float, ...] = (0.3, 0.5)
    """Graph thresholds (JC12 eq. 2) on the validation grid."""
    map_grid: int = 25
    """Value maps (2-D states): ``map_grid x map_grid`` states."""
    map_mc_rollouts: int = 8
    """Monte-Carlo roll-outs per map state."""
    map_max_bv: int = 50
    """Basis budget of the GPs drawn in the value maps."""
    kernels: tuple[str, ...] = KERNEL_NAMES
    """Learners compared; ``euclidean`` (the squared exponential) is the baseline."""
    learner: QGPConfig = field(default_factory=QGPConfig)
    """Base learner settings (scaling, kernel, budget and tuned values are set per cell)."""

    def __post_init__(self) -> None:
        for name in (
            "seeds",
            "eval_pairs",
            "eval_rollouts",
            "mc_rollouts",
            "tune_pairs",
            "tune_mc_rollouts",
            "tune_max_bv",
            "map_grid",
            "map_mc_rollouts",
            "map_max_bv",
        ):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if self.mc_rollouts < 2 or self.tune_mc_rollouts < 2 or self.map_mc_rollouts < 2:
            raise ValueError("Monte-Carlo roll-out counts must be >= 2 (for standard errors)")
        if not self.budgets or any(int(b) < 1 for b in self.budgets):
            raise ValueError(f"budgets must be integers >= 1, got {self.budgets}")
        if "euclidean" not in self.kernels or any(k not in KERNEL_NAMES for k in self.kernels):
            raise ValueError(
                f"kernels must include 'euclidean' and come from {KERNEL_NAMES}, got {self.kernels}"
            )

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["learner"] = self.learner.as_dict()
        for name in ("budgets", "graph_eps", "kernels"):
            out[name] = list(out[name])
        return out


#: Presets of ``geoq suite --scale``.
SUITE_SCALES: dict[str, SuiteConfig] = {
    "quick": SuiteConfig(),
    "full": SuiteConfig(
        scale="full",
        seeds=10,
        budgets=(5, 10, 20, 35, 50, 75, 100, 150),
        eval_pairs=200,
        eval_rollouts=20,
        mc_rollouts=50,
        tune_pairs=100,
        tune_mc_rollouts=30,
        tune_max_bv=100,
        map_grid=30,
        map_mc_rollouts=16,
        map_max_bv=50,
    ),
}


def suite_config(scale: str, root_seed: int | None = None) -> SuiteConfig:
    """The preset called ``scale`` (``quick`` or ``full``), optionally with another root seed."""
    if scale not in SUITE_SCALES:
        raise ValueError(f"scale must be one of {sorted(SUITE_SCALES)}, got {scale!r}")
    cfg = SUITE_SCALES[scale]
    return cfg if root_seed is None else replace(cfg, root_seed=int(root_seed))


def task_slug(task_id: str) -> str:
    """A directory name for a task id: ``geoq/TwoRooms-v0`` -> ``geoq_TwoRooms-v0``."""
    return task_id.replace("/", "_")


def _rng(root_seed: int, task_id: str, *key: int) -> np.random.Generator:
    return rng_for(root_seed, SUITE_STREAM, SUITE_TASK_IDS.index(task_id), *key)


def _rollouts(task: SuiteTask, n: int, rng: np.random.Generator) -> list[Rollout]:
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


def _tune_cell(cell: TuneCell) -> dict[str, Any]:
    task = suite_task(cell.task)
    rollouts = observe_rollouts(
        task, _rollouts(task, task.train_rollouts, _rng(cell.root_seed, cell.task, 0))
    )
    if cell.kernel == "euclidean":
        shared, evidence = evidence_config(
            rollouts, _base_learner(task, cell.learner), _rng(cell.root_seed, cell.task, 1)
        )
        return {"config": shared.replace(kernel="euclidean").as_dict(), "evidence": evidence}
    assert cell.shared is not None
    shared = QGPConfig.from_dict(cell.shared)
    shared = shared.replace(lengthscale=QGPConfig.from_dict(cell.learner).lengthscale)
    states, actions = sample_evaluation_pairs(
        cell.tune_pairs,
        task.policy,
        _rng(cell.root_seed, cell.task, 2),
        n_rollouts=max(2, cell.eval_rollouts // 2),
        steps=task.rollout_steps,
        start=task.sample_starts,
        step=task.step,
    )
    truth = mc_q_values(
        states,
        actions,
        task.policy,
        _rng(cell.root_seed, cell.task, 3),
        n_rollouts=cell.tune_mc_rollouts,
        gamma=task.gamma,
        step=task.step,
    ).mean
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
    states, actions = sample_evaluation_pairs(
        cell.eval_pairs,
        task.policy,
        _rng(cell.root_seed, cell.task, cell.seed, STREAM["eval_pairs"]),
        n_rollouts=cell.eval_rollouts,
        steps=task.rollout_steps,
        start=task.sample_starts,
        step=task.step,
    )
    mc = mc_q_values(
        states,
        actions,
        task.policy,
        _rng(cell.root_seed, cell.task, cell.seed, STREAM["monte_carlo"]),
        n_rollouts=cell.mc_rollouts,
        gamma=task.gamma,
        step=task.step,
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
    truth_dir: str
    truth: dict[str, Any]


def budget_cell(cell: BudgetCell) -> dict[str, Any]:
    """Fit and score one learner (:func:`geoq.experiments.fig3.score_learner`)."""
    task = suite_task(cell.task)
    truth = load_truth(cell.truth_dir, cell.truth)
    internal = np.asarray(truth["states"], dtype=np.float64)
    states = task.observed(internal)
    actions = np.asarray(truth["actions"], dtype=np.float64)
    config = QGPConfig.from_dict(cell.learner).replace(kernel=cell.kernel, max_bv=cell.max_bv)
    rollouts = observe_rollouts(
        task,
        _rollouts(
            task, task.train_rollouts, _rng(cell.root_seed, cell.task, cell.seed, STREAM["train"])
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
        _rng(cell.root_seed, cell.task, 4),
        n_rollouts=cell.mc_rollouts,
        gamma=task.gamma,
        step=task.step,
    )
    rollouts = observe_rollouts(
        task,
        _rollouts(task, task.train_rollouts, _rng(cell.root_seed, cell.task, 0, STREAM["train"])),
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


# --------------------------------------------------------------------------- driver
def run_suite(
    out: str | Path,
    tasks: Sequence[str] | None = None,
    scale: str = "quick",
    *,
    jobs: int = 1,
    backend: str = "loky",
    scheduler: str | None = None,
    root_seed: int | None = None,
    progress: bool = True,
    config: SuiteConfig | None = None,
) -> Path:
    """Run the suite into ``out`` (created; reused to resume); return the path of SUITE.md.

    ``tasks`` default to every suite task; an unknown one raises ``ValueError`` before
    anything runs.
    """
    started = time.perf_counter()
    task_ids = list(tasks) if tasks else list(SUITE_TASK_IDS)
    for t in task_ids:
        suite_task(t)  # ValueError naming the problem, before any work
    if len(set(task_ids)) != len(task_ids):
        raise ValueError(f"tasks must be distinct, got {task_ids}")
    cfg = config if config is not None else suite_config(scale, root_seed)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cells_dir = out / "cells"
    sweep: dict[str, Any] = {
        "jobs": jobs,
        "backend": backend,
        "scheduler": scheduler,
        "progress": progress,
    }
    learner = cfg.learner.as_dict()

    def tune(kernel: str, task_id: str, shared: dict[str, Any] | None) -> TuneCell:
        return TuneCell(
            task_id,
            kernel,
            cfg.root_seed,
            cfg.tune_pairs,
            cfg.tune_mc_rollouts,
            cfg.tune_max_bv,
            cfg.eval_rollouts,
            cfg.graph_eps,
            learner,
            shared,
        )

    evidence_rows = run_sweep(
        [tune("euclidean", t, None) for t in task_ids],
        tune_cell,
        cells_dir / "tune",
        desc="suite evidence",
        **sweep,
    )
    evidence = dict(zip(task_ids, evidence_rows, strict=True))
    graph_kernels = [k for k in cfg.kernels if k != "euclidean"]
    tune_cells = [tune(k, t, evidence[t]["config"]) for t in task_ids for k in graph_kernels]
    tune_rows = run_sweep(
        tune_cells, tune_cell, cells_dir / "tune", desc="suite validation", **sweep
    )
    tuned: dict[str, dict[str, dict[str, Any]]] = {
        t: {"euclidean": evidence[t]["config"]} for t in task_ids
    }
    validation: dict[str, list[dict[str, Any]]] = {t: [] for t in task_ids}
    for c, row in zip(tune_cells, tune_rows, strict=True):
        tuned[c.task][c.kernel] = row["config"]
        validation[c.task].extend(row["validation"])

    truth_dir = (cells_dir / "truth").resolve()
    truths = [
        TruthCell(t, s, cfg.root_seed, cfg.eval_pairs, cfg.eval_rollouts, cfg.mc_rollouts)
        for t in task_ids
        for s in range(cfg.seeds)
    ]
    truth_rows = run_sweep(truths, truth_cell, truth_dir, desc="suite ground truth", **sweep)
    budget_cells = [
        BudgetCell(
            tc.task,
            k,
            int(b),
            tc.seed,
            cfg.root_seed,
            tuned[tc.task][k],
            str(truth_dir),
            cell_spec(tc),
        )
        for tc in truths
        for k in cfg.kernels
        for b in cfg.budgets
    ]
    rows = run_sweep(budget_cells, budget_cell, cells_dir / "fig3", desc="suite cells", **sweep)
    rows.sort(
        key=lambda r: (
            task_ids.index(r["task"]),
            KERNEL_NAMES.index(r["kernel"]),
            int(r["max_bv"]),
            int(r["seed"]),
        )
    )

    map_tasks = [t for t in task_ids if suite_task(t).map_box is not None]
    map_cells = [
        MapCell(
            t,
            cfg.root_seed,
            cfg.map_grid,
            cfg.map_mc_rollouts,
            {k: {**tuned[t][k], "max_bv": cfg.map_max_bv} for k in cfg.kernels},
        )
        for t in map_tasks
    ]
    map_rows = run_sweep(map_cells, map_cell, cells_dir / "maps", desc="suite maps", **sweep)
    maps = dict(zip(map_tasks, map_rows, strict=True))

    from geoq.experiments.reproduce import save_figure, write_csv

    for t in task_ids:
        d = out / task_slug(t)
        d.mkdir(exist_ok=True)
        task_rows = [r for r in rows if r["task"] == t]
        write_csv(d / "fig3.csv", task_rows, SUITE_COLUMNS)
        write_csv(d / "tuning.csv", validation[t], TUNING_COLUMNS)
        save_figure(plot_budget_curves(task_rows, reference="mc"), d / "fig3.png")
        save_figure(plot_budget_curves(task_rows, posterior="refit"), d / "fig3_refit.png")
        if t in maps:
            m = maps[t]
            map_rows_csv = [
                {"map": name, "x": x, "y": y, "value": values[i * len(m["y"]) + j]}
                for name, values in m["maps"].items()
                for i, x in enumerate(m["x"])
                for j, y in enumerate(m["y"])
            ]
            write_csv(d / "value_map.csv", map_rows_csv, ("map", "x", "y", "value"))
            save_figure(plot_task_value_map(t, suite_task(t).state_names, m), d / "value_map.png")
    write_csv(out / "suite.csv", rows, SUITE_COLUMNS)

    wall = time.perf_counter() - started
    record = {
        "geoq_version": geoq.__version__,
        "python": platform.python_version(),
        "tasks": task_ids,
        "config": cfg.as_dict(),
        "tasks_settings": {
            t: {
                "gamma": suite_task(t).gamma,
                "rollout_steps": suite_task(t).rollout_steps,
                "train_rollouts": suite_task(t).train_rollouts,
                "scaling": suite_task(t).scaling.as_dict(),
                "policy": suite_task(t).policy_doc,
            }
            for t in task_ids
        },
        "tuned": tuned,
        "evidence": {t: evidence[t]["evidence"] for t in task_ids},
        "seeds": {
            "root_seed": cfg.root_seed,
            "streams": "numpy.random.SeedSequence(root_seed, spawn_key=(2_000_000, task_no, "
            "...)), task_no the index in geoq.tasks.suite.SUITE_TASK_IDS",
        },
        "execution": {"jobs": jobs, "backend": backend, "scheduler": scheduler},
    }
    atomic_write_json(out / "config.json", record)
    notes: dict[str, list[str]] = {}
    for t in task_ids:
        task = suite_task(t)
        if task.focus is None:
            continue
        train = np.vstack(
            [
                ro.states
                for s in range(cfg.seeds)
                for ro in _rollouts(
                    task, task.train_rollouts, _rng(cfg.root_seed, t, s, STREAM["train"])
                )
            ]
        )
        evaluation = np.vstack(
            [
                np.asarray(tr["states"])
                for tc, tr in zip(truths, truth_rows, strict=True)
                if tc.task == t
            ]
        )
        notes[t] = [
            focus_note(
                task.focus_doc,
                int(task.focus(evaluation).sum()),
                len(evaluation),
                int(task.focus(train).sum()),
                len(train),
            )
        ]
    report = render_suite_report(
        task_ids=task_ids,
        config=cfg.as_dict(),
        rows=rows,
        tuned=tuned,
        evidence={t: evidence[t]["evidence"] for t in task_ids},
        maps=maps,
        wall_seconds=wall,
        version=geoq.__version__,
        notes=notes,
    )
    return atomic_write_text(out / "SUITE.md", report)
