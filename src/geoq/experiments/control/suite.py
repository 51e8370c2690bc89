"""``geoq control-suite``: the control tasks, each under its own protocol and goal.

The suite's second part (the first is the Fig. 3 protocol of
:mod:`geoq.experiments.suite.run`). Every task runs :func:`run_control_benchmark` with
the agent's defaults (and optionally SAC beside it, same seeds, budgets and
evaluation) into ``out/<task>/``, then its goal is checked:

=============================  =======  =====  =====  ======================================
task                           seeds    steps  every  goal
=============================  =======  =====  =====  ======================================
geoq/PendulumSwingUp-v0        20       2,000  250    median steps to success <= 1,000
MountainCarContinuous-v0       10       3,000  500    median steps to success <= 500
Pendulum-v1                    10       5,000  500    >= 7 of 10 seeds reach success
geoq/TwoRooms-v0               10       2,000  250    median steps to success <= 2,000
InvertedPendulum-v5            5        5,000  500    median final return >= 950
Reacher-v5                     5        5,000  500    median final return >= -5
=============================  =======  =====  =====  ======================================

Success is :func:`~geoq.experiments.control.evaluation.evaluation_success` (a success
rate >= 0.9 of the greedy episodes, or a mean return >= the task's known
threshold); "final return" is the mean greedy return of the last checkpoint.
The first three goals keep what the agent learns today (the README's table, same
protocol and seeds); the others are issues 28 and 33's. The MuJoCo tasks need the
optional extra ``mujoco``: without it they are listed as skipped, not run.

Files: ``CONTROL_SUITE.md`` (one line per task: the measured figure with its 95%
interval, the verdict, ms per step against SAC's) and ``control_suite.json`` (the same;
``null`` for a median not reached or an interval without an end), written
atomically after every task has finished; each task's own ``CONTROL.md``,
``control.csv`` and cells under ``out/<task>/`` (finished cells are kept: rerun to
resume).
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from geoq._io import atomic_write_json, atomic_write_text, check_run_dir
from geoq.envs import PENDULUM_SWING_UP_ID, TWO_ROOMS_ID
from geoq.experiments.control.baselines import BASELINES
from geoq.experiments.control.benchmark import (
    benchmark_settings,
    check_baselines,
    check_benchmark_dir,
    median_interval,
    run_control_benchmark,
    steps_to_success,
)

__all__ = [
    "CONTROL_SUITE",
    "ControlGoal",
    "control_goal",
    "control_goals",
    "goal_verdict",
    "run_control_suite",
]

GoalKind = Literal["median_steps", "seeds_reaching", "median_return"]


@dataclass(frozen=True)
class ControlGoal:
    """One control task of the suite: its protocol and what it must reach."""

    env_id: str
    seeds: int
    timesteps: int
    eval_every: int
    eval_episodes: int
    kind: GoalKind
    """``median_steps``: the median over seeds of the first checkpoint of success is
    ``<= target`` steps; ``seeds_reaching``: at least ``target`` (a fraction) of the
    seeds reach success within the budget; ``median_return``: the median over seeds of
    the last checkpoint's mean greedy return is ``>= target``."""
    target: float
    source: str
    """Where the goal comes from."""
    extra: str | None = None
    """The optional extra the task needs (``mujoco``), None if none."""

    @property
    def slug(self) -> str:
        """The task's directory name under the suite's output."""
        return self.env_id.replace("/", "-")

    def describe(self) -> str:
        """The goal in words."""
        if self.kind == "median_steps":
            return f"median steps to success <= {self.target:,.0f}"
        if self.kind == "seeds_reaching":
            return f"success reached by >= {self.target:.0%} of the seeds"
        return f"median final return >= {self.target:g}"

    def available(self) -> bool:
        """Whether this machine can run the task (its optional extra is installed)."""
        return self.extra is None or importlib.util.find_spec(self.extra) is not None


_KEEP = "what the agent learns today (README table)"
_MUJOCO = "issue 33"
#: The control tasks, in the order they run.
CONTROL_SUITE: tuple[ControlGoal, ...] = (
    ControlGoal(PENDULUM_SWING_UP_ID, 20, 2_000, 250, 20, "median_steps", 1_000, _KEEP),
    ControlGoal("MountainCarContinuous-v0", 10, 3_000, 500, 20, "median_steps", 500, _KEEP),
    ControlGoal("Pendulum-v1", 10, 5_000, 500, 20, "seeds_reaching", 0.7, _KEEP),
    ControlGoal(TWO_ROOMS_ID, 10, 2_000, 250, 20, "median_steps", 2_000, "issue 28"),
    ControlGoal("InvertedPendulum-v5", 5, 5_000, 500, 10, "median_return", 950, _MUJOCO, "mujoco"),
    ControlGoal("Reacher-v5", 5, 5_000, 500, 10, "median_return", -5, _MUJOCO, "mujoco"),
)


