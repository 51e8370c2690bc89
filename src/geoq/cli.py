"""The ``geoq`` command line: a thin typer layer over library calls.

Commands
--------
``geoq reproduce --out DIR --scale quick|paper [--jobs N] [--backend loky|dask]
[--scheduler ADDRESS] [--seed ROOT_SEED] [--config FILE] [--no-progress]``
    Reproduce every figure of the paper into ``DIR`` by calling
    :func:`geoq.experiments.reproduce.reproduce`; everything it does can be
    done from Python with that function.
``geoq train --env ID --kernel K --timesteps N --seed S --out DIR``
    Learn control with a :class:`geoq.agents.GPQAgent`
    (:func:`geoq.experiments.control.train`).
``geoq evaluate DIR/agent.npz --episodes N``
    Deterministic evaluation episodes of a saved agent: mean return with its
    95% interval and the success rate.
``geoq bench-control --out DIR [--kernel K ...] [--seeds N] [--timesteps N] ...``
    Kernels x seeds through the resumable sweep runner: CONTROL.md, control.csv
    and learning curves (:func:`geoq.experiments.control.run_control_benchmark`).
``geoq suite --out DIR [--tasks ID ...] [--scale quick|full] [--jobs N] ...``
    Policy evaluation on the task suite (:func:`geoq.experiments.suite.run_suite`):
    the Fig. 3 protocol per task and a SUITE.md; resumable.
``geoq version``
    Print the package version (also ``geoq --version``).
``geoq info``
    Print the registered Gymnasium environments and the kernels.

Exit codes: 0 success; 2 usage error (bad option value or combination, from
typer/click); 1 failure while running, reported as one line on stderr;
130 interrupted (finished sweep cells are kept: rerun the same command to
resume).

Heavy imports (numpy, the experiments) happen inside the commands, so that
``geoq --help`` stays fast.
"""

from __future__ import annotations

import enum
import signal
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer

__all__ = ["Backend", "KernelChoice", "Scale", "SuiteScale", "app", "main"]


class Scale(enum.StrEnum):
    """Size of a reproduction run."""

    quick = "quick"
    paper = "paper"


class Backend(enum.StrEnum):
    """Where sweep cells run."""

    loky = "loky"
    dask = "dask"


class KernelChoice(enum.StrEnum):
    """Kernel of a GP Q-function agent."""

    euclidean = "euclidean"
    nearest = "nearest"
    interpolated = "interpolated"
    resistance = "resistance"


app = typer.Typer(
    name="geoq",
    help=(
        "Action-value functions learned by sparse online Gaussian processes with geodesic "
        "(shortest-path) kernels on the MDP-induced graph (ESANN 2012), and the command that "
        "reproduces the paper's figures."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # help texts are plain text: "geoq[dask]" is not markup
)


def _version() -> str:
    from geoq import __version__

    return __version__


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"geoq {_version()}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            help="Print the package version and exit.",
            callback=_version_callback,
            is_eager=True,
        ),
    ] = False,
) -> None:
    """Action-value functions with geodesic GP kernels; run a command with --help for details."""


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or "(no message)"
    return f"{type(exc).__name__}: {text}"


@app.command()
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
                "quick: a small protocol that finishes in minutes on 2 cores (make demo). "
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
    if scheduler is not None and backend is not Backend.dask:
        raise typer.BadParameter(
            "a scheduler address needs --backend dask", param_hint="'--scheduler'"
        )
    if scheduler is not None and not scheduler.strip():
        raise typer.BadParameter("the scheduler address is empty", param_hint="'--scheduler'")
    _check_out(out)
    jobs = _capped_jobs(jobs, scheduler)

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

        from geoq.experiments.config import config_for_scale, config_with_overrides

        try:
            overrides = json.loads(config.read_text())
            kwargs["config"] = config_with_overrides(config_for_scale(scale.value, seed), overrides)
        except (ValueError, TypeError, OSError, RecursionError) as exc:
            # JSONDecodeError and UnicodeDecodeError are ValueErrors; every field is checked
            # here (types, ranges, unknown keys at every level), before anything runs.
            raise typer.BadParameter(_one_line(exc), param_hint="'--config'") from exc
    with _reported("reproduce", "finished cells are kept, rerun the same command to resume"):
        from geoq.experiments.reproduce import reproduce as run_reproduce

        run_reproduce(**kwargs)
    typer.echo(f"geoq reproduce: done; results in {out}")


