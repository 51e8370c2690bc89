"""The speed benchmarks still run: ``benchmarks/run.py --quick`` (tiny sizes, seconds).

The benchmarks' figures live in docs/results.md and the issue notes; a benchmark that
no longer runs (a helper's signature changed under it) would go unnoticed until
someone needs its numbers. This runs every one of them end to end, on sizes too
small for the figures to mean anything.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.skipif(not BENCHMARKS.is_dir(), reason="benchmarks/ not shipped here")
def test_every_benchmark_runs_quick() -> None:
    names = sorted(p.stem for p in BENCHMARKS.glob("bench_*.py"))
    assert names, "no benchmarks found"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / "run.py"), "--quick"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    for name in names:
        assert f"=== {name} ===" in done.stdout and f"({name} took" in done.stdout, name