def control_goal(env_id: str) -> ControlGoal:
    """The suite's goal of ``env_id``; ``ValueError`` naming the known ones otherwise."""
    for goal in CONTROL_SUITE:
        if goal.env_id == env_id:
            return goal
    known = ", ".join(g.env_id for g in CONTROL_SUITE)
    raise ValueError(f"{env_id!r} is not a task of the control suite; known: {known}")


def goal_verdict(goal: ControlGoal, rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The goal checked on a task's benchmark rows (one per seed, one agent).

    Returns the measured figure (``value``) with its 95% interval (a distribution-free
    order-statistic interval of the median; for ``seeds_reaching`` the Clopper-Pearson
    interval of the fraction), the seeds that reached success, the median ms per step
    and ``met``.
    """
    if not rows:
        raise ValueError(f"no benchmark rows for {goal.env_id}")
    steps = [steps_to_success(r) for r in rows]
    reached = sum(math.isfinite(s) for s in steps)
    n = len(rows)
    if goal.kind == "median_steps":
        value, low, high = median_interval(steps)
        met = value <= goal.target
    elif goal.kind == "seeds_reaching":
        value, low, high = reached / n, *_clopper_pearson(reached, n)
        met = value >= goal.target
    else:
        value, low, high = median_interval([float(r["eval_return"][-1]) for r in rows])
        met = value >= goal.target
    return {
        "env_id": goal.env_id, "goal": goal.describe(), "source": goal.source, "seeds": n,
        "value": value, "low": low, "high": high, "reached": reached, "met": bool(met),
        "ms_per_step": float(np.median([r["ms_per_step"] for r in rows])),
    }  # fmt: skip


def _clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    from scipy import stats

    alpha = 1.0 - level
    low = 0.0 if k == 0 else float(stats.beta.ppf(alpha / 2, k, n - k + 1))
    high = 1.0 if k == n else float(stats.beta.isf(alpha / 2, k + 1, n - k))
    return low, high


def run_control_suite(
    out: str | Path,
    tasks: Sequence[str] | None = None,
    *,
    seeds: int | None = None,
    baselines: Sequence[str] = (),
    jobs: int = 1,
    backend: str = "loky",
    scheduler: str | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Run the control suite into ``out``; returns what ``control_suite.json`` holds.

    ``tasks``: env ids of :data:`CONTROL_SUITE` (default: every one this machine can
    run; a named one that needs a missing extra is an error). ``seeds``: fewer (or more)
    seeds than the protocol's, for an indicative run (the report says so). ``baselines``
    (``["sac"]``) run beside the agent on every task.
    """
    goals = control_goals(tasks)
    if seeds is not None and (isinstance(seeds, bool) or int(seeds) != seeds or seeds < 1):
        raise ValueError(f"seeds must be an integer >= 1 or None, got {seeds!r}")
    check_baselines(baselines)
    out = Path(out)
    check_run_dir(out, (), overwrite=True)  # each task's directory guards its own report
    runs = [goal if seeds is None else replace(goal, seeds=int(seeds)) for goal in goals]
    for run in runs:  # every task's directory checked before the first cell runs
        if run.available():
            check_benchmark_dir(out / run.slug, _settings(run, baselines), overwrite)
    results: list[dict[str, Any]] = []
    for goal, run in zip(goals, runs, strict=True):
        if not goal.available():
            results.append({"env_id": goal.env_id, "goal": goal.describe(),
                            "skipped": f"needs the optional extra {goal.extra}: "
                                       f"pip install -e '.[{goal.extra}]'"})  # fmt: skip
            continue
        rows = run_control_benchmark(
            out / goal.slug, env_id=goal.env_id, kernels=["euclidean"], seeds=run.seeds,
            timesteps=goal.timesteps, eval_every=goal.eval_every,
            eval_episodes=goal.eval_episodes, baselines=baselines, jobs=jobs, backend=backend,
            scheduler=scheduler, progress=progress, overwrite=overwrite,
        )  # fmt: skip
        agent_rows = [r for r in rows if r["kernel"] not in BASELINES]
        verdict = goal_verdict(goal, agent_rows) | {"protocol_seeds": goal.seeds}
        for name in baselines:
            base = goal_verdict(goal, [r for r in rows if r["kernel"] == name])
            verdict[name] = {k: base[k] for k in ("value", "low", "high", "reached", "met",
                                                  "ms_per_step")}  # fmt: skip
        results.append(verdict)
    summary = {"tasks": results, "baselines": list(baselines)}
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out / "control_suite.json", _strict_json(summary))
    atomic_write_text(out / "CONTROL_SUITE.md", control_suite_report(results, baselines))
    return summary


