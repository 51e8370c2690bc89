"""``geoq suite`` end to end at a tiny scale: files, resume, and bad task input."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

import geoq.experiments.suite.run as suite_mod
from geoq.cli import app
from geoq.experiments.suite.run import SUITE_COLUMNS, SUITE_SCALES, SuiteConfig, run_suite

TINY = SuiteConfig(
    scale="tiny",
    seeds=2,
    budgets=(5, 10),
    eval_pairs=20,
    eval_rollouts=2,
    mc_rollouts=4,
    tune_pairs=15,
    tune_mc_rollouts=3,
    tune_max_bv=10,
    map_grid=6,
    map_mc_rollouts=2,
    map_max_bv=10,
)
TASKS = ["geoq/TwoRooms-v0"]  # the other tasks: tests/tasks (a second one doubles the time)
RUNNER = CliRunner()


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("suite")
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(SUITE_SCALES, "quick", TINY)
        args = ["suite", "--out", str(out), "--no-progress", "--jobs", "1"]
        result = RUNNER.invoke(app, [*args, "--tasks", TASKS[0]])
    assert result.exit_code == 0, result.output
    assert "SUITE.md" in result.output
    return out


def test_suite_writes_every_file(finished: Path) -> None:
    for name in ("SUITE.md", "suite.csv", "config.json"):
        assert (finished / name).is_file()
    for slug in ("geoq_TwoRooms-v0",):
        for name in ("fig3.csv", "fig3.png", "fig3_refit.png", "tuning.csv", "value_map.csv"):
            assert (finished / slug / name).is_file(), (slug, name)
        assert (finished / slug / "value_map.png").stat().st_size > 1000
    rows = _rows(finished / "suite.csv")
    assert list(rows[0]) == list(SUITE_COLUMNS)
    # 4 kernels x 2 budgets x 2 seeds, every MSE a number
    assert len(rows) == 4 * 2 * 2
    assert {r["kernel"] for r in rows} == {"euclidean", "nearest", "interpolated", "resistance"}
    assert all(float(r["mse_refit"]) >= 0 for r in rows)
    report = (finished / "SUITE.md").read_text()
    first = report.split("## Every kernel")[0]
    assert "Does a graph kernel beat the squared exponential?" in first
    for task in TASKS:
        assert f"| {task} | 5 |" in first and f"| {task} | 10 |" in first
    value_map = _rows(finished / "geoq_TwoRooms-v0" / "value_map.csv")
    assert {r["map"] for r in value_map} >= {"monte_carlo", "euclidean", "nearest"}


def test_the_value_map_shows_the_wall(finished: Path) -> None:
    truth = {
        (float(r["x"]), float(r["y"])): float(r["value"])
        for r in _rows(finished / "geoq_TwoRooms-v0" / "value_map.csv")
        if r["map"] == "monte_carlo"
    }
    xs = sorted({x for x, _ in truth})
    left = max(x for x in xs if x < 0.5)
    right = min(x for x in xs if x > 0.5)
    low_y = min(y for _, y in truth)
    # Neighbours across the wall at low y: far apart along the dynamics.
    assert truth[(right, low_y)] - truth[(left, low_y)] > 5.0


def test_rerun_resumes_without_recomputing(finished: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    before = (finished / "suite.csv").read_text()

    def boom(cell: Any) -> dict[str, Any]:
        raise AssertionError(f"recomputed {cell}")

    for name in ("tune_cell", "truth_cell", "budget_cell", "map_cell"):
        monkeypatch.setattr(suite_mod, name, boom)
    run_suite(finished, TASKS, config=TINY, progress=False)
    assert (finished / "suite.csv").read_text() == before


def test_bad_tasks_are_usage_errors(tmp_path: Path) -> None:
    for task, message in (("NoSuchTask-v0", "unknown task"), ("CartPole-v1", "Discrete")):
        result = RUNNER.invoke(app, ["suite", "--out", str(tmp_path / "x"), "--tasks", task])
        assert result.exit_code == 2, result.output
        assert message in result.output
    with pytest.raises(ValueError, match="unknown task"):
        run_suite(tmp_path / "y", ["NoSuchTask-v0"], config=TINY)
    assert not (tmp_path / "y").exists()  # refused before any work
