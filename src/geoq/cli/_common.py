"""What the ``geoq`` commands share: the typer app, option choices, error reporting.

Every command module registers its commands on :data:`app`; :mod:`geoq.cli`
imports them all. Heavy imports (numpy, the experiments) happen inside the
commands, so that ``geoq --help`` stays fast.
"""

from __future__ import annotations

import enum
import signal
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer

__all__ = [
    "CONFIG_OPTION",
    "OVERWRITE_OPTION",
    "Backend",
    "KernelChoice",
    "Scale",
    "SuiteScale",
    "agent_config",
    "app",
    "capped_jobs",
    "check_agents",
    "check_choices",
    "check_env",
    "check_out",
    "check_scheduler",
    "check_video_path",
    "one_line",
    "reported",
    "version_text",
]


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


def version_text() -> str:
    from geoq import __version__

    return __version__


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"geoq {version_text()}")
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


class SuiteScale(enum.StrEnum):
    """Size of a task-suite run."""

    quick = "quick"
    full = "full"


def one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or "(no message)"
    return f"{type(exc).__name__}: {text}"


def check_out(out: Path, run_files: Sequence[str] = (), overwrite: bool = False) -> None:
    """Usage errors for an output directory that is empty (the current one), a file, one
    that cannot be made or written (on /proc, /sys, read-only: tested with a temporary
    file), or one holding an earlier run of ``run_files`` (unless ``overwrite``):
    :func:`geoq._io.check_run_dir`, the library's own check, before any work."""
    if str(out).strip() in ("", "."):
        raise typer.BadParameter(
            "give an output directory (an empty --out would write into the current one)",
            param_hint="'--out'",
        )
    from geoq._io import check_run_dir

    try:
        check_run_dir(out, run_files, overwrite)
    except OSError as exc:
        raise typer.BadParameter(str(exc).replace("overwrite=True (--overwrite)", "--overwrite"),
                                 param_hint="'--out'") from exc  # fmt: skip


def check_scheduler(scheduler: str | None, backend: Backend) -> None:
    """Usage errors for a Dask scheduler address without ``--backend dask``, or empty."""
    if scheduler is not None and backend is not Backend.dask:
        raise typer.BadParameter(
            "a scheduler address needs --backend dask", param_hint="'--scheduler'"
        )
    if scheduler is not None and not scheduler.strip():
        raise typer.BadParameter("the scheduler address is empty", param_hint="'--scheduler'")


def check_env(env_id: str, option: str = "--env") -> None:
    """A usage error unless ``env_id`` is a registered env the agent can learn (1-D Box
    spaces, a bounded action box); ``"module:Id"`` imports ``module`` first."""
    from geoq.agents._env import agent_spaces, as_env, is_registered

    try:
        known = is_registered(env_id)
    except Exception as exc:  # the module named before the id failed on import
        raise typer.BadParameter(f"importing the module of {env_id!r} failed: {one_line(exc)}",
                                 param_hint=f"'{option}'") from exc  # fmt: skip
    if not known:
        raise typer.BadParameter(
            f"{env_id!r} is not a registered Gymnasium id (`geoq info` lists geoq's envs; "
            "an env of your own: 'module:Id', the module registering Id on import)",
            param_hint=f"'{option}'",
        )
    try:
        env = as_env(env_id)
        try:
            agent_spaces(env)
        finally:
            env.close()
    except Exception as exc:  # gymnasium.make can raise anything (missing dependencies)
        raise typer.BadParameter(one_line(exc), param_hint=f"'{option}'") from exc


def check_agents(env_id: str, kernels: Sequence[str], configs: Sequence[dict[str, Any]]) -> None:
    """Every agent a command will make, made once now: the API's own validation of the
    settings (``GPQAgent``, :class:`~geoq.agents.GPQConfig`) is the CLI's (usage error)."""
    check_env(env_id)
    from geoq.agents import GPQAgent

    for kernel in kernels:
        for overrides in configs:
            try:
                GPQAgent(env_id, kernel=kernel, seed=0, **overrides)  # type: ignore[arg-type]
            except (ValueError, TypeError, RecursionError) as exc:
                raise typer.BadParameter(one_line(exc), param_hint="'--config'") from exc