def _check_out(out: Path) -> None:
    """Usage errors for an output directory that is empty (the current one) or a file."""
    if str(out).strip() in ("", "."):
        raise typer.BadParameter(
            "give an output directory (an empty --out would write into the current one)",
            param_hint="'--out'",
        )
    if out.exists() and not out.is_dir():
        raise typer.BadParameter(f"{out} exists and is not a directory", param_hint="'--out'")


def _capped_jobs(jobs: int, scheduler: str | None) -> int:
    """``--jobs`` capped at the core count (one warning line on stderr), unless remote."""
    if scheduler is not None:
        return jobs
    from geoq.experiments.sweep import cap_jobs

    capped, message = cap_jobs(jobs)
    if message is not None:
        typer.echo(f"geoq: warning: --{message}", err=True)
    return capped


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Ctrl-C's KeyboardInterrupt would be."""


def _raise_terminated(signum: int, frame: object) -> None:
    raise _Terminated


@contextmanager
def _reported(command: str, on_interrupt: str) -> Iterator[None]:
    """Exit 130 with ``on_interrupt`` on Ctrl-C, exit 1 with one line on any other failure.

    SIGTERM (``kill``, a batch scheduler's time limit) is handled like Ctrl-C, exit 143:
    its default action would end this process at once and leave the parallel workers
    computing cells that nobody writes (measured: a ``bench-control -j 2`` killed so left
    both loky workers running to the end of their cells, then idle).
    """
    previous = None
    if signal.getsignal(signal.SIGTERM) is not signal.SIG_IGN:  # ignored: the caller's choice
        try:
            previous = signal.signal(signal.SIGTERM, _raise_terminated)
        except ValueError:  # not the main thread: leave SIGTERM alone
            previous = None
    try:
        yield
    except KeyboardInterrupt as exc:
        typer.echo(f"geoq {command}: interrupted; {on_interrupt}", err=True)
        raise typer.Exit(143 if isinstance(exc, _Terminated) else 130) from None
    except Exception as exc:
        typer.echo(f"geoq {command}: error: {_one_line(exc)}", err=True)
        raise typer.Exit(1) from exc
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _agent_config(config: Path | None) -> dict[str, Any]:
    """GPQConfig overrides from a JSON file, checked up front (usage error if bad)."""
    if config is None:
        return {}
    import json

    from geoq.agents import GPQConfig

    try:
        data = json.loads(config.read_text())
        if not isinstance(data, dict):
            raise ValueError("the config must be a JSON object of GPQConfig fields")
        if "kernel" in data:
            raise ValueError("set the kernel with --kernel, not in the config")
        GPQConfig.from_dict(data)  # validates names, types and ranges
    except (ValueError, TypeError) as exc:
        raise typer.BadParameter(_one_line(exc), param_hint="'--config'") from exc
    return data


_CONFIG_OPTION = typer.Option(
    "--config",
    metavar="FILE",
    exists=True,
    dir_okay=False,
    help=(
        'JSON object of agent settings (GPQConfig fields), e.g. {"exploration": "thompson", '
        '"max_bv": 300}. Recorded in config.json.'
    ),
)


@app.command()
def train(
    env: Annotated[str, typer.Option("--env", help="Gymnasium id of the task.")] = (
        "geoq/PendulumSwingUp-v0"
    ),
    kernel: Annotated[
        KernelChoice, typer.Option("--kernel", help="Kernel of the GP Q-function.")
    ] = KernelChoice.euclidean,
    timesteps: Annotated[
        int, typer.Option("--timesteps", min=1, help="Environment steps to learn for.")
    ] = 2_000,
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of every random choice.")] = 0,
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            file_okay=False,
            help="Output directory: learning_curve.csv/.png, agent.npz, config.json.",
        ),
    ] = Path("results/train"),
    config: Annotated[Path | None, _CONFIG_OPTION] = None,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Show a progress bar on stderr.")
    ] = True,
) -> None:
    """Learn to control a task online with a GP Q-function agent (GPQAgent)."""
    _check_out(out)
    overrides = _agent_config(config)
    with _reported("train", "nothing was written"):
        from geoq.experiments.control import train as run_train

        agent = run_train(
            env, out, kernel=kernel.value, timesteps=timesteps, seed=seed, progress=progress,
            **overrides,
        )  # fmt: skip
    last = agent.episodes[-1] if agent.episodes else None
    tail = f"; last episode return {last.ret:.1f}" if last else ""
    typer.echo(f"geoq train: {agent.num_timesteps} steps, {len(agent.episodes)} episodes{tail}; "
               f"results in {out}")  # fmt: skip