def _strict_json(obj: Any) -> Any:
    """``obj`` with every non-finite float as None (JSON has no infinity): a median of
    steps that is not reached, an interval without an end."""
    if isinstance(obj, dict):
        return {k: _strict_json(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_strict_json(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _settings(goal: ControlGoal, baselines: Sequence[str]) -> dict[str, Any]:
    return benchmark_settings(goal.env_id, ["euclidean"], goal.seeds, goal.timesteps,
                              goal.eval_every, goal.eval_episodes, baselines=baselines)  # fmt: skip


def control_goals(tasks: Sequence[str] | None) -> list[ControlGoal]:
    """The goals of ``tasks`` (every one if None or empty); ``ValueError`` for an unknown
    task or one whose optional extra is missing."""
    if not tasks:
        return list(CONTROL_SUITE)
    goals = [control_goal(t) for t in dict.fromkeys(tasks)]
    for goal in goals:
        if not goal.available():
            raise ValueError(
                f"{goal.env_id} needs the optional extra {goal.extra}: "
                f"pip install -e '.[{goal.extra}]' (or make test-mujoco)"
            )
    return goals


def _figure(kind: str, value: float, low: float, high: float) -> str:
    if kind == "seeds_reaching":
        return f"{value:.0%} [{low:.0%}, {high:.0%}]"
    return f"{_short(value)} [{_short(low)}, {_short(high)}]"


def _short(value: float) -> str:
    """Four significant digits, no exponent below a million (steps: 10000, not 1e+04)."""
    return f"{float(f'{value:.4g}'):g}"


def control_suite_report(results: Sequence[Mapping[str, Any]], baselines: Sequence[str]) -> str:
    """CONTROL_SUITE.md: one line per task, its goal, the figure measured and the verdict."""
    kinds = {g.env_id: g.kind for g in CONTROL_SUITE}
    head = "| task | goal (source) | seeds | GPQAgent [95%] | reached | verdict | ms / step |"
    rule = "|---|---|---|---|---|---|---|"
    for name in baselines:
        head += f" {name} [95%] | {name} ms / step |"
        rule += "---|---|"
    lines = [
        "# Control suite",
        "",
        "Each task under its own protocol (`geoq.experiments.control.suite`; its benchmark in "
        "the task's directory): the agent's defaults, greedy evaluation episodes from the "
        "default reset at every checkpoint. Steps to success and final returns: median over "
        "seeds with a distribution-free 95% interval (unbounded, [-inf, inf], for a median "
        "of fewer than 6 seeds); a fraction of seeds: Clopper-Pearson 95% interval. "
        "ms / step: median wall time of learning per environment step.",
        "",
        head,
        rule,
    ]
    for r in results:
        if "skipped" in r:
            lines.append(f"| {r['env_id']} | {r['goal']} | - | skipped: {r['skipped']} | "
                         "| | |" + " | |" * len(baselines))  # fmt: skip
            continue
        kind = kinds[r["env_id"]]
        seeds = f"{r['seeds']}" + ("" if r["seeds"] == r["protocol_seeds"] else
                                   f" (protocol {r['protocol_seeds']}: indicative)")  # fmt: skip
        line = (
            f"| {r['env_id']} | {r['goal']} ({r['source']}) | {seeds} | "
            f"{_figure(kind, r['value'], r['low'], r['high'])} | {r['reached']}/{r['seeds']} | "
            f"{'**met**' if r['met'] else 'not met'} | {r['ms_per_step']:.1f} |"
        )
        for name in baselines:
            b = r[name]
            line += f" {_figure(kind, b['value'], b['low'], b['high'])} | {b['ms_per_step']:.1f} |"
        lines.append(line)
    lines.append("")
    return "\n".join(lines)
