"""End to end: the reproduction at a tiny scale writes every file, deterministically, resumably."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from _tiny import TINY
from matplotlib.figure import Figure

from geoq.experiments.paper.fig3 import FIG3_COLUMNS
from geoq.experiments.paper.reproduce import reproduce


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("repro")
    reproduce(out, config=TINY, progress=False)
    return out


def _read(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_every_file_is_written(run_dir):
    for name in (
        "fig1.png",
        "fig1.csv",
        "fig1_eps.csv",
        "fig2.png",
        "fig2.csv",
        "fig3.png",
        "fig3_td.png",
        "fig3_refit.png",
        "fig3_all.csv",
        "fig3.csv",
        "tuning.csv",
        "config.json",
        "REPORT.md",
    ):
        assert (run_dir / name).stat().st_size > 0, name
    rows = _read(run_dir / "fig3.csv")
    assert list(rows[0]) == list(FIG3_COLUMNS)
    assert len(rows) == 3 * 2 * 2
    every = _read(run_dir / "fig3_all.csv")
    assert {r["kernel"] for r in every} == {"euclidean", "nearest", "interpolated", "resistance"}
    assert [r for r in every if r["kernel"] != "resistance"] == rows
    assert {r["kernel"] for r in rows} == {"euclidean", "nearest", "interpolated"}  # paper only
    for r in rows:
        assert float(r["mse"]) >= 0 and 0 <= float(r["normalized_variance"]) <= 1 + 1e-9
        assert int(r["n_bv"]) <= int(r["max_bv"])
    config = json.loads((run_dir / "config.json").read_text())
    assert config["config"]["seeds"] == 2 and "geoq_version" in config
    report = (run_dir / "REPORT.md").read_text()
    assert "## The paper's claims" in report and "nearest" in report
    assert "### Edges versus eps" in report
    variants = _read(run_dir / "fig3_variants.csv")
    assert {(r["variant"], r["kernel"]) for r in variants} == {
        (v, k) for v in ("faithful", "pd_novelty") for k in ("nearest", "interpolated")
    }
    assert len(variants) == (2 + 1) * 2 * 2  # (faithful's budgets + pd_novelty's) x kernels x seeds
    assert {int(r["max_bv"]) for r in variants if r["variant"] == "pd_novelty"} == {15}
    assert {int(r["max_bv"]) for r in every if r["kernel"] == "resistance"} == {15}
    # The per-roll-out refit learner: the paper's kernels only.
    assert all((r["mse_refit_episode"] == "") == (r["kernel"] == "resistance") for r in every)
    assert "(the learners beyond the paper: [15])" in report
    for r in variants:
        assert int(r["n_bv"]) <= int(r["max_bv"]) and float(r["mse_refit"]) >= 0
    assert "### Do the paper's claims change?" in report
    edges = _read(run_dir / "fig1_eps.csv")
    assert {r["mode"] for r in edges} == {"same nodes", "rebuilt"}
    assert len(edges) == (len(TINY.graph_eps) + 1) * len(TINY.edge_count_eps)


def test_rerun_resumes_and_gives_identical_files(run_dir, tmp_path):
    before = {p.name: p.read_bytes() for p in run_dir.glob("*.csv")}
    stamps = {p: p.stat().st_mtime_ns for p in (run_dir / "cells").rglob("*.json")}
    reproduce(run_dir, config=TINY, progress=False)
    assert {p: p.stat().st_mtime_ns for p in (run_dir / "cells").rglob("*.json")} == stamps
    assert {p.name: p.read_bytes() for p in run_dir.glob("*.csv")} == before
    # and a fresh directory gives the same numbers (same seed, same numbers)
    reproduce(tmp_path, config=TINY, progress=False)
    assert (tmp_path / "fig3.csv").read_bytes() == before["fig3.csv"]


def test_a_copied_results_folder_resumes_without_recomputing(run_dir, tmp_path, monkeypatch):
    """Cell keys hold no absolute path: a moved or copied folder keeps its finished cells."""
    import shutil

    import geoq.experiments.paper.reproduce as repro

    moved = tmp_path / "elsewhere" / "copy"
    shutil.copytree(run_dir, moved)
    for path in (moved / "cells").rglob("*.json"):
        assert str(run_dir) not in path.name
        assert str(run_dir) not in json.dumps(json.loads(path.read_text())["spec"])

    def must_not_run(cell):
        raise AssertionError(f"recomputed {cell}")

    monkeypatch.setattr(repro, "truth_cell", must_not_run)
    monkeypatch.setattr(repro, "budget_cell", must_not_run)
    monkeypatch.setattr(repro, "tune", must_not_run)
    reproduce(moved, config=TINY, progress=False)
    for name in ("fig3.csv", "fig3_all.csv", "fig3_variants.csv", "tuning.csv"):
        assert (moved / name).read_bytes() == (run_dir / name).read_bytes(), name


def test_plotting_functions_return_figures():
    from geoq.experiments.paper.fig1 import GraphSnapshot
    from geoq.experiments.paper.fig2 import ValueMaps
    from geoq.experiments.paper.plotting import plot_budget_curves, plot_graphs, plot_value_maps

    snap = GraphSnapshot(
        0.3,
        np.zeros((3, 3)) + np.arange(3)[:, None],
        np.array([[0, 1]]),
        {"n_nodes": 3, "n_edges": 1, "mean_degree": 2 / 3, "n_components": 2, "isolated_nodes": 1},
    )
    fig = plot_graphs([snap, snap])
    assert isinstance(fig, Figure) and len(fig.axes) == 3  # two panels and a colour bar
    grid = np.linspace(-1, 1, 4)
    maps = ValueMaps(
        grid,
        grid,
        {"monte_carlo": np.eye(4), "nearest": np.ones((4, 4))},
        {"monte_carlo": np.zeros((4, 4)), "nearest": np.zeros((4, 4))},
    )
    assert len(plot_value_maps(maps).axes) == 3
    rows = [
        {
            "kernel": k,
            "max_bv": b,
            "seed": s,
            "mse": 1.0 + s,
            "mse_td": 2.0,
            "normalized_variance": 0.5,
        }
        for k in ("euclidean", "nearest")
        for b in (5, 10)
        for s in (0, 1)
    ]
    fig3 = plot_budget_curves(rows)
    assert [ax.get_xlabel() for ax in fig3.axes] == ["max number of basis vectors"] * 2
    assert len(fig3.axes[0].lines) == 2


def test_worker_processes_do_not_change_the_results(run_dir, tmp_path):
    """Two workers (the validation grid of the tuning and the cells) give the same files."""
    reproduce(tmp_path, config=TINY, progress=False, jobs=2)
    for name in ("tuning.csv", "fig3.csv", "fig1.csv", "fig2.csv"):
        assert (tmp_path / name).read_bytes() == (run_dir / name).read_bytes(), name


def test_long_cells_start_first_and_every_cell_is_kept():
    """Issue 31: the re-anchoring learners' cells are dispatched first, largest budget first;
    the rest keep their order (the rows are sorted afterwards, so the files do not change:
    ``test_worker_processes_do_not_change_the_results``)."""
    from geoq.experiments.paper.fig3 import BudgetCell, longest_first

    def cell(kernel: str, max_bv: int, pd: bool = False, seed: int = 0) -> BudgetCell:
        return BudgetCell(
            kernel=kernel, max_bv=max_bv, seed=seed, root_seed=0, train_rollouts=1,
            train_steps=1, learner={"pd_novelty": pd}, truth_dir="", truth={},
            variant="pd_novelty" if pd else "tuned",
        )  # fmt: skip

    cells = [
        cell("euclidean", 200), cell("resistance", 10), cell("nearest", 5),
        cell("resistance", 200, seed=1), cell("nearest", 100, pd=True), cell("resistance", 200),
    ]  # fmt: skip
    got = longest_first(cells)
    assert [(c.kernel, c.max_bv, c.seed) for c in got] == [
        ("resistance", 200, 1), ("resistance", 200, 0), ("nearest", 100, 0),
        ("resistance", 10, 0), ("euclidean", 200, 0), ("nearest", 5, 0),
    ]  # fmt: skip
    assert sorted(map(repr, got)) == sorted(map(repr, cells))
