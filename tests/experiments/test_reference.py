"""The reference test (issue 31): a reduced reproduction against a stored run.

``data/reference_run.json`` was recorded from the code before any speed change of issue 31
(``python -m geoq.experiments.reference record RUN_DIR FILE`` on a run of
``REFERENCE_CONFIG``); it is re-based only with a written reason in CHANGELOG.md.
``data/reference_run_avx2.json`` is the same run of the same code summarised on a
machine of another kind (x86_64 without AVX-512: OpenBLAS's Haswell kernels, where
``reference_run.json``'s had AVX-512); the run is held to what the two agree on
(:func:`~geoq.experiments.reference.agreed`). ``data/reference_quick.json`` is the same
summary of ``geoq reproduce --scale quick`` (checked by hand: ``python -m
geoq.experiments.reference check results/demo tests/experiments/data/reference_quick.json``).
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
    agreed,
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


#: One run of ``REFERENCE_CONFIG``, summarised on machines of two kinds.
PLATFORM_REFERENCES = ("reference_run.json", "reference_run_avx2.json")


def test_reduced_reproduction_matches_the_reference(tmp_path):
    reproduce(tmp_path, config=REFERENCE_CONFIG, jobs=2, progress=False)
    reference = agreed([_reference(name) for name in PLATFORM_REFERENCES])
    assert compare(summarise(tmp_path), reference) == []


def test_the_machines_disagree_only_where_rounding_decides():
    """What the two references leave out: the refits on the graph kernels' Gram, which is
    not positive definite (the novelty-driven learner's), and the verdicts built on them;
    every other cell and verdict is held on any machine."""
    first, second = (_reference(name) for name in PLATFORM_REFERENCES)
    both = agreed([first, second])
    cells = [tuple(x["cell"]) for x in both["left_out"] if "cell" in x]
    assert cells and all(
        (learner, column) == ("pd_novelty", "mse_refit") and kernel in ("nearest", "interpolated")
        for learner, kernel, _, column in cells
    )
    assert len(both["cells"]) + len(cells) == len(first["cells"])
    learners = {x["learner"] for x in both["left_out"] if "verdict" in x}
    assert learners <= {"pd_novelty"}
    assert agreed([first, second])["left_out"] == agreed([second, first])["left_out"]
    # A run is held to every cell the machines agree on, and asked for nothing else.
    run = copy.deepcopy(second)
    assert compare(run, both) == []
    kept = _finite_cell(run)
    kept["mean"] = 2 * kept["mean"] + 1.0
    assert any("mean" in line for line in compare(run, both))
    with pytest.raises(ValueError, match="different configurations"):
        agreed([first, {**second, "config": {**second["config"], "seeds": 2}}])


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
