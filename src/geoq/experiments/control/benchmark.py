"""``geoq bench-control``: kernels (and baselines) x seeds on one task, data and report.

:func:`control_cell` is one sweep cell = one (agent settings, seed): the agent learns for
the whole budget and is evaluated at every checkpoint (``eval_every`` steps) with
``eval_episodes`` deterministic episodes
(:func:`~geoq.experiments.control.evaluation.evaluate_agent`). :func:`run_control_benchmark`
runs the cells through the resumable sweep runner (joblib locally, Dask on a cluster) and
writes ``benchmark.json``, ``control.csv``, ``learning_curves.png`` and ``CONTROL.md``.
"""

from __future__ import annotations

import importlib.util
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from geoq._io import atomic_write_json, atomic_write_text, check_run_dir, staged_run
from geoq.agents import GPQAgent
from geoq.envs import PENDULUM_SWING_UP_ID
from geoq.experiments.control.baselines import BASELINES, sac_cell
from geoq.experiments.control.evaluation import (
    ControlCell,
    Evaluation,
    evaluate_agent,
    learn_with_checkpoints,
)
from geoq.experiments.control.plotting import plot_learning_curve
from geoq.experiments.outputs import save_figure, write_csv
from geoq.experiments.stats import mean_interval
from geoq.experiments.sweep import run_sweep
from geoq.policies import default_policy
from geoq.tasks import KNOWN_TASKS

__all__ = [
    "BENCHMARK_FILES",
    "HandMadeController",
    "benchmark_settings",
    "check_baselines",
    "check_benchmark_dir",
    "control_cell",
    "control_report",
    "median_interval",
    "run_control_benchmark",
    "steps_to_success",
]

#: The report of a ``geoq bench-control`` run (its finished cells live in ``cells/``).
BENCHMARK_FILES = ("benchmark.json", "control.csv", "learning_curves.png", "CONTROL.md")


class HandMadeController:
    """The reproduction's swing-up controller (:func:`geoq.policies.default_policy`'s mean
    action) with the ``predict`` interface of an agent: the reference of control reports."""

    env_id = PENDULUM_SWING_UP_ID

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[np.ndarray, None]:
        return default_policy().mean_action(observation)[:, None], None


def check_baselines(baselines: Sequence[str]) -> None:
    """A ``ValueError`` for a baseline that is unknown or cannot run here (its package is
    missing): checked before a benchmark starts, not after its GP cells."""
    for name in baselines:
        if name not in BASELINES:
            raise ValueError(f"baseline {name!r} is not one of {BASELINES}")
        if importlib.util.find_spec("stable_baselines3") is None:
            raise ValueError(
                f"the {name} baseline needs stable-baselines3: pip install 'geoq[baselines]' "
                "(it pulls torch, several GB)"
            )


def _benchmark_settings(**settings: Any) -> dict[str, Any]:
    """The settings a benchmark report is made of, as their JSON round trip."""
    return dict(json.loads(json.dumps(settings)))


# fmt: off
def benchmark_settings(
    env_id: str, kernels: Sequence[str], seeds: int, timesteps: int, eval_every: int,
    eval_episodes: int, configs: Sequence[Mapping[str, Any]] = ({},),
    baselines: Sequence[str] = (),
) -> dict[str, Any]:
    # fmt: on
    """The settings a benchmark's report is made of (``benchmark.json``), as
    :func:`run_control_benchmark` records them: a rerun of the same settings resumes."""
    return _benchmark_settings(
        env=env_id, kernels=list(kernels), seeds=seeds, timesteps=timesteps,
        eval_every=eval_every, eval_episodes=eval_episodes, configs=[dict(c) for c in configs],
        baselines=list(baselines),
    )  # fmt: skip


def check_benchmark_dir(out: str | Path, settings: Mapping[str, Any], overwrite: bool) -> None:
    """An ``OSError`` unless ``out`` can take a benchmark of ``settings``: writable, and its
    report (``benchmark.json``) of the same settings (a rerun resumes), or none, or
    ``overwrite`` (the report is replaced; finished cells of any settings are kept)."""
    out = Path(out)
    check_run_dir(out, (), overwrite)
    manifest = out / "benchmark.json"
    if overwrite or not (manifest.exists() or (out / "CONTROL.md").exists()):
        return
    try:
        stored = json.loads(manifest.read_text())["settings"]
    except (OSError, ValueError, KeyError, TypeError):
        stored = None
    if stored != _benchmark_settings(**settings):
        differ = sorted(k for k in settings if not isinstance(stored, dict)
                        or stored.get(k) != _benchmark_settings(**settings)[k])  # fmt: skip
        raise FileExistsError(
            f"{out} holds the report of a benchmark of other settings ({', '.join(differ)}); "
            "give another directory, or pass overwrite=True (--overwrite) to replace that "
            "report (finished cells are kept)"
        )


