"""``geoq reproduce``: every figure of the paper, its data, and a REPORT.md, in one call.

Pipeline (data flows one way)::

    tuning (evidence + validation)  ->  tuning.json, tuning.csv
    ground truth per seed (sweep)   ->  cells/truth/*.json
    Fig. 3 cells (sweep)            ->  cells/fig3/*.json -> fig3.csv (the paper's kernels),
                                        fig3_all.csv (+ resistance), fig3*.png,
                                        fig3_variants.csv (faithful, pd_novelty)
    Fig. 1 graphs, Fig. 2 maps      ->  fig1.csv/png, fig1_eps.csv (edges vs eps), fig2.csv/png
    everything                      ->  config.json, REPORT.md

Every file is written atomically; the sweeps keep one file per finished cell,
so rerunning with the same ``out`` resumes where a killed run stopped and ends
with identical files.
"""

from __future__ import annotations

import json
import os
import platform
import time
import warnings
from dataclasses import replace
from pathlib import Path

import geoq
from geoq._io import atomic_write_json, atomic_write_text
from geoq.experiments.outputs import save_figure, write_csv
from geoq.experiments.paper.config import (
    VARIANT_KERNELS,
    VARIANTS,
    ReproConfig,
    config_for_scale,
    variant_learner,
)
from geoq.experiments.paper.fig1 import EDGE_COUNT_COLUMNS, build_graphs, edge_counts_by_eps
from geoq.experiments.paper.fig2 import value_maps
from geoq.experiments.paper.fig3 import (
    FIG3_COLUMNS,
    VARIANT_COLUMNS,
    BudgetCell,
    TruthCell,
    budget_cell,
    longest_first,
    truth_cell,
)
from geoq.experiments.paper.plotting import plot_budget_curves, plot_graphs, plot_value_maps
from geoq.experiments.paper.report import render_report
from geoq.experiments.paper.rounding import attach_probes
from geoq.experiments.paper.seeding import STREAM, rng_for
from geoq.experiments.paper.tuning import TUNING_COLUMNS, TuningResult, tune
from geoq.experiments.sweep import cap_jobs, cell_spec, run_sweep
from geoq.gp import NumericalWarning
from geoq.learners import KERNEL_NAMES, PAPER_KERNELS
from geoq.policies import DEFAULT_POLICY_SIGMA, default_policy
from geoq.rollouts import collect_rollouts

__all__ = ["reproduce"]


def _tuning(out: Path, cfg: ReproConfig, policy_sigma: float, jobs: int = 1) -> TuningResult:
    """Tune once per configuration; reuse ``tuning.json`` when it was made for the same one."""
    path = out / "tuning.json"
    key = {"config": cfg.as_dict(), "policy_sigma": policy_sigma}
    if path.is_file():
        try:
            stored = json.loads(path.read_text())
            if stored.get("key") == json.loads(json.dumps(key)):
                return TuningResult.from_dict(stored["result"])
        except (ValueError, KeyError, TypeError):
            pass  # unreadable or foreign: tune again
    result = tune(cfg, default_policy(policy_sigma), jobs=jobs)
    atomic_write_json(path, {"key": key, "result": result.as_dict()})
    return result