@app.command()
def evaluate(
    agent_path: Annotated[
        Path,
        typer.Argument(metavar="AGENT", exists=True, dir_okay=False, help="A saved agent.npz."),
    ],
    episodes: Annotated[
        int, typer.Option("--episodes", min=1, help="Number of evaluation episodes.")
    ] = 20,
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of the episodes' resets.")] = 0,
    env: Annotated[
        str | None, typer.Option("--env", help="Gymnasium id (default: the agent's own).")
    ] = None,
) -> None:
    """Evaluate a saved agent: mean return with its 95% interval, and the success rate."""
    with _reported("evaluate", "nothing was written"):
        from geoq.agents import GPQAgent
        from geoq.experiments.control import evaluate_agent

        agent = GPQAgent.load(agent_path, env=env)
        result = evaluate_agent(agent, env, episodes, seed)
    typer.echo(result.summary())


def _check_choices(values: list[str] | None, allowed: Sequence[str], option: str) -> None:
    """A usage error (exit 2) for the first of ``values`` that is not in ``allowed``."""
    for value in values or []:
        if value not in allowed:
            raise typer.BadParameter(
                f"{value!r} is not one of {tuple(allowed)}", param_hint=f"'{option}'"
            )


@app.command("bench-control")
def bench_control(
    out: Annotated[Path, typer.Option("--out", file_okay=False, help="Output directory.")] = Path(
        "results/control"
    ),
    env: Annotated[str, typer.Option("--env", help="Gymnasium id of the task.")] = (
        "geoq/PendulumSwingUp-v0"
    ),
    kernels: Annotated[
        list[KernelChoice] | None,
        typer.Option("--kernel", help="Kernel(s) to compare (repeat the option)."),
    ] = None,
    explorations: Annotated[
        list[str] | None,
        typer.Option(
            "--exploration",
            help="Exploration mode(s) to compare: ucb, thompson, gaussian (repeat the option).",
        ),
    ] = None,
    replays: Annotated[
        list[str] | None,
        typer.Option(
            "--replay",
            help="Replay mode(s) to compare: none, uniform, graph (repeat the option).",
        ),
    ] = None,
    baselines: Annotated[
        list[str] | None,
        typer.Option(
            "--baseline",
            help=(
                "Also run a baseline with its default settings, same seeds, budgets and "
                "evaluation: sac (Stable-Baselines3; needs pip install 'geoq[baselines]', "
                "which pulls torch)."
            ),
        ),
    ] = None,
    seeds: Annotated[int, typer.Option("--seeds", min=1, help="Seeds per setting.")] = 10,
    timesteps: Annotated[int, typer.Option("--timesteps", min=1, help="Steps per run.")] = 3_000,
    eval_every: Annotated[
        int, typer.Option("--eval-every", min=1, help="Steps between evaluations.")
    ] = 250,
    eval_episodes: Annotated[
        int, typer.Option("--eval-episodes", min=1, help="Episodes per evaluation.")
    ] = 20,
    jobs: Annotated[int, typer.Option("--jobs", "-j", min=1, help="Worker processes.")] = 1,
    backend: Annotated[
        Backend, typer.Option("--backend", case_sensitive=False, help="loky or dask.")
    ] = Backend.loky,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", metavar="ADDRESS", help="Dask scheduler.")
    ] = None,
    config: Annotated[Path | None, _CONFIG_OPTION] = None,
    progress: Annotated[bool, typer.Option("--progress/--no-progress")] = True,
) -> None:
    """Benchmark the agent: steps to success, kernels x exploration x replay x seeds (resumable)."""
    from geoq.agents.acquisition import EXPLORATION_MODES
    from geoq.agents.config import REPLAYS

    if scheduler is not None and backend is not Backend.dask:
        raise typer.BadParameter("a scheduler needs --backend dask", param_hint="'--scheduler'")
    from geoq.experiments.sac_baseline import BASELINES

    _check_choices(explorations, EXPLORATION_MODES, "--exploration")
    _check_choices(replays, REPLAYS, "--replay")
    _check_choices(baselines, BASELINES, "--baseline")
    _check_out(out)
    jobs = _capped_jobs(jobs, scheduler)
    base = _agent_config(config)
    configs = [dict(base, exploration=m) for m in explorations] if explorations else [base]
    if replays:
        configs = [dict(c, replay=r) for c in configs for r in replays]
    with _reported("bench-control", "finished cells are kept; rerun to resume"):
        from geoq.experiments.control import run_control_benchmark

        run_control_benchmark(
            out, env_id=env, kernels=[k.value for k in (kernels or [KernelChoice.euclidean])],
            seeds=seeds, timesteps=timesteps, eval_every=eval_every,
            eval_episodes=eval_episodes, configs=configs, baselines=baselines or [],
            jobs=jobs, backend=backend.value, scheduler=scheduler, progress=progress,
        )  # fmt: skip
    typer.echo(f"geoq bench-control: done; {out / 'CONTROL.md'}")


