"""What the ``geoq`` commands share: the typer app, option choices, error reporting.

Every command module registers its commands on :data:`app`; :mod:`geoq.cli`
imports them all. Heavy imports (numpy, the experiments) happen inside the
commands, so that ``geoq --help`` stays fast.
"""

from __future__ import annotations

import enum
import signal
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer

__all__ = [
    "CONFIG_OPTION",
    "Backend",
    "KernelChoice",
    "Scale",
    "SuiteScale",
    "agent_config",
    "app",
    "capped_jobs",
    "check_choices",
    "check_out",
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


def check_out(out: Path) -> None:
    """Usage errors for an output directory that is empty (the current one) or a file."""
    if str(out).strip() in ("", "."):
        raise typer.BadParameter(
            "give an output directory (an empty --out would write into the current one)",
            param_hint="'--out'",
        )
    if out.exists() and not out.is_dir():
        raise typer.BadParameter(f"{out} exists and is not a directory", param_hint="'--out'")


def check_video_path(path: Path) -> None:
    """Usage errors for a video path that is not a ``.gif`` file in an existing directory."""
    if path.suffix.lower() != ".gif":
        raise typer.BadParameter(
            f"{path} does not end in .gif (videos are animated GIFs)", param_hint="'--video'"
        )
    if path.is_dir():
        raise typer.BadParameter(f"{path} is a directory", param_hint="'--video'")
    if not path.parent.is_dir():
        raise typer.BadParameter(
            f"the directory {path.parent} does not exist; create it first",
            param_hint="'--video'",
        )


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
    try:
        yield
    except KeyboardInterrupt as exc:
        typer.echo(f"geoq {command}: interrupted; {on_interrupt}", err=True)
        raise typer.Exit(143 if isinstance(exc, _Terminated) else 130) from None
    except Exception as exc:
        typer.echo(f"geoq {command}: error: {one_line(exc)}", err=True)
        raise typer.Exit(1) from exc
    finally:
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
        GPQConfig.from_dict(data)  # validates names, types and ranges
    except (ValueError, TypeError) as exc:
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


def check_choices(values: list[str] | None, allowed: Sequence[str], option: str) -> None:
    """A usage error (exit 2) for the first of ``values`` that is not in ``allowed``."""
    for value in values or []:
        if value not in allowed:
            raise typer.BadParameter(
                f"{value!r} is not one of {tuple(allowed)}", param_hint=f"'{option}'"
            )
