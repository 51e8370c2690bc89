"""Kernel settings: one machine standing in for machines of other kinds.

The last bits of a result depend on which kernels run: the SIMD code NumPy dispatches to
(``exp`` differs between its AVX-512 and libm paths), OpenBLAS's kernels for the CPU it
detects, the CPU numba compiles for, and the variant of each libm function glibc picks
(its FMA variants of ``exp``, ``log``, ``sin``, ``pow`` round differently from the SSE2
ones: measured, 5 million arguments each). Each can be forced *down* by environment
variables read when the process starts, so a check in a subprocess sees what an older
CPU would compute:

* ``native``: whatever this machine picks;
* ``avx2``: a Haswell (no AVX-512);
* ``sse``: a Nehalem (x86-64-v2: no AVX, no FMA), glibc's libm included.

:func:`portable` is ``sse`` with one BLAS thread: the common baseline of every x86-64 CPU
NumPy supports, so numbers computed under it are the same bits on any of them. The
pinned runs (``tests/agents/test_pinned.py``) are recorded and checked there.

``python -m tests._kernels [PYTEST ARGS]`` (``make test-kernels``) runs the tests that
compare numbers with recorded ones (marker ``numbers``) under each setting and says which
failed where; with arguments, those tests instead.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: glibc's ifunc choice of libm variants, without FMA and AVX2 (the SSE2 ones).
_GLIBC_SSE2 = "glibc.cpu.hwcaps=-AVX2,-FMA"

SETTINGS: dict[str, dict[str, str]] = {
    "native": {},
    "avx2": {
        "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
        "OPENBLAS_CORETYPE": "Haswell",
        "NUMBA_CPU_NAME": "haswell",
    },
    "sse": {
        "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
        "OPENBLAS_CORETYPE": "Nehalem",
        "NUMBA_CPU_NAME": "nehalem",
        "GLIBC_TUNABLES": _GLIBC_SSE2,
    },
}

#: Set in a process started under :func:`portable` (so a recorder can tell where it runs).
PORTABLE_FLAG = "GEOQ_PORTABLE_NUMERICS"


def environ(setting: str, base: dict[str, str] | None = None) -> dict[str, str]:
    """The environment of a process under ``setting`` (``base``: ``os.environ``)."""
    env = dict(os.environ if base is None else base)
    for key, value in SETTINGS[setting].items():
        if key == "GLIBC_TUNABLES" and env.get(key):
            value = f"{env[key]}:{value}"
        env[key] = value
    return env


def portable() -> dict[str, str]:
    """The environment of a process whose numbers are the same bits on any x86-64 CPU."""
    env = environ("sse")
    env.update(
        {
            "OPENBLAS_NUM_THREADS": "1",
            "OMP_NUM_THREADS": "1",
            "NUMBA_NUM_THREADS": "1",
            PORTABLE_FLAG: "1",
            "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")])),
        }
    )
    return env


def supports_portable() -> bool:
    """Whether :func:`portable` can be honoured here (an x86-64 CPU)."""
    return platform.machine().lower() in ("x86_64", "amd64")


def in_effect() -> dict[str, str]:
    """What this process runs on, read back from the libraries themselves: NumPy's
    dispatched targets, OpenBLAS's kernels and numba's target CPU."""
    import numba
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    from threadpoolctl import threadpool_info

    blas = sorted(
        {str(i.get("architecture")) for i in threadpool_info() if i["user_api"] == "blas"}
    )
    return {
        "numpy": ",".join(f for f in __cpu_dispatch__ if __cpu_features__.get(f)) or "baseline",
        "openblas": ",".join(blas),
        "numba": str(numba.config.CPU_NAME or "host"),
    }


def main(argv: list[str]) -> int:
    args = argv or ["-m", "numbers"]
    failed = []
    for name in SETTINGS:
        print(f"== {name}: {' '.join(f'{k}={v}' for k, v in SETTINGS[name].items()) or '-'}")
        code = subprocess.call(
            [sys.executable, "-m", "pytest", "-q", "-n", "auto", "-p", "no:cacheprovider", *args],
            cwd=ROOT,
            env=environ(name),
        )
        if code != 0:
            failed.append(f"{name} (exit {code})")
    verdict = f"failed under: {', '.join(failed)}" if failed else "passed under every setting"
    print(f"== {verdict}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