def reproduce(
    out: str | Path,
    scale: str = "quick",
    *,
    jobs: int = 1,
    backend: str = "loky",
    scheduler: str | None = None,
    root_seed: int | None = None,
    progress: bool = True,
    config: ReproConfig | None = None,
) -> Path:
    """Reproduce Fig. 1-3 into ``out``; return the path of ``REPORT.md``.

    Parameters
    ----------
    out : output directory (created; reused to resume).
    scale : ``"quick"`` or ``"paper"`` (see :mod:`geoq.experiments.paper.config`).
    jobs, backend, scheduler : how the sweeps run (:func:`geoq.experiments.sweep.run_sweep`).
    root_seed : overrides the preset's root seed.
    config : a full configuration instead of a preset (tests use tiny ones).
    """
    started = time.perf_counter()
    cfg = config if config is not None else config_for_scale(scale, root_seed)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sigma = DEFAULT_POLICY_SIGMA
    policy = default_policy(sigma)

    # The validation grid runs in local worker processes (a remote cluster is for the cells).
    local_jobs = (os.cpu_count() or 1) if jobs == -1 else jobs
    tuning = _tuning(out, cfg, sigma, cap_jobs(local_jobs)[0] if scheduler is None else 1)
    write_csv(out / "tuning.csv", tuning.validation, TUNING_COLUMNS)

    truth_dir = (out / "cells" / "truth").resolve()
    truth_cells = [TruthCell.of(cfg, s, sigma) for s in range(cfg.seeds)]
    sweep = {"jobs": jobs, "backend": backend, "scheduler": scheduler, "progress": progress}
    run_sweep(truth_cells, truth_cell, truth_dir, desc="ground truth", **sweep)  # type: ignore[arg-type]

    def budget(kernel: str, max_bv: int, tc: TruthCell, variant: str) -> BudgetCell:
        learner = tuning.configs[kernel]
        if variant != "tuned":
            learner = variant_learner(variant, learner)
        return BudgetCell(
            kernel=kernel,
            max_bv=max_bv,
            seed=tc.seed,
            root_seed=cfg.root_seed,
            train_rollouts=cfg.train_rollouts,
            train_steps=cfg.train_steps,
            learner=learner.as_dict(),
            truth_dir=str(truth_dir),
            truth=cell_spec(tc),
            variant=variant,
        )

    cells = [
        budget(k, b, tc, "tuned")
        for tc in truth_cells
        for k in cfg.kernels
        for b in cfg.budgets_of(k)
    ]
    cells += [
        budget(k, b, tc, v)
        for v in cfg.variants
        for tc in truth_cells
        for k in VARIANT_KERNELS
        if k in cfg.kernels
        for b in cfg.budgets_of(k, v)
    ]
    cells += [replace(c, probe=True) for c in cells if c.seed < cfg.probe_seeds]
    # Long cells first (the rows are sorted below; their content does not depend on it).
    ordered = longest_first(cells)
    done = run_sweep(ordered, budget_cell, out / "cells" / "fig3", desc="fig3 cells", **sweep)  # type: ignore[arg-type]
    every = attach_probes(
        [r for r in done if not r.get("probe")], [r for r in done if r.get("probe")]
    )
    rows = [r for r in every if "variant" not in r]
    rows.sort(key=lambda r: (KERNEL_NAMES.index(r["kernel"]), int(r["max_bv"]), int(r["seed"])))
    variant_rows = [r for r in every if "variant" in r]
    variant_rows.sort(
        key=lambda r: (
            list(VARIANTS).index(r["variant"]),
            KERNEL_NAMES.index(r["kernel"]),
            int(r["max_bv"]),
            int(r["seed"]),
        )
    )
    write_csv(out / "fig3.csv", [r for r in rows if r["kernel"] in PAPER_KERNELS], FIG3_COLUMNS)
    write_csv(out / "fig3_all.csv", rows, FIG3_COLUMNS)
    if variant_rows:
        write_csv(out / "fig3_variants.csv", variant_rows, VARIANT_COLUMNS)
    save_figure(plot_budget_curves(rows, reference="mc"), out / "fig3.png")
    save_figure(plot_budget_curves(rows, posterior="refit"), out / "fig3_refit.png")
    save_figure(plot_budget_curves(rows, reference="td"), out / "fig3_td.png")

    with warnings.catch_warnings():
        # Repairs of the indefinite geodesic Gram are expected and counted (REPORT.md).
        warnings.simplefilter("ignore", NumericalWarning)
        graph_rollouts = collect_rollouts(
            cfg.graph_rollouts,
            cfg.train_steps,
            policy,
            rng_for(cfg.root_seed, STREAM["graphs"]),
            gamma=cfg.gamma,
        )
        graphs = build_graphs(
            graph_rollouts, tuning.configs["nearest"], cfg.graph_eps, cfg.graph_max_bv
        )
        write_csv(out / "fig1.csv", [{"eps": g.eps, **g.stats} for g in graphs])
        edge_counts = edge_counts_by_eps(
            graph_rollouts,
            tuning.configs["nearest"],
            cfg.graph_eps,
            cfg.edge_count_eps,
            cfg.graph_max_bv,
        )
        write_csv(out / "fig1_eps.csv", edge_counts, EDGE_COUNT_COLUMNS)
        save_figure(plot_graphs(graphs), out / "fig1.png")

        map_rollouts = collect_rollouts(
            cfg.train_rollouts,
            cfg.train_steps,
            policy,
            rng_for(cfg.root_seed, 0, STREAM["train"]),
            gamma=cfg.gamma,
        )
        maps = value_maps(
            map_rollouts,
            {k: tuning.configs[k].replace(max_bv=cfg.map_max_bv) for k in cfg.kernels},
            policy,
            rng_for(cfg.root_seed, STREAM["maps"]),
            cfg.map_grid,
            cfg.map_mc_rollouts,
            cfg.gamma,
        )
        write_csv(out / "fig2.csv", maps.rows())
        save_figure(plot_value_maps(maps), out / "fig2.png")

    wall = time.perf_counter() - started
    config_record = {
        "geoq_version": geoq.__version__,
        "python": platform.python_version(),
        "config": cfg.as_dict(),
        "policy_sigma": sigma,
        "seeds": {
            "root_seed": cfg.root_seed,
            "streams": "numpy.random.SeedSequence(root_seed, spawn_key=(seed, stream)) per seed, "
            "(stream,) run-wide",
            "stream_ids": STREAM,
            "seed_indices": list(range(cfg.seeds)),
        },
        "tuning": tuning.as_dict(),
        "execution": {"jobs": jobs, "backend": backend, "scheduler": scheduler},
    }
    atomic_write_json(out / "config.json", config_record)
    report = render_report(
        config=cfg.as_dict(),
        tuning=tuning.as_dict(),
        rows=rows,
        variant_rows=variant_rows,
        graphs=graphs,
        edge_counts=edge_counts,
        maps=maps,
        wall_seconds=wall,
        version=geoq.__version__,
    )
    return atomic_write_text(out / "REPORT.md", report)
