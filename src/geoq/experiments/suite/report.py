"""SUITE.md and the suite's value-map figure, from the rows of :mod:`geoq.experiments.suite.run`.

The first table answers, per task and budget: does a graph kernel beat the
squared exponential? For each graph kernel the paired difference of MSEs
(graph - SE, same seed, same data, same evaluation pairs) gets a Student-t 95%
interval over seeds; the table shows the graph kernel with the lowest mean
difference. "yes" when its interval lies below 0, "no, SE better" when the
best graph kernel's interval lies above 0, "no difference shown" otherwise.
Picking the best of three kernels after the fact favours the graph kernels;
every kernel's interval is in the second table.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from geoq.experiments.stats import Interval, log_interval, paired_difference
from geoq.experiments.style import KERNEL_STYLE

__all__ = ["focus_note", "graph_vs_se", "plot_task_value_map", "render_suite_report"]

_POSTERIORS = {"online": "mse", "refit": "mse_refit"}


def _paired(
    rows: Sequence[Mapping[str, Any]], task: str, budget: int, kernel: str, column: str
) -> Interval:
    def by_seed(k: str) -> dict[int, float]:
        return {
            int(r["seed"]): float(r[column])
            for r in rows
            if r["task"] == task and r["kernel"] == k and int(r["max_bv"]) == budget
        }

    a, b = by_seed(kernel), by_seed("euclidean")
    seeds = sorted(set(a) & set(b))
    return paired_difference([a[s] for s in seeds], [b[s] for s in seeds])


def graph_vs_se(
    rows: Sequence[Mapping[str, Any]], task: str, budget: int, column: str
) -> tuple[str, Interval, dict[str, Interval]] | None:
    """The best graph kernel (lowest mean paired MSE difference to SE), its interval and
    every graph kernel's; ``None`` when there is no graph kernel or no SE row."""
    kernels = sorted({str(r["kernel"]) for r in rows if r["task"] == task} - {"euclidean"})
    if not kernels or not any(r["kernel"] == "euclidean" and r["task"] == task for r in rows):
        return None
    diffs = {k: _paired(rows, task, budget, k, column) for k in kernels}
    finite = {k: iv for k, iv in diffs.items() if np.isfinite(iv.mean)}
    if not finite:
        return None
    best = min(finite, key=lambda k: finite[k].mean)
    return best, finite[best], diffs


def _verdict(iv: Interval) -> str:
    if iv.high < 0:
        return "**yes**"
    if iv.low > 0:
        return "no, SE better"
    return "no difference shown"


def _geo(
    rows: Sequence[Mapping[str, Any]], task: str, kernel: str, budget: int, col: str
) -> Interval:
    return log_interval(
        float(r[col])
        for r in rows
        if r["task"] == task and r["kernel"] == kernel and int(r["max_bv"]) == budget
    )


def focus_note(
    description: str, n_eval: int, total_eval: int, n_train: int, total_train: int
) -> str:
    """One line: how many evaluation and training pairs lie in a task's focus region."""
    return (
        f"Pairs {description}: {n_eval} of {total_eval} evaluation pairs "
        f"({100 * n_eval / max(total_eval, 1):.1f}%) and {n_train} of {total_train} training "
        f"pairs ({100 * n_train / max(total_train, 1):.1f}%), all seeds. The MSE over "
        "those evaluation pairs alone is in the table below (`mse_focus`, `mse_refit_focus`)."
    )


def _focus_table(rows: Sequence[Mapping[str, Any]], task: str, budgets: Sequence[int]) -> list[str]:
    """MSE over the focus pairs only, per kernel and budget, with the paired difference to SE."""
    out = [
        "| kernel | max_bv | MSE online, focus pairs | MSE refit, focus pairs | graph - SE online "
        "[95%] | graph - SE refit [95%] |",
        "|---|---|---|---|---|---|",
    ]
    kernels = [k for k in KERNEL_STYLE if any(r["kernel"] == k and r["task"] == task for r in rows)]
    for k in kernels:
        for b in budgets:
            online = _geo(rows, task, k, b, "mse_focus")
            refit = _geo(rows, task, k, b, "mse_refit_focus")
            diffs = ["-", "-"]
            if k != "euclidean":
                diffs = [
                    str(_paired(rows, task, b, k, c)) for c in ("mse_focus", "mse_refit_focus")
                ]
            out.append(f"| {k} | {b} | {online} | {refit} | {diffs[0]} | {diffs[1]} |")
    return [*out, ""]


