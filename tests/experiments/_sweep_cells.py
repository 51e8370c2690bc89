"""Cell functions for the sweep tests.

They live in an importable module (not in the test file) so that loky and Dask
worker processes can unpickle them by reference. Every call leaves a marker
file in ``cell["log_dir"]``, so tests count calls through the file system and
never through global state (workers are other processes).
"""

from __future__ import annotations

import os
import sys
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["count_calls", "main", "random_cell", "slow_cell", "threads_cell"]


def _mark(cell: dict[str, Any]) -> None:
    log_dir = Path(cell["log_dir"])
    log_dir.mkdir(parents=True, exist_ok=True)
    (log_dir / f"{cell['i']}.{uuid.uuid4().hex}.call").write_text(str(os.getpid()))


def count_calls(log_dir: str | os.PathLike[str]) -> dict[int, int]:
    """Return ``{cell index: number of fn calls}`` from the marker files."""
    counts: dict[int, int] = {}
    for p in Path(log_dir).glob("*.call"):
        i = int(p.name.split(".", 1)[0])
        counts[i] = counts.get(i, 0) + 1
    return counts


def random_cell(cell: dict[str, Any]) -> dict[str, Any]:
    """A row that depends on the cell's own seed only (no global RNG)."""
    _mark(cell)
    rng = np.random.default_rng(cell["seed"])
    z = rng.normal(size=50)
    return {
        "i": cell["i"],
        "seed": cell["seed"],
        "mean": float(z.mean()),
        "norm": np.float64(np.linalg.norm(z)),  # numpy scalar: converted by the sweep
        "argmax": np.int64(np.argmax(z)),
        "pair": (1, 2),  # tuple: becomes a list after the JSON round trip
    }


def slow_cell(cell: dict[str, Any]) -> dict[str, Any]:
    """Sleep ``cell["sleep"]`` seconds, then return a seeded row."""
    time.sleep(cell["sleep"])
    row = random_cell(cell)
    return row


def threads_cell(cell: dict[str, Any]) -> dict[str, Any]:
    """Report the native thread-pool sizes seen inside the worker that runs the cell."""
    import numba
    from threadpoolctl import threadpool_info

    _mark(cell)
    np.dot(np.ones((200, 200)), np.ones((200, 200)))  # make sure BLAS is loaded
    blas = [d["num_threads"] for d in threadpool_info() if d.get("user_api") == "blas"]
    return {
        "i": cell["i"],
        "pid": os.getpid(),
        "blas_threads": max(blas) if blas else -1,
        "numba_threads": int(numba.config.NUMBA_NUM_THREADS),
        "numba_env": os.environ.get("NUMBA_NUM_THREADS", ""),
    }


def main() -> None:  # pragma: no cover - run in a subprocess by the kill test
    """``python _sweep_cells.py STORE LOG N SLEEP JOBS``: run a slow sweep."""
    import _sweep_cells  # by module name, so workers import it instead of __main__

    from geoq.experiments.sweep import run_sweep

    store, log, n, sleep, jobs = sys.argv[1:6]
    cells = [
        {"i": i, "seed": 1000 + i, "sleep": float(sleep), "log_dir": log} for i in range(int(n))
    ]
    run_sweep(cells, _sweep_cells.slow_cell, store, jobs=int(jobs), progress=False)


if __name__ == "__main__":  # pragma: no cover
    main()