# --------------------------------------------------------------------------- benchmark
def control_cell(cell: ControlCell) -> dict[str, Any]:
    """Learn for ``cell.timesteps`` steps, evaluating every ``cell.eval_every`` steps.

    ``cell.kernel`` may also name a baseline (``"sac"``,
    :mod:`geoq.experiments.control.baselines`), trained and evaluated the same way.

    Returns a row with the checkpoints, the evaluation's mean return and
    success rate at each, the training curve and the wall time of learning.
    """

    if cell.kernel in BASELINES:
        return sac_cell(cell)
    agent = GPQAgent(cell.env_id, kernel=cell.kernel, seed=cell.seed, **dict(cell.config))  # type: ignore[arg-type]
    row = learn_with_checkpoints(cell, agent.learn, agent)
    row["train_timesteps"] = [e.timesteps for e in agent.episodes]
    row["train_return"] = [e.ret for e in agent.episodes]
    row["n_bv"] = agent.gp.n_bv
    row["train_seconds_per_episode"] = agent.log.train_seconds / max(len(agent.episodes), 1)
    return row


def steps_to_success(row: Mapping[str, Any], threshold: float = 0.9) -> float:
    """First checkpoint whose success rate is >= ``threshold`` (inf if none)."""
    for t, s in zip(row["checkpoints"], row["eval_success"], strict=True):
        if s is not None and np.isfinite(s) and s >= threshold:
            return float(t)
    return math.inf


def median_interval(values: Sequence[float], level: float = 0.95) -> tuple[float, float, float]:
    """Median with a distribution-free (binomial order-statistic) interval."""

    v = np.sort(np.asarray(values, dtype=np.float64))
    n = v.size
    med = float(np.median(v))
    if n < 2:
        return med, -math.inf, math.inf
    lo_k = int(stats.binom.ppf((1 - level) / 2, n, 0.5))
    hi_k = int(stats.binom.isf((1 - level) / 2, n, 0.5))
    lo = float(v[lo_k - 1]) if lo_k >= 1 else -math.inf
    hi = float(v[hi_k]) if hi_k < n else math.inf
    return med, lo, hi


