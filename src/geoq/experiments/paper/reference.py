"""The reference test of the reproduction: a run's Fig. 3 cells and claim verdicts against a
stored run, with stated tolerances.

Outputs need not be byte-identical across versions of geoq (within a version the same
seed gives the same bytes); what a change must keep is the science. A run is summarised
(:func:`summarise`) as

* one record per Fig. 3 *cell* (learner: ``tuned`` or a variant; kernel; budget; MSE
  column: online, refitted, refitted after every roll-out): the mean over seeds and the
  half-width of its Student-t 95% interval, over the seeds whose posterior did not
  diverge (MSE not finite or above :data:`~geoq.experiments.paper.report.DIVERGED` x the
  constant predictor's, REPORT.md's definition), and how many diverged;
* the verdict of every claim, posterior, graph kernel and learner
  (:func:`~geoq.experiments.paper.claims.claim_verdicts`, REPORT.md's verdicts).

:func:`compare` holds a run to a stored summary: the same configuration and cells; in
every cell the same number of diverged seeds and a mean within :data:`REL_TOL` of the
reference's (relative) or within :data:`HALF_WIDTH_FRACTION` of its 95% half-width,
whichever is looser; every verdict unchanged. A reference is re-based (recorded again)
only with a written reason in CHANGELOG.md.

Some learners' results are decided by rounding: the same code and seeds give other
numbers on another CPU (:mod:`geoq.experiments.paper.rounding`; the ``pd_novelty`` learners'
chaotic re-anchoring, for one). The run measures which, with its rounding probe; their
cells carry ``sensitive: true`` and their claims' verdicts read
:data:`~geoq.experiments.paper.claims.SENSITIVE`. :func:`compare` holds such a cell as
sensitive (the run must find it so too; its mean and divergences are rounding's, not
compared) and such a verdict as that word, on any machine.

``python -m geoq.experiments.paper.reference record RUN_DIR FILE`` writes a summary;
``python -m geoq.experiments.paper.reference check RUN_DIR FILE`` compares a run with a summary
(exit status 1 and one line per difference when they differ).
"""

from __future__ import annotations

import csv
import json
import math
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from geoq._io import atomic_write_json
from geoq.experiments.paper.claims import claim_verdicts
from geoq.experiments.paper.config import VARIANTS, ReproConfig, config_for_scale
from geoq.experiments.paper.report import DIVERGED
from geoq.experiments.paper.rounding import sensitive_learners
from geoq.experiments.stats import mean_interval
from geoq.learners import KERNEL_NAMES

__all__ = [
    "HALF_WIDTH_FRACTION",
    "MSE_COLUMNS",
    "REFERENCE_CONFIG",
    "REL_TOL",
    "compare",
    "summarise",
]

#: A cell's mean may differ from the reference's by this fraction of it ...
REL_TOL = 0.02
#: ... or by this fraction of the reference's 95% half-width, whichever is looser.
HALF_WIDTH_FRACTION = 0.1
#: The Fig. 3 columns compared (``mse_refit_episode``: the paper's tuned kernels only).
MSE_COLUMNS = ("mse", "mse_refit", "mse_refit_episode")
_FORMAT = 2

#: The reduced reproduction of the reference test (``tests/experiments``): the quick
#: preset's learning problem (3 seeds, 3 x 250 training steps) with every kernel and
#: variant (the paper scale's) at the budgets 10, 50 and 100, with smaller ground truth,
#: maps and tuning (about a minute on 2 cores).
REFERENCE_CONFIG: ReproConfig = config_for_scale("quick").replace(
    scale="reference",
    kernels=KERNEL_NAMES,
    variants=tuple(VARIANTS),
    budgets=(10, 50, 100),
    eval_pairs=100,
    mc_rollouts=30,
    map_grid=10,
    map_mc_rollouts=4,
    td_episodes=200,
    graph_max_bv=100,
    edge_count_eps=(0.1, 0.5, 0.9),
    tune_max_bv=50,
    tune_pairs=50,
    tune_mc_rollouts=10,
)


def _read_rows(path: Path) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    text = ("kernel", "variant")
    return [{k: v if k in text or v == "" else float(v) for k, v in r.items()} for r in rows]


def _cells(
    rows: Sequence[Mapping[str, Any]], learner: str, sensitive: set[tuple[str, str]]
) -> list[dict[str, Any]]:
    out = []
    keys = sorted({(str(r["kernel"]), int(r["max_bv"])) for r in rows})
    for kernel, budget in keys:
        sub = [r for r in rows if r["kernel"] == kernel and int(r["max_bv"]) == budget]
        for column in MSE_COLUMNS:
            if any(r.get(column, "") == "" for r in sub):
                continue
            ok = [
                float(r[column])
                for r in sub
                if float(r[column]) <= DIVERGED * float(r["mse_constant"])  # NaN: diverged
            ]
            iv = mean_interval(ok)
            half = (iv.high - iv.low) / 2.0 if iv.n >= 2 else math.inf
            out.append(
                {
                    "learner": learner,
                    "kernel": kernel,
                    "max_bv": budget,
                    "column": column,
                    "mean": iv.mean if ok else None,
                    "half_width": half if math.isfinite(half) else None,
                    "n_seeds": len(sub),
                    "diverged": len(sub) - len(ok),
                    "sensitive": (learner, kernel) in sensitive,
                }
            )
    return out


