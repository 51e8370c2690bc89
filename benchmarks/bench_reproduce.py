"""The whole reproduction: ``geoq reproduce --scale quick --jobs 2`` against its former preset.

Issue 31 asks for the quick reproduction (``make demo``) in under a minute on 2 cores.
The quick preset now runs the paper's learners only (the three kernels and the
``faithful`` variant); the beyond-paper cells, the ``resistance`` kernel and the
``pd_novelty`` variant, run at the paper scale. The baseline in the same run is the
former quick preset (every kernel and variant), timed alternately with the new one
(``rounds`` of each, fresh output directories, 2 worker processes), and the stages of
each run (tuning, ground truth, Fig. 3 cells, the rest) are printed. A third run,
the quick preset without its rounding probe (``probe_seeds = 0``), gives the probe's
cost in the same process (issue 44).
"""

from __future__ import annotations

import functools
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import geoq.experiments.paper.reproduce as reproduce_module
from geoq.experiments.paper.config import VARIANTS, ReproConfig, config_for_scale
from geoq.learners import KERNEL_NAMES, QGPConfig

#: Tiny sizes for ``benchmarks/run.py --quick`` (figures of no meaning).
TINY = dict(
    seeds=2, budgets=(5, 15), train_rollouts=2, train_steps=60, graph_rollouts=2,
    graph_max_bv=30, eval_pairs=20, eval_rollouts=2, mc_rollouts=4, map_grid=6,
    map_mc_rollouts=2, map_max_bv=15, td_episodes=20, td_steps=30, tune_max_bv=15,
    tune_pairs=20, tune_mc_rollouts=4, learner=QGPConfig(),
)  # fmt: skip


def _timed_run(cfg: ReproConfig, jobs: int) -> dict[str, float]:
    """Run the reproduction of ``cfg`` in a fresh directory; wall seconds per stage."""
    stages: dict[str, float] = {}

    def timed(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                key = kwargs.get("desc", name) if name == "sweep" else name
                stages[key] = stages.get(key, 0.0) + time.perf_counter() - start

        return wrapper

    originals = {n: getattr(reproduce_module, n) for n in ("tune", "run_sweep")}
    reproduce_module.tune = timed("tuning", originals["tune"])  # type: ignore[attr-defined]
    reproduce_module.run_sweep = timed("sweep", originals["run_sweep"])  # type: ignore[attr-defined]
    try:
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            reproduce_module.reproduce(Path(out), config=cfg, jobs=jobs, progress=False)
            total = time.perf_counter() - start
    finally:
        for name, fn in originals.items():
            setattr(reproduce_module, name, fn)
    stages["the rest"] = total - sum(stages.values())
    stages["total"] = total
    return stages


def main(quick: bool = False, rounds: int = 2, jobs: int = 2) -> None:
    """``quick``: tiny sizes, one round (``benchmarks/run.py --quick``)."""
    new = config_for_scale("quick")
    old = new.replace(kernels=KERNEL_NAMES, variants=tuple(VARIANTS))
    if quick:
        new, old, rounds = new.replace(**TINY), old.replace(**TINY), 1
    unprobed = new.replace(probe_seeds=0)
    print(f"geoq reproduce, quick preset, {jobs} worker processes, {rounds} round(s), alternating")
    runs: dict[str, list[dict[str, float]]] = {
        "former preset": [],
        "quick preset": [],
        "no probe": [],
    }
    for _ in range(rounds):
        runs["former preset"].append(_timed_run(old, jobs))
        runs["quick preset"].append(_timed_run(new, jobs))
        runs["no probe"].append(_timed_run(unprobed, jobs))
    names = list(runs["quick preset"][0])
    print(f"  {'stage (s)':>16} " + "".join(f"{n:>16}" for n in runs))
    for stage in names:
        cells = [", ".join(f"{r.get(stage, 0.0):.1f}" for r in rs) for rs in runs.values()]
        print(f"  {stage:>16} " + "".join(f"{c:>16}" for c in cells))
    ratios = [
        o["total"] / n["total"]
        for o, n in zip(runs["former preset"], runs["quick preset"], strict=True)
    ]
    print("  former / quick, round by round: " + ", ".join(f"{r:.2f}x" for r in ratios))
    probe = [
        n["total"] / u["total"] for n, u in zip(runs["quick preset"], runs["no probe"], strict=True)
    ]
    print("  quick / no probe (the probe's cost): " + ", ".join(f"{r:.2f}x" for r in probe))


if __name__ == "__main__":
    main()
