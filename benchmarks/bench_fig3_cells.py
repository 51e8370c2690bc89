"""One Fig. 3 cell of the quick scale's learning problem in isolation, per cell type and budget.

Until issue 31 the Fig. 3 stage was most of ``make demo``: at ``--scale quick`` (3
seeds, 5 budgets) its 120 cells took ~170 s with one job, and a few cell types carried
nearly all of it (issue 13; since issue 31 they run at the paper scale only): the
``resistance`` kernel (``K_BV`` re-factorised and the whitened posterior re-anchored
after every change of the BV set) and the ``pd_novelty`` variant of the geodesic
kernels (the same, plus an eigendecomposition of the indefinite ``K_BV`` per change).
Each row here is one cell exactly as ``geoq.experiments.paper.fig3.budget_cell`` runs it
(training roll-outs of seed 0, the seed's evaluation pairs and Monte-Carlo truth,
``score_learner``), timed with one BLAS thread; ``x 3 seeds`` is what that cell type
and budget added to the former quick run's Fig. 3 stage.

Learner settings: the quick run's tuning (``results/demo/tuning.json`` from
``make demo``) if it exists, else the values that tuning gives at root seed 2012
(:data:`QUICK_TUNED`), so the benchmark needs no 40 s tuning of its own.

The columns are the paper scale's budgets; each row runs at the budgets ``geoq reproduce
--scale paper`` runs its cell type at for 10 seeds (``-``: not run there: the learners
beyond the paper run at part of the grid, issue 31), timed in CPU seconds (the machine
is often shared). A row that the paper run computes differently since issue 31 is timed
twice, ``before`` (every budget, the per-roll-out refit learner for every tuned kernel)
and ``now``. The last line is what one seed's cells of the slow types cost both ways,
their ratio in this run, and times 10 seeds over 2 workers: about their share of the
paper run's Fig. 3 stage on 2 idle cores (its evaluation uses 500 pairs where this uses
the quick scale's 150, a small part).
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from geoq._threads import one_blas_thread
from geoq.experiments.paper.config import config_for_scale, variant_learner
from geoq.experiments.paper.fig3 import TruthCell, refits_per_rollout, score_learner, truth_cell
from geoq.experiments.paper.seeding import STREAM, rng_for
from geoq.gp import NumericalWarning
from geoq.learners import QGPConfig
from geoq.policies import DEFAULT_POLICY_SIGMA, default_policy
from geoq.rollouts import collect_rollouts

#: (variant, kernel) of the rows: the slow cell types, and the SE and the tuned
#: ``nearest`` kernel for scale.
CELL_TYPES = (
    ("tuned", "euclidean"),
    ("tuned", "nearest"),
    ("tuned", "resistance"),
    ("pd_novelty", "nearest"),
    ("pd_novelty", "interpolated"),
)
#: The paper scale, whose budgets are the columns.
PAPER = config_for_scale("paper")
TUNING_FILE = Path("results/demo/tuning.json")
_SHARED = {"amplitude": 3.7870371398361082, "noise": 0.17506494876403583}
#: The quick scale's tuned settings at root seed 2012 (``tuning.json``), per kernel.
QUICK_TUNED: dict[str, dict[str, Any]] = {
    "euclidean": {**_SHARED, "lengthscale": (1.1431958796596038, 1.1975909836798757, 1e3)},
    "nearest": {**_SHARED, "eps": 0.3, "sigma_sp": 0.3},
    "interpolated": {
        **_SHARED,
        "eps": 0.5,
        "sigma_sp": 0.1,
        "sigma_se": 0.01,
        "normalize_weights": True,
        "attach_weights": True,
    },
    "resistance": {**_SHARED, "eps": 0.3, "resistance_lengthscale": 3.0},
}


def tuned_learners() -> tuple[dict[str, QGPConfig], str]:
    """Learner settings per kernel and where they came from (the quick run tunes no
    ``resistance`` kernel since issue 31: its settings come from :data:`QUICK_TUNED`)."""
    learners = {k: QGPConfig(kernel=k, **v) for k, v in QUICK_TUNED.items()}  # type: ignore[arg-type]
    if not TUNING_FILE.is_file():
        return learners, "QUICK_TUNED (no results/demo/tuning.json)"
    configs = json.loads(TUNING_FILE.read_text())["result"]["configs"]
    learners.update({k: QGPConfig.from_dict(v) for k, v in configs.items()})
    return learners, f"{TUNING_FILE} (missing kernels: QUICK_TUNED)"


def main(quick: bool = False) -> None:
    """``quick``: tiny sizes, figures of no meaning (``benchmarks/run.py --quick``)."""
    cfg = config_for_scale("quick")
    budgets = PAPER.budgets
    if quick:
        cfg = cfg.replace(train_rollouts=1, train_steps=40, eval_pairs=10, mc_rollouts=4)
        budgets = (10,)
    sigma = DEFAULT_POLICY_SIGMA
    truth = truth_cell(TruthCell.of(cfg, 0, sigma))
    rollouts = collect_rollouts(
        cfg.train_rollouts,
        cfg.train_steps,
        default_policy(sigma),
        rng_for(cfg.root_seed, 0, STREAM["train"]),
        gamma=cfg.gamma,
    )
    arrays = [np.asarray(truth[k]) for k in ("states", "actions", "mc_mean", "mc_stderr", "td")]
    learners, source = tuned_learners()
    print(f"one Fig. 3 cell (seed 0, quick scale, one BLAS thread, CPU s); settings: {source}")
    header = "".join(f"{b:>7}" for b in budgets)
    print(f"  {'variant':>10} {'kernel':>12} {'':>6} {header}{'sum':>8}")
    slow_before = slow_now = 0.0
    with warnings.catch_warnings(), one_blas_thread():
        warnings.simplefilter("ignore", NumericalWarning)
        for variant, kernel in CELL_TYPES:
            learner = learners[kernel]
            if variant != "tuned":
                learner = variant_learner(variant, learner)

            def timed(budget: int, episode: bool) -> float:
                config = learner.replace(kernel=kernel, max_bv=budget)  # noqa: B023
                start = time.process_time()
                score_learner(config, rollouts, *arrays[:4], td=arrays[4], refit_episode=episode)
                return time.process_time() - start

            # Before issue 31's sub-grid: every budget, the per-roll-out refit for every
            # tuned learner. Now: the paper run's budgets and rule.
            before = [timed(b, variant == "tuned") for b in budgets]
            runs = set(PAPER.budgets_of(kernel, variant)) if not quick else set(budgets)
            same_rule = refits_per_rollout(kernel, variant) == (variant == "tuned")
            now = [
                None
                if b not in runs
                else (t if same_rule else timed(b, refits_per_rollout(kernel, variant)))
                for b, t in zip(budgets, before, strict=True)
            ]
            changed = not same_rule or None in now
            rows = [("before", before), ("now", now)] if changed else [("", before)]
            for label, times in rows:
                cells = "".join("      -" if t is None else f"{t:7.2f}" for t in times)
                total = sum(t for t in times if t is not None)
                print(f"  {variant:>10} {kernel:>12} {label:>6} {cells}{total:8.1f}")
            if kernel == "resistance" or variant == "pd_novelty":
                slow_before += sum(before)
                slow_now += sum(t for t in now if t is not None)
    print(
        f"  resistance and pd_novelty cells, one seed, CPU s: {slow_now:.1f} as the paper run "
        f"computes them now, {slow_before:.1f} on every budget as before issue 31's sub-grid "
        f"(ratio {slow_now / slow_before:.2f}); x 10 seeds / 2 workers: {5 * slow_now:.0f} s "
        f"against {5 * slow_before:.0f} s of the paper run's Fig. 3 stage"
    )


if __name__ == "__main__":
    main()
