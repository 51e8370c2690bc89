"""``geoq version`` and ``geoq info``: what is installed."""

from __future__ import annotations

import typer

from geoq.cli._common import version_text

__all__ = ["info", "version"]


def version() -> None:
    """Print the package version."""
    typer.echo(version_text())


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
