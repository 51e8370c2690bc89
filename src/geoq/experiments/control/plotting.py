"""Control results -> :class:`matplotlib.figure.Figure`: learning curves, one agent's
training with its evaluations, and where it went. Nothing here saves a file.

Figures are built on ``matplotlib.figure.Figure`` objects directly (no pyplot
state), so they are safe in worker processes and tests.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from geoq._typing import ArrayLike
from geoq.experiments.control.visits import VisitMap
from geoq.experiments.stats import mean_interval
from geoq.experiments.style import KERNEL_STYLE

__all__ = ["plot_learning_curve", "plot_training_with_evaluations", "plot_visits"]


def plot_learning_curve(
    curves: Mapping[str, tuple[np.ndarray, np.ndarray]],
    title: str,
    ylabel: str = "episode return",
) -> Figure:
    """Learning curves: per label, ``(timesteps [n_seeds, n], values [n_seeds, n])``.

    One seed: the curve itself. Several: the mean and its 95% interval over seeds.
    """
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.subplots()
    for label, (steps, values) in curves.items():
        kernel = label.split("[")[0]
        color = KERNEL_STYLE.get(kernel, {}).get("color")
        x = np.asarray(steps, dtype=np.float64)[0]
        v = np.atleast_2d(np.asarray(values, dtype=np.float64))
        if v.shape[0] == 1:
            ax.plot(x, v[0], marker="o", ms=3, color=color, label=label)
            continue
        stats = [mean_interval(v[:, j]) for j in range(v.shape[1])]
        ax.plot(x, [s.mean for s in stats], color=color, label=f"{label} (n={v.shape[0]})")
        ax.fill_between(
            x, [s.low for s in stats], [s.high for s in stats], color=color, alpha=0.2, lw=0
        )
    ax.set_xlabel("environment steps")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8)
    return fig


def plot_training_with_evaluations(
    train_steps: ArrayLike,
    train_returns: ArrayLike,
    evaluations: Sequence[Mapping[str, Any]],
    title: str,
) -> Figure:
    """One agent's learning: (a) the returns of its training episodes (exploring) and of
    the greedy evaluations (mean with its 95% interval over the evaluation episodes),
    (b) the evaluations' success, when the task reports one.

    ``evaluations`` are the rows of :class:`~geoq.experiments.control.evaluation.EvalCallback`
    (``timesteps``, ``mean_return``, ``return_low``, ``return_high``, ``success``).
    """
    t_eval = np.array([float(r["timesteps"]) for r in evaluations])
    success = np.array([float(r["success"]) for r in evaluations])
    with_success = bool(np.any(np.isfinite(success)))
    fig = Figure(figsize=(10.0 if with_success else 6.4, 4.2), layout="constrained")
    axes = fig.subplots(1, 2 if with_success else 1, squeeze=False)[0]
    ax = axes[0]
    ax.plot(
        np.asarray(train_steps, dtype=np.float64),
        np.asarray(train_returns, dtype=np.float64),
        "o-",
        ms=3,
        color="0.6",
        label="training episodes (exploring)",
    )
    if len(evaluations):
        mean = np.array([float(r["mean_return"]) for r in evaluations])
        low = np.array([float(r["return_low"]) for r in evaluations])
        high = np.array([float(r["return_high"]) for r in evaluations])
        n = int(evaluations[-1].get("episodes", 0))
        ax.plot(
            t_eval, mean, "o-", ms=4, color="tab:blue", label=f"greedy evaluation ({n} episodes)"
        )
        band = np.isfinite(low) & np.isfinite(high)
        ax.fill_between(t_eval[band], low[band], high[band], color="tab:blue", alpha=0.2, lw=0)
    ax.set_xlabel("environment steps")
    ax.set_ylabel("episode return")
    ax.set_title(f"(a) {title}: returns", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    if with_success:
        ax_s = axes[1]
        ax_s.plot(t_eval, success, "o-", ms=4, color="tab:blue")
        ax_s.set_ylim(-0.05, 1.05)
        ax_s.set_xlabel("environment steps")
        ax_s.set_ylabel("success rate of the greedy episodes")
        ax_s.set_title("(b) greedy evaluation: success", fontsize=10)
        ax_s.grid(alpha=0.3)
    return fig


def plot_visits(visits: VisitMap, title: str = "") -> Figure:
    """Training visits (log scale) and the greedy route of a 2-D task
    (:mod:`geoq.experiments.control.visits`)."""
    fig = Figure(figsize=(5.5, 4.6), layout="constrained")
    ax = fig.add_subplot()
    (x0, x1), (y0, y1) = visits.extent
    image = ax.imshow(
        np.log10(1.0 + visits.counts.T), origin="lower", extent=(x0, x1, y0, y1),
        aspect="auto", cmap="Greys", interpolation="nearest",
    )  # fmt: skip
    fig.colorbar(image, ax=ax, label="log10(1 + visits) in training")
    route = visits.route
    ax.plot(route[:, 0], route[:, 1], color="tab:red", lw=1.5, label="greedy route")
    ax.plot(*route[0], "o", color="tab:green", label="start")
    ax.plot(*route[-1], "s", color="tab:red", label="end")
    outcome = (
        "" if np.isnan(visits.success) else (" (success)" if visits.success else " (no success)")
    )
    ax.set(xlim=(x0, x1), ylim=(y0, y1), xlabel=visits.names[0], ylabel=visits.names[1])
    ax.set_title((title + ": " if title else "") + "where the agent went" + outcome)
    ax.legend(loc="best", fontsize="small")
    return fig
