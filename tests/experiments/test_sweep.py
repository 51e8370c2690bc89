"""Tests of the resumable parallel sweep runner (real processes, real kills, real Dask)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from geoq.experiments.sweep import cell_key, cell_spec, load_cell, run_sweep

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:  # worker processes inherit sys.path and import the cells by name
    sys.path.insert(0, str(HERE))

import _sweep_cells as cells_mod  # noqa: E402


def _cells(log_dir: Path, n: int, **extra: object) -> list[dict[str, object]]:
    return [{"i": i, "seed": 1000 + i, "log_dir": str(log_dir), **extra} for i in range(n)]


def _store_files(store: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(store.glob("*.json"))}


# --------------------------------------------------------------------------- keys and specs
def test_cell_key_is_stable_readable_and_distinct() -> None:
    a = {"kernel": "nearest", "max_bv": 5, "seed": 3}
    assert cell_key(a) == cell_key(dict(reversed(list(a.items()))))  # order-free
    assert cell_key(a).startswith("kernel-nearest_max_bv-5_seed-3__")
    assert cell_key(a) != cell_key({**a, "seed": 4})
    assert cell_key(a) != cell_key({**a, "max_bv": 5.0 + 1e-12})
    assert all(ch.isalnum() or ch in "._-" for ch in cell_key({"path": "/a b/c?*", "x": [1, 2]}))


def test_cell_spec_accepts_dataclasses_and_rejects_non_json() -> None:
    import dataclasses
    import enum

    import numpy as np

    @dataclasses.dataclass(frozen=True)
    class Cell:
        kernel: str
        budgets: tuple[int, ...]
        seed: int

    class Kind(enum.Enum):
        NEAREST = "nearest"

    spec = cell_spec(Cell("euclidean", (5, 10), np.int64(7)))  # type: ignore[arg-type]
    assert spec == {"kernel": "euclidean", "budgets": [5, 10], "seed": 7}
    spec = cell_spec({"kind": Kind.NEAREST, "out": Path("a/b"), "w": np.array([0.5, 1.0])})
    assert spec == {"kind": "nearest", "out": "a/b", "w": [0.5, 1.0]}
    with pytest.raises(TypeError, match="not JSON-serialisable"):
        cell_spec({"f": object()})
    with pytest.raises(TypeError, match="mapping or a dataclass"):
        cell_spec(3)


def test_bad_arguments_are_rejected(tmp_path: Path) -> None:
    cells = _cells(tmp_path / "log", 2)
    with pytest.raises(ValueError, match="backend"):
        run_sweep(cells, cells_mod.random_cell, tmp_path / "s", backend="ray", progress=False)
    with pytest.raises(ValueError, match="needs backend='dask'"):
        run_sweep(
            cells, cells_mod.random_cell, tmp_path / "s", scheduler="tcp://x:1", progress=False
        )
    with pytest.raises(ValueError, match="jobs"):
        run_sweep(cells, cells_mod.random_cell, tmp_path / "s", jobs=0, progress=False)
    with pytest.raises(ValueError, match="distinct"):
        run_sweep([cells[0], dict(cells[0])], cells_mod.random_cell, tmp_path / "s", progress=False)


# --------------------------------------------------------------------------- results
def test_serial_and_loky_give_identical_rows_in_cell_order(tmp_path: Path) -> None:
    cells = _cells(tmp_path / "log", 8)
    serial = run_sweep(cells, cells_mod.random_cell, tmp_path / "serial", jobs=1, progress=False)
    loky = run_sweep(cells, cells_mod.random_cell, tmp_path / "loky", jobs=2, progress=False)
    assert serial == loky
    assert [r["i"] for r in serial] == list(range(8))
    assert serial[0]["pair"] == [1, 2] and isinstance(serial[0]["argmax"], int)
    assert _store_files(tmp_path / "serial") == _store_files(tmp_path / "loky")
    assert len({r["mean"] for r in serial}) == 8  # seeds really differ
    # one file per cell, named by its key, holding its spec and row
    for cell, row in zip(cells, serial, strict=True):
        path = tmp_path / "serial" / f"{cell_key(cell)}.json"
        assert load_cell(path, cell_spec(cell)) == row


def test_loky_workers_have_native_threads_pinned_to_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A parent environment asking for 2 threads must not leak into the workers
    # (joblib's default would pass these values on; the sweep pins them to 1).
    for var in ("NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
        monkeypatch.setenv(var, "2")
    cells = _cells(tmp_path / "log", 4)
    rows = run_sweep(cells, cells_mod.threads_cell, tmp_path / "s", jobs=2, progress=False)
    assert {r["pid"] for r in rows}.isdisjoint({os.getpid()})  # ran in worker processes
    assert all(r["blas_threads"] == 1 for r in rows), rows
    assert all(r["numba_threads"] == 1 and r["numba_env"] == "1" for r in rows), rows


def test_resume_skips_finished_cells(tmp_path: Path) -> None:
    log = tmp_path / "log"
    cells = _cells(log, 6)
    first = run_sweep(cells[:4], cells_mod.random_cell, tmp_path / "s", jobs=2, progress=False)
    before = _store_files(tmp_path / "s")
    rows = run_sweep(cells, cells_mod.random_cell, tmp_path / "s", jobs=2, progress=False)
    assert rows[:4] == first
    assert cells_mod.count_calls(log) == {i: 1 for i in range(6)}
    after = _store_files(tmp_path / "s")
    assert all(after[name] == data for name, data in before.items())  # untouched
    again = run_sweep(cells, cells_mod.random_cell, tmp_path / "s", progress=False)
    assert again == rows
    assert cells_mod.count_calls(log) == {i: 1 for i in range(6)}


def test_corrupt_or_foreign_cell_files_are_recomputed(tmp_path: Path) -> None:
    log = tmp_path / "log"
    cells = _cells(log, 5)
    store = tmp_path / "s"
    rows = run_sweep(cells, cells_mod.random_cell, store, progress=False)
    paths = [store / f"{cell_key(c)}.json" for c in cells]
    data = paths[0].read_bytes()
    paths[0].write_bytes(data[: len(data) // 2])  # truncated
    paths[1].write_bytes(b"\x00\xff garbage")  # not JSON
    record = json.loads(paths[2].read_text())
    record["spec"]["seed"] = -1  # stores another cell's spec
    paths[2].write_text(json.dumps(record))
    paths[3].write_text(json.dumps({"format": 999, "row": {}}))  # unknown format
    again = run_sweep(cells, cells_mod.random_cell, store, progress=False)
    assert again == rows
    assert cells_mod.count_calls(log) == {0: 2, 1: 2, 2: 2, 3: 2, 4: 1}
    assert all(load_cell(p, cell_spec(c)) is not None for p, c in zip(paths, cells, strict=True))


def test_fn_error_keeps_finished_cells_and_names_the_failing_one(tmp_path: Path) -> None:
    log = tmp_path / "log"
    cells = [*_cells(log, 3), {"i": 3, "log_dir": str(log)}]  # no "seed": KeyError in fn
    with pytest.raises(KeyError) as info:
        run_sweep(cells, cells_mod.random_cell, tmp_path / "s", progress=False)
    assert any(cell_key(cells[3]) in note for note in getattr(info.value, "__notes__", []))
    assert len(_store_files(tmp_path / "s")) == 3


# --------------------------------------------------------------------------- a real kill
def test_sigkill_mid_sweep_then_resume(tmp_path: Path) -> None:
    n, sleep = 12, 0.3
    store, log = tmp_path / "store", tmp_path / "log"
    cmd = [sys.executable, str(HERE / "_sweep_cells.py"), str(store), str(log), str(n), str(sleep)]
    proc = subprocess.Popen([*cmd, "2"], start_new_session=True)  # own process group
    try:
        deadline = time.monotonic() + 60
        while len(list(store.glob("*.json"))) < 4:
            assert proc.poll() is None, "the sweep ended before it could be killed"
            assert time.monotonic() < deadline, "the sweep did not start"
            time.sleep(0.02)
    finally:  # kill the driver and its loky workers, as an OOM killer or `kill -9` would
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL

    cells = [{"i": i, "seed": 1000 + i, "sleep": sleep, "log_dir": str(log)} for i in range(n)]
    finished = _store_files(store)
    done = {i for i, c in enumerate(cells) if f"{cell_key(c)}.json" in finished}
    assert 4 <= len(done) < n, "the kill must land mid-sweep"
    for i in done:  # every file that exists is complete and valid
        path = store / f"{cell_key(cells[i])}.json"
        assert load_cell(path, cell_spec(cells[i])) is not None

    rows = run_sweep(cells, cells_mod.slow_cell, store, jobs=2, progress=False)
    calls = cells_mod.count_calls(log)
    assert all(calls[i] == 1 for i in done), "a finished cell was redone"
    assert set(calls) == set(range(n))
    after = _store_files(store)
    assert all(after[name] == data for name, data in finished.items())

    reference = run_sweep(
        [{**c, "log_dir": str(tmp_path / "ref_log")} for c in cells],
        cells_mod.random_cell,
        tmp_path / "ref",
        progress=False,
    )
    assert rows == reference  # identical to an uninterrupted run (slow_cell = sleep + random_cell)


# --------------------------------------------------------------------------- Dask
def test_dask_local_cluster_gives_identical_rows(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    cells = _cells(tmp_path / "log", 6)
    serial = run_sweep(cells, cells_mod.random_cell, tmp_path / "serial", progress=False)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        rows = run_sweep(
            cells,
            cells_mod.random_cell,
            tmp_path / "dask",
            backend="dask",
            scheduler=cluster.scheduler_address,
            progress=False,
        )
    assert rows == serial
    assert _store_files(tmp_path / "dask") == _store_files(tmp_path / "serial")


def test_dask_without_scheduler_starts_a_pinned_local_cluster(tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    cells = _cells(tmp_path / "log", 4)
    rows = run_sweep(cells, cells_mod.threads_cell, tmp_path / "s", backend="dask", progress=False)
    assert {r["pid"] for r in rows}.isdisjoint({os.getpid()})
    assert all(r["blas_threads"] == 1 and r["numba_threads"] == 1 for r in rows), rows


def test_progress_bar_counts_cells_on_stderr(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cells = _cells(tmp_path / "log", 3)
    run_sweep(cells[:1], cells_mod.random_cell, tmp_path / "s", desc="fig-test")
    run_sweep(cells, cells_mod.random_cell, tmp_path / "s", desc="fig-test")
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "fig-test" in captured.err and "3/3" in captured.err
    assert "1/3" in captured.err  # the resumed run starts from the finished cell
    run_sweep(cells, cells_mod.random_cell, tmp_path / "s", progress=False)
    assert capsys.readouterr().err == ""


def test_jobs_above_the_core_count_are_capped_with_a_warning(monkeypatch, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from geoq.experiments import sweep

    monkeypatch.setattr(sweep.os, "cpu_count", lambda: 1)
    with pytest.warns(UserWarning, match="jobs=8 is more than the 1 core"):
        assert sweep._resolve_jobs(8) == 1
    assert sweep._resolve_jobs(8, local=False) == 8  # a remote cluster decides
    assert sweep._resolve_jobs(1) == 1
