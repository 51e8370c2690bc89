"""CPU seconds of Fig. 3 cells exactly as a paper run computes them (issue 31).

Not a speed benchmark of ``run.py`` (it needs a finished run): the measurement behind the
design notes' section on resyncs that find the factor unchanged. It reads the tuned
settings and the ground truth of a run of ``geoq reproduce --scale paper`` (``OUT/tuning.json``,
``OUT/cells/truth``), runs the named cells of one seed with
:func:`geoq.experiments.paper.fig3.budget_cell` in this process, one after the other, and prints
each cell's CPU time and MSEs (so two versions can be compared cell by cell)::

    python research/paper_cells.py OUT SEED VARIANT:KERNEL:BUDGET ... [--profile FILE]
    python research/paper_cells.py OUT 0 --slow    # resistance and pd_novelty, every budget

``VARIANT`` is ``tuned`` or a variant (``pd_novelty``, ``faithful``). ``--profile FILE``
writes a cProfile of the last cell. Run it under ``PYTHONPATH`` of the version to time,
alternating with the other version.
"""

from __future__ import annotations

import cProfile
import json
import sys
import time
from pathlib import Path

from geoq.experiments.paper.config import config_for_scale, variant_learner
from geoq.experiments.paper.fig3 import BudgetCell, TruthCell, budget_cell
from geoq.experiments.paper.tuning import TuningResult
from geoq.experiments.sweep import cell_spec
from geoq.policies import DEFAULT_POLICY_SIGMA

#: ``--slow``: the cell types that re-anchor at every basis change, at every paper budget.
SLOW = tuple(
    f"{cell}:{b}"
    for cell in ("tuned:resistance", "pd_novelty:nearest", "pd_novelty:interpolated")
    for b in config_for_scale("paper").budgets
)


def main(argv: list[str]) -> int:
    if argv[:1] in (["-h"], ["--help"]):
        print(__doc__)
        return 0
    profile = None
    if "--profile" in argv:
        i = argv.index("--profile")
        profile = argv[i + 1]
        argv = argv[:i] + argv[i + 2 :]
    if len(argv) < 3:
        print(__doc__)
        return 2
    out, seed = Path(argv[0]), int(argv[1])
    specs = list(SLOW) if argv[2:] == ["--slow"] else argv[2:]
    cfg = config_for_scale("paper")
    tuning = TuningResult.from_dict(json.loads((out / "tuning.json").read_text())["result"])
    truth = TruthCell.of(cfg, seed, DEFAULT_POLICY_SIGMA)
    total = 0.0
    for spec in specs:
        variant, kernel, budget = spec.split(":")
        learner = tuning.configs[kernel]
        if variant != "tuned":
            learner = variant_learner(variant, learner)
        cell = BudgetCell(
            kernel=kernel,
            max_bv=int(budget),
            seed=seed,
            root_seed=cfg.root_seed,
            train_rollouts=cfg.train_rollouts,
            train_steps=cfg.train_steps,
            learner=learner.as_dict(),
            truth_dir=str((out / "cells" / "truth").resolve()),
            truth=cell_spec(truth),
            variant=variant,
        )
        profiler = cProfile.Profile() if profile else None
        start = time.process_time()
        if profiler:
            profiler.enable()
        row = budget_cell(cell)
        if profiler:
            profiler.disable()
            profiler.dump_stats(profile)
        seconds = time.process_time() - start
        total += seconds
        episode = row.get("mse_refit_episode", float("nan"))
        print(
            f"{spec:30s} {seconds:7.2f} s  mse={row['mse']:.6g} refit={row['mse_refit']:.6g} "
            f"episode={episode:.6g} n_bv={row['n_bv']} resyncs={row['q_resyncs']}",
            flush=True,
        )
    print(f"total {total:.2f} s CPU")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
