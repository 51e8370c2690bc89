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
  most 500 training pairs (:func:`geoq.experiments.paper.tuning.evidence_config`);
  the prior variance and noise are then shared by every kernel. Graph kernels
  (``nearest``, ``interpolated``, ``resistance``): their own parameters by
  held-out validation MSE against Monte-Carlo ``Q^pi``, after a refit
  (:func:`geoq.experiments.paper.tuning.select_by_validation`; the same grids as
  ``geoq reproduce``). Tuning data come from the task's own streams, disjoint
  from every seed's.
* **One cell's protocol** is :func:`geoq.experiments.paper.fig3.score_learner`, the
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
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import geoq
from geoq._io import atomic_write_json, atomic_write_text
from geoq.experiments.outputs import save_figure, write_csv
from geoq.experiments.paper.fig3 import FIG3_COLUMNS
from geoq.experiments.paper.plotting import plot_budget_curves
from geoq.experiments.paper.seeding import STREAM
from geoq.experiments.paper.tuning import TUNING_COLUMNS
from geoq.experiments.suite.cells import (
    BudgetCell,
    MapCell,
    TruthCell,
    TuneCell,
    budget_cell,
    map_cell,
    task_rng,
    task_rollouts,
    truth_cell,
    tune_cell,
)
from geoq.experiments.suite.report import (
    focus_note,
    plot_task_value_map,
    render_suite_report,
)
from geoq.experiments.sweep import cell_spec, run_sweep
from geoq.learners import KERNEL_NAMES, QGPConfig
from geoq.tasks.suite import SUITE_TASK_IDS, suite_task

__all__ = [
    "SUITE_COLUMNS",
    "SUITE_SCALES",
    "SuiteConfig",
    "run_suite",
    "suite_config",
    "task_slug",
]


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
                for ro in task_rollouts(
                    task, task.train_rollouts, task_rng(cfg.root_seed, t, s, STREAM["train"])
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
