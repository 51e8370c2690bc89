"""``geoq reproduce`` and ``geoq suite``: the paper's figures and the task suite (sweeps)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from geoq.cli._common import (
    Backend,
    BackendOption,
    JobsOption,
    Scale,
    SchedulerOption,
    SuiteScale,
    capped_jobs,
    check_out,
    check_scheduler,
    one_line,
    reported,
)

__all__ = ["reproduce", "suite"]


def reproduce(
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            help=(
                "Output directory (created if missing). Receives each figure as PNG, its data as "
                "tidy CSV (fig3.csv: kernel, max_bv, seed, mse, normalized_variance, n_bv, ...), "
                "config.json and REPORT.md. Finished sweep cells are stored under it, so rerunning "
                "with the same --out resumes an interrupted run and skips finished cells."
            ),
            file_okay=False,
            dir_okay=True,
            resolve_path=False,
        ),
    ],
    scale: Annotated[
        Scale,
        typer.Option(
            "--scale",
            help=(
                "quick: the paper's learners on a small protocol, well under a minute on 2 "
                "cores (make demo). "
                "paper: the full protocol of the paper (>= 10 seeds, ~10 basis budgets "
                "between 5 and 200); about 10 minutes with --jobs 2 on a 2-core machine."
            ),
            case_sensitive=False,
        ),
    ] = Scale.quick,
    jobs: Annotated[
        int,
        typer.Option(
            "--jobs",
            "-j",
            min=1,
            help=(
                "Worker processes for the sweeps (>= 1). With the loky backend: local joblib "
                "workers, each limited to one BLAS/OpenMP/numba thread, so use at most the number "
                "of cores. With --backend dask and no --scheduler: the number of workers of the "
                "local Dask cluster (1 = one per core). Ignored with --scheduler."
            ),
        ),
    ] = 1,
    backend: Annotated[
        Backend,
        typer.Option(
            "--backend",
            help=(
                "loky: run the sweep cells in local joblib/loky processes. "
                "dask: run them on a Dask distributed cluster (the one at --scheduler, or a local "
                "one started for the run); needs 'pip install geoq[dask]'. Results are identical "
                "whichever backend and number of jobs."
            ),
            case_sensitive=False,
        ),
    ] = Backend.loky,
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler",
            metavar="ADDRESS",
            help=(
                "Address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 (only with "
                "--backend dask). Its workers need geoq installed; set NUMBA_NUM_THREADS=1 in "
                "their environment."
            ),
        ),
    ] = None,
    seed: Annotated[
        int | None,
        typer.Option(
            "--seed",
            metavar="ROOT_SEED",
            min=0,
            help=(
                "Root seed: every random stream of the run is spawned from "
                "numpy.random.SeedSequence(ROOT_SEED), so the same seed gives identical CSVs. "
                "Default: the preset's root seed (recorded in config.json)."
            ),
        ),
    ] = None,
    progress: Annotated[
        bool,
        typer.Option(
            "--progress/--no-progress",
            help="Show progress bars over sweep cells on stderr.",
        ),
    ] = True,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config",
            metavar="FILE",
            exists=True,
            dir_okay=False,
            help=(
                "JSON object of settings that override the --scale preset, e.g. "
                '{"seeds": 2, "budgets": [5, 10], "learner": {"tol": 1e-4}} (field names as in '
                "config.json). The full configuration used is recorded in config.json."
            ),
        ),
    ] = None,
) -> None:
    """Reproduce every figure of the paper (Fig. 1-3), their data and a REPORT.md into --out."""
    check_scheduler(scheduler, backend)
    check_out(out)
    jobs = capped_jobs(jobs, scheduler)

    kwargs: dict[str, Any] = {
        "out": out,
        "scale": scale.value,
        "jobs": jobs,
        "backend": backend.value,
        "scheduler": scheduler,
        "progress": progress,
    }
    if seed is not None:
        kwargs["root_seed"] = seed
    if config is not None:
        import json

        from geoq.experiments.paper.config import config_for_scale, config_with_overrides

        try:
            overrides = json.loads(config.read_text())
            kwargs["config"] = config_with_overrides(config_for_scale(scale.value, seed), overrides)
        except (ValueError, TypeError, OSError, RecursionError) as exc:
            # JSONDecodeError and UnicodeDecodeError are ValueErrors; every field is checked
            # here (types, ranges, unknown keys at every level), before anything runs.
            raise typer.BadParameter(one_line(exc), param_hint="'--config'") from exc
    with reported("reproduce", "finished cells are kept, rerun the same command to resume"):
        from geoq.experiments.paper.reproduce import reproduce as run_reproduce

        run_reproduce(**kwargs)
    typer.echo(f"geoq reproduce: done; results in {out}")


def suite(
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            help=(
                "Output directory (created if missing): SUITE.md, suite.csv, config.json and, "
                "per task, fig3.csv, fig3.png, fig3_refit.png, tuning.csv and value_map.csv/png "
                "(2-D states). Finished cells are kept under it: rerun to resume."
            ),
            file_okay=False,
        ),
    ],
    tasks: Annotated[
        list[str] | None,
        typer.Option(
            "--tasks",
            "--task",
            help=(
                "Task id (repeat the option; default: all of geoq/PendulumSwingUp-v0, "
                "geoq/TwoRooms-v0, MountainCarContinuous-v0, Pendulum-v1)."
            ),
        ),
    ] = None,
    scale: Annotated[
        SuiteScale,
        typer.Option(
            "--scale",
            case_sensitive=False,
            help="quick: 3 seeds, 4 budgets (minutes on 2 cores). full: 10 seeds, 8 budgets.",
        ),
    ] = SuiteScale.quick,
    jobs: JobsOption = 1,
    backend: BackendOption = Backend.loky,
    scheduler: SchedulerOption = None,
    seed: Annotated[
        int | None, typer.Option("--seed", metavar="ROOT_SEED", min=0, help="Root seed.")
    ] = None,
    progress: Annotated[bool, typer.Option("--progress/--no-progress")] = True,
) -> None:
    """Policy evaluation on the task suite: the Fig. 3 protocol per task, SUITE.md (resumable)."""
    check_scheduler(scheduler, backend)
    check_out(out)
    from geoq.tasks.suite import suite_task

    for task in tasks or []:
        try:
            suite_task(task)
        except ValueError as exc:
            raise typer.BadParameter(one_line(exc), param_hint="'--tasks'") from exc
    jobs = capped_jobs(jobs, scheduler)
    with reported("suite", "finished cells are kept; rerun to resume"):
        from geoq.experiments.suite.run import run_suite

        path = run_suite(
            out, tasks or None, scale.value, jobs=jobs, backend=backend.value,
            scheduler=scheduler, root_seed=seed, progress=progress,
        )  # fmt: skip
    typer.echo(f"geoq suite: done; {path}")
