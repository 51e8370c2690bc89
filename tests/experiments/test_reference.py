"""The reference test (issue 31): a reduced reproduction against a stored run.

``data/reference_run.json`` is the summary of a run of ``REFERENCE_CONFIG``
(``python -m geoq.experiments.paper.reference record RUN_DIR FILE``); it is re-based only with a
written reason in CHANGELOG.md. The run measures which learners rounding decides (its
rounding probe, :mod:`geoq.experiments.paper.rounding`), and the test holds those as
sensitive on any machine. ``data/kernels/`` holds the same run summarised on the same
machine under the AVX2 and SSE kernel settings (``tests/_kernels.py``), and
``data/machines/`` two summaries from machines of other kinds (an AVX-512 Sapphire
Rapids, a machine with OpenBLAS's Haswell kernels; recorded before the probe existed,
format 1). ``data/reference_quick.json`` is the same summary of ``geoq reproduce --scale
quick`` (checked by hand: ``python -m geoq.experiments.paper.reference check results/demo
tests/experiments/data/reference_quick.json``).
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from geoq.experiments.paper.claims import SENSITIVE
from geoq.experiments.paper.config import VARIANTS, config_for_scale
from geoq.experiments.paper.reference import (
    HALF_WIDTH_FRACTION,
    REFERENCE_CONFIG,
    REL_TOL,
    _cell_difference,
    _cell_key,
    _verdict_key,
    compare,
    summarise,
)
from geoq.experiments.paper.reproduce import reproduce
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


#: The same run summarised under the other kernel settings of this machine, and on
#: machines of other kinds.
KERNEL_SETTINGS = ("kernels/avx2.json", "kernels/sse.json")
OTHER_MACHINES = ("machines/sapphire_rapids.json", "machines/haswell.json")


@pytest.mark.numbers
def test_reduced_reproduction_matches_the_reference(tmp_path):
    reproduce(tmp_path, config=REFERENCE_CONFIG, jobs=2, progress=False)
    assert compare(summarise(tmp_path), _reference()) == []


def test_the_probe_finds_the_learners_rounding_decides():
    """In the reference, rounding decides ``pd_novelty`` on both graph kernels (every
    cell and every verdict of theirs) and nothing else; the other kernel settings find
    the same and match it, although their numbers for those learners differ."""
    ref = _reference()
    flagged = {(c["learner"], c["kernel"]) for c in ref["cells"] if c["sensitive"]}
    assert flagged == {("pd_novelty", "nearest"), ("pd_novelty", "interpolated")}
    assert all(c["sensitive"] == ((c["learner"], c["kernel"]) in flagged) for c in ref["cells"])
    for v in ref["verdicts"]:
        assert (v["pd_novelty"] == SENSITIVE) == (v["kernel"] in ("nearest", "interpolated"))
        assert SENSITIVE not in (v["tuned"], v["faithful"])
    for name in KERNEL_SETTINGS:
        other = _reference(name)
        assert compare(other, ref) == [] and compare(ref, other) == []
        means = {_cell_key(c): c["mean"] for c in other["cells"]}
        moved = [c for c in ref["cells"] if c["sensitive"] and means[_cell_key(c)] != c["mean"]]
        assert moved  # the flags are doing work


def test_other_machines_differ_only_where_the_probe_found_rounding():
    """The summaries of two other kinds of machine (before the probe existed) differ from
    the reference beyond the tolerances only in cells and verdicts it flags."""
    ref = _reference()
    cells = {_cell_key(c): c for c in ref["cells"]}
    verdicts = {_verdict_key(v): v for v in ref["verdicts"]}
    for name in OTHER_MACHINES:
        other = _reference(name)
        differing = 0
        for c in other["cells"]:
            mine = cells[_cell_key(c)]
            if _cell_difference(c, {**mine, "sensitive": False}) is not None:
                assert mine["sensitive"], (name, _cell_key(c))
                differing += 1
        for v in other["verdicts"]:
            mine = verdicts[_verdict_key(v)]
            for learner in ("tuned", *VARIANTS):
                if v[learner] != mine[learner]:
                    assert mine[learner] == SENSITIVE, (name, _verdict_key(v), learner)
        assert differing > 0


def _finite_cell(summary: dict) -> dict:
    return next(
        c
        for c in summary["cells"]
        if c["mean"] is not None and c["half_width"] and not c["sensitive"]
    )


def test_a_mean_is_held_to_the_looser_of_the_two_tolerances():
    ref = _reference()
    cell = _finite_cell(ref)
    allowed = max(REL_TOL * abs(cell["mean"]), HALF_WIDTH_FRACTION * cell["half_width"])
    for factor, passes in ((0.99, True), (1.01, False)):
        run = copy.deepcopy(ref)
        _finite_cell(run)["mean"] = cell["mean"] + factor * allowed
        assert (compare(run, ref) == []) is passes


def test_a_sensitive_cell_is_held_as_sensitive():
    ref = _reference()
    cell = next(c for c in ref["cells"] if c["sensitive"])
    run = copy.deepcopy(ref)
    moved = next(c for c in run["cells"] if _cell_key(c) == _cell_key(cell))
    moved["mean"], moved["diverged"] = 1e9, 0  # rounding's numbers: not compared
    assert compare(run, ref) == []
    moved["sensitive"] = False
    assert any("decided by rounding in the reference only" in line for line in compare(run, ref))
    stable = next(c for c in run["cells"] if not c["sensitive"])
    stable["sensitive"] = True
    assert any("decided by rounding in the run only" in line for line in compare(run, ref))


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
