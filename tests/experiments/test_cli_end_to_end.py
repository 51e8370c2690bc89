"""``geoq reproduce`` end to end through the CLI at a tiny scale, on loky and on Dask."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from _tiny import TINY
from typer.testing import CliRunner

from geoq.cli import app
from geoq.experiments.paper.config import VARIANT_KERNELS
from geoq.experiments.paper.fig3 import FIG3_COLUMNS

runner = CliRunner()


@pytest.fixture(scope="module")
def tiny_json(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("cfg") / "tiny.json"
    path.write_text(json.dumps(TINY.as_dict()))
    return path


def _run(out: Path, config: Path, *extra: str) -> None:
    result = runner.invoke(
        app, ["reproduce", "--out", str(out), "--config", str(config), "--no-progress", *extra]
    )
    assert result.exit_code == 0, result.output


def test_cli_writes_every_file_with_the_promised_columns(tmp_path: Path, tiny_json: Path) -> None:
    _run(tmp_path, tiny_json)
    for name in ("fig1.png", "fig2.png", "fig3.png", "fig3.csv", "config.json", "REPORT.md"):
        assert (tmp_path / name).stat().st_size > 0, name
    with open(tmp_path / "fig3.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == list(FIG3_COLUMNS)
    assert {"kernel", "max_bv", "seed", "mse", "normalized_variance", "n_bv"} <= set(rows[0])
    assert {r["kernel"] for r in rows} == {"euclidean", "nearest", "interpolated"}
    assert len(rows) == 3 * TINY.seeds * len(TINY.budgets)
    recorded = json.loads((tmp_path / "config.json").read_text())
    assert recorded["config"]["budgets"] == list(TINY.budgets)


def test_dask_local_cluster_gives_the_same_csv_as_loky(tmp_path: Path, tiny_json: Path) -> None:
    pytest.importorskip("distributed")
    _run(tmp_path / "loky", tiny_json, "--jobs", "2")
    _run(tmp_path / "dask", tiny_json, "--backend", "dask", "--jobs", "2")
    for name in ("fig3.csv", "fig1.csv", "tuning.csv"):
        assert (tmp_path / "dask" / name).read_bytes() == (tmp_path / "loky" / name).read_bytes()


def test_bad_config_is_a_usage_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"seedz": 3}))
    result = runner.invoke(app, ["reproduce", "--out", str(tmp_path / "o"), "--config", str(bad)])
    assert result.exit_code == 2
    assert "seedz" in result.output
    bad.write_text(json.dumps({"seeds": 0}))
    result = runner.invoke(app, ["reproduce", "--out", str(tmp_path / "o"), "--config", str(bad)])
    assert result.exit_code == 2 and "seeds" in result.output


def test_killed_run_resumes_to_identical_files(tmp_path: Path, tiny_json: Path) -> None:
    """``kill -9`` of ``geoq reproduce`` mid-sweep, rerun: same CSVs as an uninterrupted run."""
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "geoq.cli", "reproduce", "--out", str(out)]
    cmd += ["--config", str(tiny_json), "--no-progress", "--jobs", "1"]
    proc = subprocess.Popen(cmd, start_new_session=True, stderr=subprocess.DEVNULL)
    cells = out / "cells" / "fig3"
    try:
        deadline = time.monotonic() + 120
        while len(list(cells.glob("*.json"))) < 3:
            assert proc.poll() is None, "the run ended before it could be killed"
            assert time.monotonic() < deadline, "the Fig. 3 sweep did not start"
            time.sleep(0.01)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    finished = {p.name: p.read_bytes() for p in cells.glob("*.json")}
    per_seed = sum(len(TINY.budgets_of(k)) for k in TINY.kernels) + sum(
        len(TINY.budgets_of(k, v)) for v in TINY.variants for k in VARIANT_KERNELS
    )
    n_cells = per_seed * (TINY.seeds + min(TINY.probe_seeds, TINY.seeds))  # rounding probes
    assert 3 <= len(finished) < n_cells, "the kill must land mid-sweep"
    assert not (out / "fig3.csv").exists()

    _run(out, tiny_json)
    assert {p.name: p.read_bytes() for p in cells.glob("*.json") if p.name in finished} == finished
    assert len(list(cells.glob("*.json"))) == n_cells
    _run(tmp_path / "clean", tiny_json)
    for name in (
        "fig3.csv", "fig3_all.csv", "fig3_variants.csv", "fig1.csv", "fig1_eps.csv", "fig2.csv",
        "tuning.csv",
    ):  # fmt: skip
        assert (out / name).read_bytes() == (tmp_path / "clean" / name).read_bytes(), name
