"""The paper's Fig. 3 claims as tests on paired differences, and their verdicts.

Each of the paper's Fig. 3 claims is turned into a test on *paired*
differences (the kernels of one seed see the same roll-outs and are scored on
the same evaluation pairs), with Student-t 95% intervals over seeds:

1. *geodesic better at small budgets*: ``MSE_geo - MSE_euc < 0`` at the
   smallest budgets (the lowest third of the grid; a kernel run at part of the grid is
   tested at its budgets in that third, or its smallest);
2. *equal past a threshold*: the smallest budget from which on every interval
   of the difference contains 0;
3. *slower variance decrease*: ``NV_geo - NV_euc > 0``;
4. *a band where it is worse*: budgets where ``MSE_geo - MSE_euc > 0``.

A verdict that reads a learner whose results rounding decides (the graph kernel's or
the baseline's; :mod:`geoq.experiments.paper.rounding`) is :data:`SENSITIVE`: the same code
and seeds give another verdict on another CPU.

REPORT.md (:mod:`geoq.experiments.paper.report`) renders them; the reference test of the
reproduction (:mod:`geoq.experiments.paper.reference`) compares them with a stored run.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from geoq.experiments.paper.config import VARIANTS
from geoq.experiments.paper.rounding import sensitive_learners
from geoq.experiments.stats import Interval, paired_difference

__all__ = [
    "GRAPH_KERNELS",
    "POSTERIOR_COLUMNS",
    "SENSITIVE",
    "ClaimVerdict",
    "assess_claims",
    "claim_verdicts",
]

#: The verdict of a claim that reads results rounding decides.
SENSITIVE = "sensitive to rounding"

GRAPH_KERNELS = ("nearest", "interpolated", "resistance")

ClaimVerdict = dict[str, Any]


def _by(
    rows: Sequence[Mapping[str, Any]], kernel: str, budget: int, column: str
) -> dict[int, float]:
    return {
        int(r["seed"]): float(r[column])
        for r in rows
        if r["kernel"] == kernel and int(r["max_bv"]) == budget
    }


def _paired(rows: Sequence[Mapping[str, Any]], kernel: str, budget: int, column: str) -> Interval:
    a = _by(rows, kernel, budget, column)
    b = _by(rows, "euclidean", budget, column)
    seeds = sorted(set(a) & set(b))
    return paired_difference([a[s] for s in seeds], [b[s] for s in seeds])


#: Columns (MSE, normalised variance) of each posterior in ``fig3.csv``.
POSTERIOR_COLUMNS = {
    "online": ("mse", "normalized_variance"),
    "refit": ("mse_refit", "normalized_variance_refit"),
}


def assess_claims(
    rows: Sequence[Mapping[str, Any]], posterior: str = "online"
) -> dict[str, list[ClaimVerdict]]:
    """Per graph kernel, a verdict on each of the paper's four Fig. 3 claims.

    ``posterior`` is ``"online"`` (the paper's online posterior) or ``"refit"``
    (the DTC refit on the final BV set and graph).
    """
    mse_col, nv_col = POSTERIOR_COLUMNS[posterior]
    grid = sorted({int(r["max_bv"]) for r in rows})
    small_grid = grid[: max(1, len(grid) // 3)]
    euclidean = {int(r["max_bv"]) for r in rows if r["kernel"] == "euclidean"}
    out: dict[str, list[ClaimVerdict]] = {}
    for g in GRAPH_KERNELS:
        # A kernel run at part of the grid (the learners beyond the paper) is tested at
        # its own budgets; "small" stays the lowest third of the whole grid.
        budgets = sorted({int(r["max_bv"]) for r in rows if r["kernel"] == g} & euclidean)
        if not budgets:
            continue
        small = [b for b in budgets if b <= small_grid[-1]] or budgets[:1]
        diff = {b: _paired(rows, g, b, mse_col) for b in budgets}
        nv = {b: _paired(rows, g, b, nv_col) for b in budgets}
        verdicts: list[ClaimVerdict] = []

        better = [b for b in small if diff[b].high < 0]
        worse_small = [b for b in small if diff[b].low > 0]
        verdicts.append(
            {
                "claim": "the graph kernel has lower MSE at small budgets",
                "verdict": "supported"
                if len(better) == len(small)
                else (
                    "contradicted"
                    if worse_small
                    else ("partly supported" if better else "not supported")
                ),
                "evidence": {b: diff[b] for b in small},
            }
        )

        threshold = next(
            (
                b
                for i, b in enumerate(budgets)
                if all(not diff[c].excludes_zero for c in budgets[i:])
            ),
            None,
        )
        verdicts.append(
            {
                "claim": "same MSE as the standard GP past a threshold budget",
                "verdict": "consistent (no significant difference from the threshold on)"
                if threshold is not None and threshold != budgets[0]
                else (
                    "no significant difference at any budget"
                    if threshold == budgets[0]
                    else "not supported"
                ),
                "threshold": threshold,
                "evidence": {b: diff[b] for b in budgets[-max(1, len(budgets) // 3) :]},
            }
        )

        higher = [b for b in budgets if nv[b].low > 0]
        lower = [b for b in budgets if nv[b].high < 0]
        verdicts.append(
            {
                "claim": "normalised variance decreases more slowly with the graph kernel",
                "verdict": "supported"
                if len(higher) > len(budgets) / 2
                else ("contradicted" if len(lower) > len(budgets) / 2 else "mixed"),
                "higher_at": higher,
                "lower_at": lower,
                "evidence": nv,
            }
        )

        worse = [b for b in budgets if diff[b].low > 0]
        verdicts.append(
            {
                "claim": "a band of budgets where the graph kernel is worse",
                "verdict": "supported" if worse else "not supported",
                "worse_at": worse,
                "evidence": {b: diff[b] for b in budgets},
            }
        )
        out[g] = verdicts
    return out


def _finite_enough(rows: Sequence[Mapping[str, Any]], kernel: str, posterior: str) -> bool:
    """Whether every budget has >= 2 seeds with a finite MSE of ``kernel`` (else no test)."""
    column = POSTERIOR_COLUMNS[posterior][0]
    budgets = {int(r["max_bv"]) for r in rows if r["kernel"] == kernel}
    return all(
        sum(np.isfinite(v) for v in _by(rows, kernel, b, column).values()) >= 2 for b in budgets
    )


def claim_verdicts(
    rows: Sequence[Mapping[str, Any]],
    variant_rows: Sequence[Mapping[str, Any]] = (),
    *,
    tuned_only_kernels: bool = True,
    show_local: bool = False,
) -> list[dict[str, str]]:
    """The verdict of each claim, posterior and graph kernel, per learner: REPORT.md's
    "Do the paper's claims change?" table as records (``claim``, ``posterior``, ``kernel``,
    then ``tuned`` and each variant: the verdict, :data:`SENSITIVE`, ``"undetermined (MSE
    not finite)"`` or ``"-"``). ``tuned_only_kernels``: keep the kernels no variant was run
    for (``resistance``; the report's table leaves them out, their verdicts are in the
    sections above it). ``show_local``: a sensitive verdict also says what it is on this
    machine (``"sensitive to rounding (here: supported)"``).
    """
    sensitive = sensitive_learners([*rows, *variant_rows])
    names = [v for v in VARIANTS if any(r["variant"] == v for r in variant_rows)]
    baseline = [r for r in rows if r["kernel"] == "euclidean"]
    by_variant = {
        "tuned": list(rows),
        **{v: baseline + [r for r in variant_rows if r["variant"] == v] for v in names},
    }
    verdicts = {
        (v, posterior): assess_claims(sub, posterior)
        for v, sub in by_variant.items()
        for posterior in POSTERIOR_COLUMNS
    }
    out: list[dict[str, str]] = []
    claims = [c["claim"] for c in next(iter(verdicts[("tuned", "online")].values()), [])]
    for i, claim in enumerate(claims):
        for posterior in POSTERIOR_COLUMNS:
            for g in GRAPH_KERNELS:
                cells = [verdicts[(v, posterior)].get(g) for v in ("tuned", *names)]
                variants_skip = all(c is None for c in cells[1:]) and bool(names)
                if cells[0] is None or (variants_skip and not tuned_only_kernels):
                    continue
                record = {"claim": claim, "posterior": posterior, "kernel": g}
                for v, c, sub in zip(by_variant, cells, by_variant.values(), strict=True):
                    verdict = (
                        "undetermined (MSE not finite)"
                        if c is not None
                        and "variance" not in claim  # the other three claims test MSEs
                        and not _finite_enough(sub, g, posterior)
                        else (c[i]["verdict"] if c is not None else "-")
                    )
                    if c is not None and {(v, g), ("tuned", "euclidean")} & sensitive:
                        verdict = f"{SENSITIVE} (here: {verdict})" if show_local else SENSITIVE
                    record[v] = verdict
                out.append(record)
    return out