def render_suite_report(
    *,
    task_ids: Sequence[str],
    config: Mapping[str, Any],
    rows: Sequence[Mapping[str, Any]],
    tuned: Mapping[str, Mapping[str, Mapping[str, Any]]],
    evidence: Mapping[str, Mapping[str, Any]],
    maps: Mapping[str, Mapping[str, Any]],
    wall_seconds: float,
    version: str,
    notes: Mapping[str, Sequence[str]] | None = None,
) -> str:
    """The Markdown of SUITE.md; ``notes`` adds measured lines under a task's table."""
    budgets = sorted({int(r["max_bv"]) for r in rows})
    seeds = len({int(r["seed"]) for r in rows})
    lines = [
        "# geoq task suite: policy evaluation (the Fig. 3 protocol on every task)",
        "",
        f"geoq {version}, scale `{config['scale']}`, root seed {config['root_seed']}, "
        f"{seeds} seeds, budgets {budgets}. Per-task settings (evaluation policy, gamma, "
        "roll-outs, input scaling) are in `config.json` and `geoq.tasks.suite`; inputs are "
        "scaled by the spaces' half-ranges, so the swing-up here uses `(pi, 8, 5)` where "
        "`geoq reproduce` uses `(2, 4, 5)`, and its numbers differ from REPORT.md's.",
        "",
        "## Does a graph kernel beat the squared exponential?",
        "",
        "Paired difference of the MSE against Monte-Carlo `Q^pi` (graph kernel - SE, same "
        "seed; negative = the graph kernel is better), mean and Student-t 95% interval over "
        "seeds, for the graph kernel with the lowest mean difference (of `nearest`, "
        "`interpolated`, `resistance`; choosing the best of three after the fact favours the "
        "graph kernels). *online*: the paper's posterior; *refit*: DTC refit on the final "
        "basis set and graph.",
        "",
        "| task | max_bv | SE MSE (online) | best graph kernel, online | graph - SE, online "
        "[95%] | beats SE? | best graph kernel, refit | graph - SE, refit [95%] | beats SE? |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for t in task_ids:
        for b in budgets:
            se = _geo(rows, t, "euclidean", b, "mse")
            cells = [t, str(b), str(se)]
            for col in _POSTERIORS.values():
                res = graph_vs_se(rows, t, b, col)
                if res is None:
                    cells += ["-", "-", "-"]
                    continue
                best, iv, _ = res
                ratio = _geo(rows, t, best, b, col).mean / max(
                    _geo(rows, t, "euclidean", b, col).mean, 1e-300
                )
                cells += [best, f"{iv} (x{ratio:.2g} SE's MSE)", _verdict(iv)]
            lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        "(`x r SE's MSE`: the ratio of the two geometric-mean MSEs.)",
        "",
        "## Every kernel",
        "",
        "MSE against Monte-Carlo `Q^pi` (geometric mean [95% interval] over seeds), online "
        "and refitted, the normalised predictive variance (online) and the mean number of "
        "basis vectors. `constant` is the MSE of predicting the mean training return.",
        "",
    ]
    for t in task_ids:
        lines += [
            f"### {t}",
            "",
            "| kernel | max_bv | MSE online | MSE refit | norm. variance | "
            "n_bv | negative novelty | graph - SE online [95%] | graph - SE refit [95%] |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for k in [
            k for k in KERNEL_STYLE if any(r["kernel"] == k and r["task"] == t for r in rows)
        ]:
            for b in budgets:
                sub = [
                    r for r in rows if r["task"] == t and r["kernel"] == k and int(r["max_bv"]) == b
                ]
                if not sub:
                    continue
                diffs = ["-", "-"]
                if k != "euclidean":
                    diffs = [str(_paired(rows, t, b, k, c)) for c in _POSTERIORS.values()]
                mse_online, mse_refit = _geo(rows, t, k, b, "mse"), _geo(rows, t, k, b, "mse_refit")
                n_bv = np.mean([r["n_bv"] for r in sub])
                negative = np.mean([r["negative_novelty"] for r in sub])
                lines.append(
                    f"| {k} | {b} | {mse_online} | {mse_refit} "
                    f"| {_geo(rows, t, k, b, 'normalized_variance')} | {n_bv:.1f} "
                    f"| {negative:.0f} | {diffs[0]} | {diffs[1]} |"
                )
        const = [
            float(r["mse_constant"]) for r in rows if r["task"] == t and r["kernel"] == "euclidean"
        ]
        floor = [
            float(r["mc_noise_floor"])
            for r in rows
            if r["task"] == t and r["kernel"] == "euclidean"
        ]
        lines += [
            "",
            f"Constant predictor: MSE {np.mean(const):.4g}; Monte-Carlo noise floor (mean "
            f"squared standard error of the truth): {np.mean(floor):.3g}.",
            "",
        ]
        for note in (notes or {}).get(t, ()):
            lines += [note, ""]
        if any(r["task"] == t and "mse_focus" in r for r in rows):
            lines += _focus_table(rows, t, budgets)
        if t in maps:
            m = maps[t]
            errs = ", ".join(f"`{k}` {v:.4g}" for k, v in m["mse"].items())
            lines += [
                f"Value map (`{t.replace('/', '_')}/value_map.png`, `Q(s, f(s))` at the "
                f"policy's mean action over the whole state box, "
                f"{len(m['x'])} x {len(m['y'])} states, learners trained on seed 0's "
                f"roll-outs with {config['map_max_bv']} basis vectors): MSE against the "
                f"Monte-Carlo map {errs}.",
                "",
            ]
    lines += [
        "## Hyper-parameters",
        "",
        "Squared exponential: length-scales (one per scaled input), prior variance and "
        "noise by maximum exact-GP evidence on at most 500 training pairs (standardised "
        "targets), with 3 restarts; the prior variance and noise are shared by every kernel. "
        "Graph kernels: `eps`, `sigma_sp`, `sigma_se` and the eq. 5 variant (`nearest`, "
        "`interpolated`) and `eps`, `l` (`resistance`) by the held-out validation MSE "
        "against Monte-Carlo `Q^pi` after a refit, on the grids of `geoq reproduce` "
        "(`<task>/tuning.csv` lists every candidate). Inputs are scaled by the spaces' "
        "half-ranges (`geoq.tasks.box_scaling`).",
        "",
        "| task | SE length-scales | amplitude | noise | log evidence (start -> end) | "
        "nearest | interpolated | resistance |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for t in task_ids:
        ev = evidence[t]
        ls = ", ".join(f"{v:.3g}" for v in ev["lengthscale"])
        graph = []
        for k in ("nearest", "interpolated", "resistance"):
            c = tuned[t].get(k)
            if c is None:
                graph.append("-")
            elif k == "resistance":
                graph.append(f"eps {c['eps']}, l {c['resistance_lengthscale']}")
            else:
                extra = (
                    f", sigma_se {c['sigma_se']}, normalised {c['normalize_weights']}"
                    if k == "interpolated"
                    else ""
                )
                graph.append(f"eps {c['eps']}, sigma_sp {c['sigma_sp']}{extra}")
        lines.append(
            f"| {t} | {ls} | {ev['amplitude']:.3g} | {ev['noise']:.3g} | "
            f"{ev['log_evidence_start']:.1f} -> {ev['log_evidence']:.1f} | "
            + " | ".join(graph)
            + " |"
        )
    lines += [
        "",
        f"Wall time: {wall_seconds:.0f} s.",
        "",
    ]
    return "\n".join(lines)


def plot_task_value_map(task_id: str, names: Sequence[str], m: Mapping[str, Any]) -> Figure:
    """Value maps of a task with a 2-D state: Monte-Carlo truth and one panel per kernel.

    ``m`` is a row of :func:`geoq.experiments.suite.run.map_cell`. The colour scale is the
    truth's; the GP panels show the training states (grey dots). For ``geoq/TwoRooms-v0``
    the wall (``x = 0.5`` outside the door ``0.8 <= y <= 1``) is drawn on every panel.
    """
    xs, ys = np.asarray(m["x"]), np.asarray(m["y"])
    # The truth first, then the kernels in the order of every other figure (a cell's row
    # comes back from JSON with its keys sorted).
    names_maps = [k for k in KERNEL_STYLE if k == "monte_carlo" and k in m["maps"]]
    names_maps += [k for k in KERNEL_STYLE if k != "monte_carlo" and k in m["maps"]]
    names_maps += sorted(k for k in m["maps"] if k not in names_maps)
    fig = Figure(figsize=(3.6 * len(names_maps), 3.4), layout="constrained")
    axes = fig.subplots(1, len(names_maps), squeeze=False)[0]
    truth = np.asarray(m["maps"]["monte_carlo"], dtype=np.float64)
    vmin, vmax = float(np.nanmin(truth)), float(np.nanmax(truth))
    dx, dy = 0.5 * (xs[1] - xs[0]), 0.5 * (ys[1] - ys[0])
    extent = (xs[0] - dx, xs[-1] + dx, ys[0] - dy, ys[-1] + dy)
    train = np.asarray(m.get("train_states", []), dtype=np.float64).reshape(-1, 2)
    im = None
    for ax, name in zip(axes, names_maps, strict=True):
        values = np.asarray(m["maps"][name], dtype=np.float64).reshape(len(xs), len(ys))
        im = ax.imshow(
            values.T,
            origin="lower",
            extent=extent,
            aspect="auto",
            vmin=vmin,
            vmax=vmax,
            cmap="viridis",
        )
        title = KERNEL_STYLE.get(name, {}).get("label", name)
        if name in m["mse"]:
            title += f"\nMSE vs MC {m['mse'][name]:.3g}"
            if train.size:
                ax.scatter(train[:, 0], train[:, 1], s=1, c="0.7", alpha=0.5)
        ax.set_title(title, fontsize=8)
        ax.set_xlabel(names[0])
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        if task_id == "geoq/TwoRooms-v0":
            ax.plot([0.5, 0.5], [0.0, 0.8], color="white", lw=2)
    axes[0].set_ylabel(names[1])
    if im is not None:
        fig.colorbar(im, ax=list(axes), label="Q(s, f(s))")
    fig.suptitle(f"{task_id}: value maps", fontsize=9)
    return fig