def check_video_path(path: Path) -> None:
    """Usage errors for a video path that is not a ``.gif`` file, or cannot be written: not a
    regular file or a new one, or not in an existing directory where files can be made
    (:func:`geoq._io.check_output_file`, tested with a temporary file there)."""
    if path.suffix.lower() != ".gif":
        raise typer.BadParameter(
            f"{path} does not end in .gif (videos are animated GIFs)", param_hint="'--video'"
        )
    from geoq._io import check_output_file

    try:
        check_output_file(path, create=False)
    except OSError as exc:
        raise typer.BadParameter(str(exc), param_hint="'--video'") from exc


def capped_jobs(jobs: int, scheduler: str | None) -> int:
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
def reported(command: str, on_interrupt: str) -> Iterator[None]:
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

    def show(message: Any, category: Any, *args: Any, **kwargs: Any) -> None:
        text = " ".join(str(message).split())
        typer.echo(f"geoq {command}: warning: {category.__name__}: {text}", err=True)

    shown, warnings.showwarning = warnings.showwarning, show  # one line, as the CLI's own
    try:
        yield
    except KeyboardInterrupt as exc:
        typer.echo(f"geoq {command}: interrupted; {on_interrupt}", err=True)
        raise typer.Exit(143 if isinstance(exc, _Terminated) else 130) from None
    except Exception as exc:
        typer.echo(f"geoq {command}: error: {one_line(exc)}", err=True)
        raise typer.Exit(1) from exc
    finally:
        warnings.showwarning = shown
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def agent_config(config: Path | None) -> dict[str, Any]:
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
        GPQConfig.from_dict(data)  # names, types and ranges; check_agents does the rest
    except RecursionError:
        raise typer.BadParameter(
            "the JSON is nested too deeply; give a flat object of GPQConfig fields",
            param_hint="'--config'",
        ) from None
    except (ValueError, TypeError, OSError) as exc:  # JSON and UTF-8 errors are ValueErrors
        raise typer.BadParameter(one_line(exc), param_hint="'--config'") from exc
    return data


CONFIG_OPTION = typer.Option(
    "--config",
    metavar="FILE",
    exists=True,
    dir_okay=False,
    help=(
        'JSON object of agent settings (GPQConfig fields), e.g. {"exploration": "thompson", '
        '"max_bv": 300}. Recorded in config.json.'
    ),
)


#: The sweep options of ``bench-control`` and ``suite`` (``reproduce`` words its help for
#: the paper's protocol).
JobsOption = Annotated[int, typer.Option("--jobs", "-j", min=1, help="Worker processes.")]
BackendOption = Annotated[
    Backend, typer.Option("--backend", case_sensitive=False, help="loky or dask.")
]
SchedulerOption = Annotated[
    str | None, typer.Option("--scheduler", metavar="ADDRESS", help="Dask scheduler.")
]
#: ``--baseline`` of ``bench-control`` and ``control-suite``.
BaselinesOption = Annotated[
    list[str] | None,
    typer.Option(
        "--baseline",
        help=(
            "Also run a baseline with its default settings, same seeds, budgets and "
            "evaluation: sac (Stable-Baselines3; needs pip install 'geoq[baselines]', "
            "which pulls torch)."
        ),
    ),
]
#: ``--overwrite`` of the benchmarks, whose finished cells outlive their report.
BENCHMARK_OVERWRITE_OPTION = typer.Option(
    "--overwrite",
    help="Replace the report of a benchmark of other settings in --out (finished "
    "cells are kept; refused without it).",
)


OVERWRITE_OPTION = typer.Option(
    "--overwrite", help="Replace an earlier run in --out (refused without it)."
)


def check_choices(values: list[str] | None, allowed: Sequence[str], option: str) -> None:
    """A usage error (exit 2) for the first of ``values`` that is not in ``allowed``."""
    for value in values or []:
        if value not in allowed:
            raise typer.BadParameter(
                f"{value!r} is not one of {tuple(allowed)}", param_hint=f"'{option}'"
            )
