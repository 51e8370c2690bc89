"""The ``geoq`` command line: a thin typer layer over library calls.

Commands
--------
``geoq reproduce --out DIR --scale quick|paper [--jobs N] [--backend loky|dask]
[--scheduler ADDRESS] [--seed ROOT_SEED] [--config FILE] [--no-progress]``
    Reproduce every figure of the paper into ``DIR`` by calling
    :func:`geoq.experiments.paper.reproduce.reproduce`; everything it does can be
    done from Python with that function.
``geoq train --env ID --kernel K --timesteps N --seed S --out DIR [--eval-every N]``
    Learn control with a :class:`geoq.agents.GPQAgent`, with periodic greedy
    evaluations (:func:`geoq.experiments.control.training.train`).
``geoq evaluate DIR/agent.npz --episodes N [--video FILE.gif]``
    Deterministic evaluation episodes of a saved agent: mean return with its
    95% interval and the success rate; ``--video`` films the first one
    (:mod:`geoq.experiments.control.video`).
``geoq bench-control --out DIR [--kernel K ...] [--seeds N] [--timesteps N] ...``
    Kernels x seeds through the resumable sweep runner: CONTROL.md, control.csv
    and learning curves (:func:`geoq.experiments.control.benchmark.run_control_benchmark`).
``geoq suite --out DIR [--tasks ID ...] [--scale quick|full] [--jobs N] ...``
    Policy evaluation on the task suite (:func:`geoq.experiments.suite.run.run_suite`):
    the Fig. 3 protocol per task and a SUITE.md; resumable.
``geoq version``
    Print the package version (also ``geoq --version``).
``geoq info``
    Print the registered Gymnasium environments and the kernels.

Exit codes: 0 success; 2 usage error (a bad option value or combination, an
``--env`` that is not registered or that the agent cannot learn, a ``--config``
whose settings the agent refuses, an ``--out`` or ``--video`` that cannot be written
(tried with a temporary file there: /proc, /sys, a read-only directory) or an ``--out``
holding an earlier run without ``--overwrite``, an ``AGENT`` file that is not a saved
agent), always before any work; 1 failure while running, reported as one line on stderr
(warnings too are one line each); 130 interrupted, 143 terminated (finished sweep
cells are kept: rerun the same command to resume).

Heavy imports (numpy, the experiments) happen inside the commands, so that
``geoq --help`` stays fast.
"""

from __future__ import annotations

from geoq.cli._about import info, version
from geoq.cli._common import Backend, KernelChoice, Scale, SuiteScale, app
from geoq.cli._control import bench_control, control_suite, evaluate, train
from geoq.cli._paper import reproduce, suite

__all__ = ["Backend", "KernelChoice", "Scale", "SuiteScale", "app", "main"]

# One module per command group; registered here, in the order ``geoq --help`` lists them.
app.command()(reproduce)
app.command()(suite)
app.command()(train)
app.command()(evaluate)
app.command("bench-control")(bench_control)
app.command("control-suite")(control_suite)
app.command()(version)
app.command()(info)


def main() -> None:
    """Entry point of the ``geoq`` console script: a failure the commands did not report
    (a bug) is still one line on stderr and exit 1, never a traceback."""
    import sys

    from geoq.cli._common import one_line

    try:
        app()
    except Exception as exc:
        print(f"geoq: internal error: {one_line(exc)}", file=sys.stderr)
        sys.exit(1)