@app.command()
def version() -> None:
    """Print the package version."""
    typer.echo(_version())


@app.command()
def info() -> None:
    """Print the registered Gymnasium environments and the available kernels."""
    import inspect

    import gymnasium

    import geoq
    import geoq.kernels as kernels

    typer.echo(f"geoq {geoq.__version__}")
    env_ids = sorted(k for k in gymnasium.registry if k.startswith("geoq/"))
    typer.echo("environments:")
    for env_id in env_ids or ["(none registered)"]:
        typer.echo(f"  {env_id}")
    typer.echo("kernels:")
    for name in sorted(getattr(kernels, "__all__", [])):
        obj = getattr(kernels, name, None)
        if inspect.isclass(obj) and issubclass(obj, kernels.Kernel) and not inspect.isabstract(obj):
            doc = (inspect.getdoc(obj) or "").splitlines()
            typer.echo(f"  {name}: {doc[0] if doc else ''}".rstrip(": "))


class SuiteScale(enum.StrEnum):
    """Size of a task-suite run."""

    quick = "quick"
    full = "full"


@app.command()
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
    jobs: Annotated[int, typer.Option("--jobs", "-j", min=1, help="Worker processes.")] = 1,
    backend: Annotated[
        Backend, typer.Option("--backend", case_sensitive=False, help="loky or dask.")
    ] = Backend.loky,
    scheduler: Annotated[
        str | None, typer.Option("--scheduler", metavar="ADDRESS", help="Dask scheduler.")
    ] = None,
    seed: Annotated[
        int | None, typer.Option("--seed", metavar="ROOT_SEED", min=0, help="Root seed.")
    ] = None,
    progress: Annotated[bool, typer.Option("--progress/--no-progress")] = True,
) -> None:
    """Policy evaluation on the task suite: the Fig. 3 protocol per task, SUITE.md (resumable)."""
    if scheduler is not None and backend is not Backend.dask:
        raise typer.BadParameter("a scheduler needs --backend dask", param_hint="'--scheduler'")
    if out.exists() and not out.is_dir():
        raise typer.BadParameter(f"{out} exists and is not a directory", param_hint="'--out'")
    from geoq.tasks.suite import suite_task

    for task in tasks or []:
        try:
            suite_task(task)
        except ValueError as exc:
            raise typer.BadParameter(_one_line(exc), param_hint="'--tasks'") from exc
    with _reported("suite", "finished cells are kept; rerun to resume"):
        from geoq.experiments.suite import run_suite

        path = run_suite(
            out, tasks or None, scale.value, jobs=jobs, backend=backend.value,
            scheduler=scheduler, root_seed=seed, progress=progress,
        )  # fmt: skip
    typer.echo(f"geoq suite: done; {path}")


def main() -> None:
    """Entry point of the ``geoq`` console script."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
