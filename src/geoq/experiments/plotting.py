"""Results -> :class:`matplotlib.figure.Figure` (the top of the data flow: it reads the
experiment records of :mod:`geoq.experiments`). Nothing here saves a file (the CLI does).

Figures are built on ``matplotlib.figure.Figure`` objects directly (no pyplot
state), so they are safe in worker processes and tests.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from geoq._typing import ArrayLike
from geoq.experiments.fig1 import GraphSnapshot
from geoq.experiments.fig2 import ValueMaps
from geoq.experiments.stats import log_interval, mean_interval
from geoq.experiments.visits import VisitMap

__all__ = [
    "KERNEL_STYLE",
    "plot_budget_curves",
    "plot_graphs",
    "plot_learning_curve",
    "plot_training_with_evaluations",
    "plot_value_maps",
    "plot_visits",
]

#: Colour and label per kernel name, shared by every figure.
KERNEL_STYLE: dict[str, dict[str, str]] = {
    "euclidean": {"color": "tab:blue", "label": "Euclidean (SE)"},
    "nearest": {"color": "tab:orange", "label": "shortest path, nearest (eq. 4)"},
    "interpolated": {"color": "tab:green", "label": "shortest path, interpolated (eq. 5)"},
    "resistance": {"color": "tab:purple", "label": "resistance distance, PD (beyond paper)"},
    "monte_carlo": {"color": "black", "label": "Monte-Carlo Q^pi (ground truth)"},
}


def plot_graphs(snapshots: Sequence[GraphSnapshot]) -> Figure:
    """Fig. 1: a panel per ``eps``: nodes over (theta, omega) coloured by torque, edges as lines."""
    fig = Figure(figsize=(5.0 * len(snapshots), 4.4), layout="constrained")
    axes = fig.subplots(1, len(snapshots), squeeze=False)[0]
    for ax, snap in zip(axes, snapshots, strict=True):
        xy = snap.nodes[:, :2]
        if len(snap.edges):
            segments = np.stack([xy[snap.edges[:, 0]], xy[snap.edges[:, 1]]], axis=1)
            ax.add_collection(
                LineCollection(list(segments), colors="0.6", linewidths=0.5, zorder=1)
            )
        sc = ax.scatter(
            xy[:, 0], xy[:, 1], c=snap.nodes[:, 2], cmap="coolwarm", s=12, zorder=2, vmin=-5, vmax=5
        )
        s = snap.stats
        ax.set_title(
            f"eps = {snap.eps:g}: {s['n_nodes']} nodes, {s['n_edges']} edges\n"
            f"mean degree {s['mean_degree']:.1f}, {s['n_components']} components, "
            f"{s['isolated_nodes']} isolated",
            fontsize=9,
        )
        ax.set_xlabel("theta [rad]")
        ax.set_ylabel("omega [rad/s]")
        ax.set_xlim(-np.pi, np.pi)
        ax.autoscale(axis="y")
    fig.colorbar(sc, ax=list(axes), label="torque [N m]")
    return fig


def plot_value_maps(maps: ValueMaps) -> Figure:
    """Fig. 2: value maps ``Q(s, f(s))`` over (theta, omega), ground truth and one per kernel."""
    names = list(maps.maps)
    fig = Figure(figsize=(4.0 * len(names), 3.8), layout="constrained")
    axes = fig.subplots(1, len(names), squeeze=False)[0]
    # One colour scale, the ground truth's when there is one (a learner's outliers would
    # otherwise wash it out); values beyond it saturate.
    scale_maps = [maps.maps["monte_carlo"]] if "monte_carlo" in maps.maps else maps.maps.values()
    finite = np.concatenate([m[np.isfinite(m)].ravel() for m in scale_maps])
    vmin, vmax = (float(np.min(finite)), float(np.max(finite))) if finite.size else (0.0, 1.0)
    dt = 0.5 * (maps.theta[1] - maps.theta[0]) if maps.theta.size > 1 else 0.5
    dw = 0.5 * (maps.omega[1] - maps.omega[0]) if maps.omega.size > 1 else 0.5
    extent = (maps.theta[0] - dt, maps.theta[-1] + dt, maps.omega[0] - dw, maps.omega[-1] + dw)
    im = None
    for ax, name in zip(axes, names, strict=True):
        im = ax.imshow(
            maps.maps[name].T,
            origin="lower",
            extent=extent,
            aspect="auto",
            vmin=vmin,
            vmax=vmax,
            cmap="viridis",
            interpolation="nearest",
        )
        if name in maps.basis:
            b = maps.basis[name]
            ax.scatter(b[:, 0], b[:, 1], s=3, c="white", alpha=0.6, linewidths=0)
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        title = KERNEL_STYLE.get(name, {"label": name})["label"]
        if name in maps.mse:
            title += f"\nMSE vs MC {maps.mse[name]:.3g}"
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("theta [rad]")
    axes[0].set_ylabel("omega [rad/s]")
    if im is not None:
        fig.colorbar(im, ax=list(axes), label="Q(s, f(s))")
    return fig


def plot_budget_curves(
    rows: Sequence[Mapping[str, Any]], *, reference: str = "mc", posterior: str = "online"
) -> Figure:
    """Fig. 3: (a) MSE and (b) normalised variance vs ``max_bv``, over seeds: geometric mean
    and 95% log-scale interval (:func:`~geoq.experiments.stats.log_interval`).

    ``rows`` are the tidy rows of ``fig3.csv`` (one per kernel, budget and seed).
    ``reference`` chooses the MSE column: ``"mc"`` (``mse``) or ``"td"`` (``mse_td``).
    ``posterior``: ``"online"`` (the paper's) or ``"refit"`` (DTC on the final BV set
    and graph; MSE against Monte-Carlo only).
    """
    if posterior not in ("online", "refit") or reference not in ("mc", "td"):
        raise ValueError(f"unknown reference {reference!r} or posterior {posterior!r}")
    if posterior == "refit" and reference != "mc":
        raise ValueError("the refit posterior is scored against Monte-Carlo only")
    column = {"mc": "mse", "td": "mse_td"}[reference]
    var_column = "normalized_variance"
    if posterior == "refit":
        column, var_column = "mse_refit", "normalized_variance_refit"
    fig = Figure(figsize=(10.0, 4.0), layout="constrained")
    ax_mse, ax_var = fig.subplots(1, 2)
    kernels = [k for k in KERNEL_STYLE if any(r["kernel"] == k for r in rows)]  # no MC rows
    for kernel in kernels:
        style = KERNEL_STYLE[kernel]
        budgets = sorted({int(r["max_bv"]) for r in rows if r["kernel"] == kernel})
        for ax, col in ((ax_mse, column), (ax_var, var_column)):
            stats = [  # the same log-scale intervals as REPORT.md: never below 0
                log_interval(
                    float(r[col]) for r in rows if r["kernel"] == kernel and int(r["max_bv"]) == b
                )
                for b in budgets
            ]
            mean = np.array([s.mean for s in stats])
            low = np.array([s.low if np.isfinite(s.low) else s.mean for s in stats])
            high = np.array([s.high if np.isfinite(s.high) else s.mean for s in stats])
            ax.plot(budgets, mean, "o-", color=style["color"], label=style["label"], ms=3)
            ax.fill_between(budgets, low, high, color=style["color"], alpha=0.2, linewidth=0)
    n_seeds = len({r["seed"] for r in rows})
    ax_mse.set_title(
        f"(a) MSE vs {'Monte-Carlo' if reference == 'mc' else 'TD'} Q^pi, {posterior} "
        f"posterior ({n_seeds} seeds, 95% CI)",
        fontsize=9,
    )
    ax_mse.set_yscale("log")
    ax_mse.set_ylabel("MSE")
    ax_var.set_title("(b) normalised predictive variance (var / prior var)", fontsize=9)
    for ax in (ax_mse, ax_var):
        ax.set_xlabel("max number of basis vectors")
        ax.grid(alpha=0.3)
    ax_mse.legend(fontsize=8)
    return fig


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

    ``evaluations`` are the rows of :class:`~geoq.experiments.control_eval.EvalCallback`
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
    (:mod:`geoq.experiments.visits`)."""
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
