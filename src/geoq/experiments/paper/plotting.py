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

from geoq.experiments.paper.fig1 import GraphSnapshot
from geoq.experiments.paper.fig2 import ValueMaps
from geoq.experiments.stats import log_interval
from geoq.experiments.style import KERNEL_STYLE

__all__ = [
    "plot_budget_curves",
    "plot_graphs",
    "plot_value_maps",
]


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
