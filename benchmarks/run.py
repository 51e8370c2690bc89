"""Run every speed benchmark: ``make bench`` (or ``python benchmarks/run.py [--quick] [NAME ...]``).

Each ``benchmarks/bench_*.py`` module has a ``main(quick=False)`` that prints its
own table, with ratios against a baseline measured in the same process.
``--quick`` runs every benchmark on tiny sizes, in seconds: its figures mean
nothing, it checks that the benchmarks still run (``tests/test_benchmarks.py``).
"""

from __future__ import annotations

import importlib.util
import platform
import sys
import time
from pathlib import Path

import numpy as np

import geoq


def _load(path: Path):  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main(argv: list[str]) -> int:
    here = Path(__file__).resolve().parent
    quick = "--quick" in argv
    wanted = {a for a in argv if a != "--quick"}
    print(f"geoq {geoq.__version__}  python {platform.python_version()}  numpy {np.__version__}")
    print(f"machine: {platform.machine()}  cpus: {__import__('os').cpu_count()}\n")
    for path in sorted(here.glob("bench_*.py")):
        if wanted and path.stem not in wanted and path.stem.removeprefix("bench_") not in wanted:
            continue
        print(f"=== {path.stem} ===")
        start = time.perf_counter()
        _load(path).main(quick=quick)
        print(f"({path.stem} took {time.perf_counter() - start:.1f} s)\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