def summarise(run_dir: str | Path) -> dict[str, Any]:
    """The summary of the reproduction in ``run_dir`` (its ``config.json`` and Fig. 3 CSVs)."""
    run = Path(run_dir)
    config = json.loads((run / "config.json").read_text())["config"]
    rows = _read_rows(run / "fig3_all.csv")
    variant_rows = _read_rows(run / "fig3_variants.csv")
    sensitive = sensitive_learners([*rows, *variant_rows])
    cells = _cells(rows, "tuned", sensitive)
    for v in VARIANTS:
        cells += _cells([r for r in variant_rows if r["variant"] == v], v, sensitive)
    return {
        "format": _FORMAT,
        "config": config,
        "cells": cells,
        "verdicts": claim_verdicts(rows, variant_rows),
    }


def _cell_key(c: Mapping[str, Any]) -> tuple[str, str, int, str]:
    return (c["learner"], c["kernel"], int(c["max_bv"]), c["column"])


def _cell_difference(new: Mapping[str, Any], ref: Mapping[str, Any]) -> str | None:
    """Why ``new`` does not match ``ref`` (one cell), or None."""
    if bool(new.get("sensitive")) != bool(ref.get("sensitive")):
        found = "the run" if new.get("sensitive") else "the reference"
        return f"decided by rounding in {found} only"
    if ref.get("sensitive"):
        return None  # its numbers are rounding's
    if new["diverged"] != ref["diverged"] or new["n_seeds"] != ref["n_seeds"]:
        return (
            f"{new['diverged']} of {new['n_seeds']} seeds diverged, reference "
            f"{ref['diverged']} of {ref['n_seeds']}"
        )
    if ref["mean"] is None:
        return None  # every seed diverged, in both
    half = math.inf if ref["half_width"] is None else float(ref["half_width"])
    allowed = max(REL_TOL * abs(float(ref["mean"])), HALF_WIDTH_FRACTION * half)
    gap = abs(float(new["mean"]) - float(ref["mean"]))
    if not gap <= allowed:
        return (
            f"mean {new['mean']:.6g}, reference {ref['mean']:.6g} (differs by {gap:.3g}; "
            f"allowed {allowed:.3g})"
        )
    return None


def compare(run: Mapping[str, Any], reference: Mapping[str, Any]) -> list[str]:
    """Every difference between the summaries ``run`` and ``reference`` beyond the
    tolerances (module docstring), one line each; empty when the run passes."""
    out = []
    if run["config"] != reference["config"]:
        keys = set(run["config"]) | set(reference["config"])
        changed = sorted(k for k in keys if run["config"].get(k) != reference["config"].get(k))
        out.append(f"configuration differs from the reference's in {changed}")
    new = {_cell_key(c): c for c in run["cells"]}
    ref = {_cell_key(c): c for c in reference["cells"]}
    for key in sorted(set(new) ^ set(ref)):
        out.append(f"cell {key}: only in the {'run' if key in new else 'reference'}")
    for key in sorted(set(new) & set(ref)):
        why = _cell_difference(new[key], ref[key])
        if why is not None:
            out.append(f"cell {key}: {why}")
    verdicts = {_verdict_key(v): v for v in run["verdicts"]}
    for v in reference["verdicts"]:
        got = verdicts.pop(_verdict_key(v), None)
        if got != v:
            out.append(f"verdict {_verdict_key(v)}: {_learners(got)}, reference {_learners(v)}")
    out += [f"verdict {k}: only in the run" for k in verdicts]
    return out


#: The fields of a verdict record that name it; the others are its learners' verdicts.
_VERDICT_KEY = ("claim", "posterior", "kernel")


def _verdict_key(v: Mapping[str, str]) -> tuple[str, str, str]:
    return (v["claim"], v["posterior"], v["kernel"])


def _learners(v: Mapping[str, str] | None) -> str:
    if v is None:
        return "missing"
    return ", ".join(f"{k}: {x}" for k, x in v.items() if k not in _VERDICT_KEY)


def _main(argv: list[str]) -> int:
    if len(argv) != 3 or argv[0] not in ("record", "check"):
        print(__doc__.split("\n\n")[-1].strip(), file=sys.stderr)
        return 2
    command, run_dir, *paths = argv
    summary = summarise(run_dir)
    if command == "record":
        atomic_write_json(Path(paths[0]), summary)
        print(f"recorded {len(summary['cells'])} cells and {len(summary['verdicts'])} verdicts")
        return 0
    reference = json.loads(Path(paths[0]).read_text())
    differences = compare(summary, reference)
    for line in differences:
        print(line)
    n = len(reference["cells"])
    rounding = sum(bool(c.get("sensitive")) for c in reference["cells"])
    print(f"{'differs from' if differences else 'matches'} the reference ({n} cells, "
          f"{rounding} of them decided by rounding)")  # fmt: skip
    return 1 if differences else 0


if __name__ == "__main__":  # pragma: no cover - command line
    sys.exit(_main(sys.argv[1:]))