def control_report(
    rows: Sequence[Mapping[str, Any]],
    title: str,
    threshold: float = 0.9,
    reference: Evaluation | None = None,
    env_id: str | None = None,
) -> str:
    """CONTROL.md: steps to success and final evaluation per agent setting, over seeds.

    ``reference``: the evaluation of a known controller on the same episodes, quoted.
    """
    labels = list(dict.fromkeys(r["label"] for r in rows))
    quoted = (
        []
        if reference is None
        else [
            "Reference, the hand-made controller of the reproduction on the same episodes: "
            f"{reference.summary()}.",
            "",
        ]
    )
    lines = [
        f"# {title}",
        "",
        f"Steps to a success rate >= {threshold} (deterministic evaluation episodes from the "
        "default reset, checked at every checkpoint): median over seeds with a distribution-free "
        "95% interval (order statistics), `inf` = not reached within the budget. Final success "
        "rate and return (last checkpoint): mean with a Student-t 95% interval over seeds (the "
        "success interval clipped to [0, 1]). ms / step: wall time of learning per environment "
        "step, everything included (median over seeds); the last column is the part spent in "
        "the fitted-Q phases (with replay), per training episode.",
        "",
        *_success_definition(env_id),
        *quoted,
        "| agent | seeds | steps to success (median [95%]) | reached | final success | "
        "final return | ms / step | fitted-Q + replay s / episode |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for label in labels:
        sel = [r for r in rows if r["label"] == label]
        steps = [steps_to_success(r, threshold) for r in sel]
        med, lo, hi = median_interval(steps)
        final_s = mean_interval([r["eval_success"][-1] for r in sel])
        final_r = mean_interval([r["eval_return"][-1] for r in sel])
        ms = float(np.median([r["ms_per_step"] for r in sel]))
        phases = [r["train_seconds_per_episode"] for r in sel if "train_seconds_per_episode" in r]
        phase = f"{float(np.median(phases)):.2f}" if phases else "-"
        reached = sum(math.isfinite(s) for s in steps)
        lines.append(
            f"| {label} | {len(sel)} | {med:g} [{lo:g}, {hi:g}] | {reached}/{len(sel)} | "
            f"{final_s.mean:.2f} [{max(final_s.low, 0.0):.2f}, {min(final_s.high, 1.0):.2f}] | "
            f"{final_r.mean:.1f} [{final_r.low:.1f}, {final_r.high:.1f}] | {ms:.2f} | {phase} |"
        )
    lines += [
        "",
        "Median evaluation success rate over seeds at each checkpoint (mean return in brackets):",
        "",
        "| steps | " + " | ".join(labels) + " |",
        "|---|" + "---|" * len(labels),
    ]
    checkpoints = sorted({t for r in rows for t in r["checkpoints"]})
    for t in checkpoints:
        cells = []
        for label in labels:
            at = [
                (s, ret)
                for r in rows if r["label"] == label
                for c, s, ret in zip(r["checkpoints"], r["eval_success"], r["eval_return"],
                                     strict=True)
                if c == t
            ]  # fmt: skip
            if at:
                med = float(np.median([a[0] for a in at]))
                cells.append(f"{med:.2f} ({np.mean([a[1] for a in at]):.1f})")
            else:
                cells.append("")
        lines.append(f"| {t} | " + " | ".join(cells) + " |")
    lines.append("")
    return "\n".join(lines)


def _success_definition(env_id: str | None) -> list[str]:
    known = KNOWN_TASKS.get(env_id) if env_id else None
    if known is None or known.success_return is None:
        return []
    return [
        f"{env_id} reports no per-episode success: an evaluation counts as a success (1) when "
        f"its mean return is >= {known.success_return:g}, else 0.",
        "",
    ]


def run_control_benchmark(
    out: str | Path,
    *,
    env_id: str,
    kernels: Sequence[str],
    seeds: int,
    timesteps: int,
    eval_every: int,
    eval_episodes: int = 20,
    configs: Sequence[Mapping[str, Any]] = ({},),
    baselines: Sequence[str] = (),
    jobs: int = 1,
    backend: str = "loky",
    scheduler: str | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> list[dict[str, Any]]:
    """Every (kernel, config, seed) cell through the resumable sweep runner; writes
    ``benchmark.json`` (the settings), ``control.csv``, ``learning_curves.png`` and
    ``CONTROL.md`` into ``out``, together.

    ``baselines`` (e.g. ``["sac"]``) adds cells of those baselines with default
    settings, same seeds, budgets and evaluation. Before any cell runs: the baselines
    can run (:func:`check_baselines`) and ``out`` holds no report of other settings
    unless ``overwrite`` (:func:`check_benchmark_dir`).
    """

    out = Path(out)
    settings = benchmark_settings(env_id, kernels, seeds, timesteps, eval_every, eval_episodes,
                                  configs, baselines)  # fmt: skip
    check_baselines(baselines)
    check_benchmark_dir(out, settings, overwrite)
    cells = [
        ControlCell(env_id, k, s, timesteps, eval_every, eval_episodes, dict(c))
        for k in kernels for c in configs for s in range(seeds)
    ] + [
        ControlCell(env_id, b, s, timesteps, eval_every, eval_episodes)
        for b in baselines for s in range(seeds)
    ]  # fmt: skip
    rows = run_sweep(
        cells, control_cell, out / "cells", jobs=jobs, backend=backend,
        scheduler=scheduler, progress=progress, desc="control",
    )  # fmt: skip
    flat = [
        {"label": r["label"], "kernel": r["kernel"], "seed": r["seed"], "timesteps": t,
         "eval_return": ret, "eval_success": s, "ms_per_step": r["ms_per_step"]}
        for r in rows
        for t, ret, s in zip(r["checkpoints"], r["eval_return"], r["eval_success"], strict=True)
    ]  # fmt: skip
    curves: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for label in dict.fromkeys(r["label"] for r in rows):
        sel = [r for r in rows if r["label"] == label]
        curves[label] = (
            np.array([r["checkpoints"] for r in sel], dtype=np.float64),
            np.array([r["eval_success"] for r in sel], dtype=np.float64),
        )
    reference = None
    if env_id == PENDULUM_SWING_UP_ID:
        reference = evaluate_agent(HandMadeController(), env_id, eval_episodes, seed=10_000)
    with staged_run(out, BENCHMARK_FILES, overwrite=True) as staging:  # checked above
        atomic_write_json(staging / "benchmark.json", {"settings": settings})
        write_csv(staging / "control.csv", flat)
        save_figure(
            plot_learning_curve(curves, env_id, ylabel="evaluation success rate"),
            staging / "learning_curves.png",
        )
        atomic_write_text(
            staging / "CONTROL.md",
            control_report(rows, f"Control benchmark on {env_id}", reference=reference,
                           env_id=env_id),
        )  # fmt: skip
    return rows
