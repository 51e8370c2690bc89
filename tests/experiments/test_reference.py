"""The reference test (issue 31): a reduced reproduction against a stored run.

``data/reference_run.json`` was recorded from the code before any speed change of issue 31
(``python -m geoq.experiments.reference record RUN_DIR FILE`` on a run of
``REFERENCE_CONFIG``); it is re-based only with a written reason in CHANGELOG.md.
``data/reference_quick.json`` is the same summary of ``geoq reproduce --scale quick``
(checked by hand: ``python -m geoq.experiments.reference check results/demo
tests/experiments/data/reference_quick.json``).
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from geoq.experiments.config import VARIANTS, config_for_scale
from geoq.experiments.reference import (
    HALF_WIDTH_FRACTION,
    REFERENCE_CONFIG,
    REL_TOL,
    compare,
    summarise,
)
from geoq.experiments.reproduce import reproduce
from geoq.learners import KERNEL_NAMES, PAPER_KERNELS

DATA = Path(__file__).parent / "data"


def _reference(name: str = "reference_run.json") -> dict:
    return json.loads((DATA / name).read_text())


def test_reference_config_is_the_recorded_one():
    """A changed preset or reduced scale needs a new reference (and a reason)."""
    stored = _reference()["config"]
    assert json.loads(json.dumps(REFERENCE_CONFIG.as_dict())) == stored
    quick = _reference("reference_quick.json")["config"]
    assert quick["scale"] == "quick" and quick["budgets"] == [10, 25, 50, 100, 200]


def test_quick_runs_every_paper_learner_and_paper_scale_every_learner():
    """Issue 31: the beyond-paper cells left the quick preset only; the paper scale keeps them."""
    quick, paper = config_for_scale("quick"), config_for_scale("paper")
    assert set(PAPER_KERNELS) <= set(quick.kernels) and "faithful" in quick.variants
    assert set(paper.kernels) == set(KERNEL_NAMES) and set(paper.variants) == set(VARIANTS)
    # The learners beyond the paper at part of the grid: its span and its lowest third.
    part = paper.budgets_of("resistance")
    assert part == paper.budgets_of("nearest", "pd_novelty") and len(part) < len(paper.budgets)
    assert set(paper.budgets[: len(paper.budgets) // 3]) <= set(part)
    assert (part[0], part[-1]) == (paper.budgets[0], paper.budgets[-1])
    assert paper.budgets_of("nearest", "faithful") == paper.budgets == paper.budgets_of("nearest")


def test_reduced_reproduction_matches_the_reference(tmp_path):
    reproduce(tmp_path, config=REFERENCE_CONFIG, jobs=2, progress=False)
    assert compare(summarise(tmp_path), _reference()) == []


def _finite_cell(summary: dict) -> dict:
    return next(c for c in summary["cells"] if c["mean"] is not None and c["half_width"])


def test_a_mean_is_held_to_the_looser_of_the_two_tolerances():
    ref = _reference()
    cell = _finite_cell(ref)
    allowed = max(REL_TOL * abs(cell["mean"]), HALF_WIDTH_FRACTION * cell["half_width"])
    for factor, passes in ((0.99, True), (1.01, False)):
        run = copy.deepcopy(ref)
        _finite_cell(run)["mean"] = cell["mean"] + factor * allowed
        assert (compare(run, ref) == []) is passes


def test_divergence_verdicts_and_cells_are_compared():
    ref = _reference()
    run = copy.deepcopy(ref)
    _finite_cell(run)["diverged"] += 1
    assert any("diverged" in line for line in compare(run, ref))
    run = copy.deepcopy(ref)
    run["verdicts"][0]["tuned"] = "supported" if ref["verdicts"][0]["tuned"] != "supported" else "-"
    assert any(line.startswith("verdict") for line in compare(run, ref))
    run = copy.deepcopy(ref)
    run["cells"].pop()
    assert any("only in the reference" in line for line in compare(run, ref))
    run = copy.deepcopy(ref)
    run["config"]["seeds"] = 2
    assert any("configuration" in line for line in compare(run, ref))


@pytest.mark.parametrize(
    ("name", "learners"),
    [
        ("reference_run.json", {"tuned", "faithful", "pd_novelty"}),
        ("reference_quick.json", {"tuned", "faithful"}),  # the paper's learners only
    ],
)
def test_a_reference_matches_itself(name, learners):
    ref = _reference(name)
    assert compare(copy.deepcopy(ref), ref) == []
    assert {c["learner"] for c in ref["cells"]} == learners
