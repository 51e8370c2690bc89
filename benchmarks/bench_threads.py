"""The BLAS threading policy (``geoq._threads``): fits do not depend on the caller's threads.

1. The cost of entering and leaving the one-thread block, against
   ``threadpoolctl.threadpool_limits(1)`` (which scans the loaded libraries every
   time), and of a nested entry.
2. The same fits in two fresh processes, one with ``OPENBLAS_NUM_THREADS`` unset
   (OpenBLAS's default: one thread per core) and one with it set to 1; goal
   (issue 13): no fit more than 10% slower with the default than with one
   thread. The fits: squared exponential and resistance kernel on the pendulum
   data of ``bench_resistance`` (SE at ``max_bv = 200``, resistance at
   ``max_bv = 100`` to keep this short), a DTC refit of the resistance GP, and
   predictions of the SE GP on 10 and 750 points (small batches: one thread).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

GOAL = 1.10
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def _per_call_us(fn, n: int = 2000) -> float:  # type: ignore[no-untyped-def]
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - start) / n)
    return 1e6 * best


def entry_costs(calls: int = 200) -> None:
    from threadpoolctl import threadpool_limits

    from geoq._threads import blas_controllers, one_blas_thread

    def limits() -> None:
        with threadpool_limits(1):
            pass

    def ours() -> None:
        with one_blas_thread():
            pass

    blas_controllers()  # found once
    t_tp = _per_call_us(limits, calls)
    t_ours = _per_call_us(ours, 10 * calls)
    with one_blas_thread():
        t_nested = _per_call_us(ours, 10 * calls)
    n_libs = len(blas_controllers())
    print(f"enter + leave one BLAS thread ({n_libs} BLAS libraries loaded):")
    print(f"  threadpoolctl.threadpool_limits(1)  {t_tp:8.1f} us")
    ratio = t_tp / t_ours
    print(f"  geoq._threads.one_blas_thread()     {t_ours:8.1f} us   ({ratio:.0f}x cheaper)")
    print(f"  ... nested inside another           {t_nested:8.1f} us")


def child(quick: bool = False) -> None:
    """Run in a fresh process: time the fits, print JSON."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_resistance import PERIOD, STEPS, fit_time, pendulum_data
    from geoq.gp import NumericalWarning
    from geoq.kernels import ResistanceKernel, SquaredExponential

    data = pendulum_data(40 if quick else STEPS)
    out: dict[str, float] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        t, se_gp, _, _ = fit_time(lambda: SquaredExponential(0.3, period=PERIOD), data, 5)
        out["SE fit, max_bv 200"] = t
        Xq = np.vstack([X for X, _ in data])
        for n, calls in ((10, 200), (len(Xq), 10)):
            best = np.inf
            for _ in range(5):
                start = time.perf_counter()
                for _ in range(calls):
                    se_gp.predict(Xq[:n], return_std=True)
                best = min(best, (time.perf_counter() - start) / calls)
            out[f"SE predict {n} points"] = best
        t, gp, _, _ = fit_time(
            lambda: ResistanceKernel(eps=0.3, lengthscale=1.0, period=PERIOD), data[:1], 1
        )
        out[f"resistance fit, {len(data[0][1])} points"] = t
        X = np.vstack([X for X, _ in data])
        y = np.concatenate([y for _, y in data])
        refit = np.inf
        for _ in range(5):
            start = time.perf_counter()
            gp.refit(X, y)
            refit = min(refit, time.perf_counter() - start)
        out["resistance DTC refit"] = refit
    print(json.dumps(out))


def _run(env_threads: str | None, quick: bool) -> dict[str, float]:
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    if env_threads is not None:
        env["OPENBLAS_NUM_THREADS"] = env_threads
    done = subprocess.run(
        [sys.executable, __file__, "--child", *(["--quick"] if quick else [])],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def main(quick: bool = False) -> None:
    """``quick``: tiny sizes, figures of no meaning (``benchmarks/run.py --quick``)."""
    entry_costs(5 if quick else 200)
    best: dict[str | None, dict[str, float]] = {None: {}, "1": {}}
    for _ in range(1 if quick else 3):  # alternate, keep the best of each
        for threads in (None, "1"):
            for name, t in _run(threads, quick).items():
                best[threads][name] = min(best[threads].get(name, np.inf), t)
    print(f"\nfresh processes, best of {1 if quick else 3} (cpus: {os.cpu_count()}), ms:")
    print(f"  {'':30s} {'unset':>9s} {'=1':>9s} {'ratio':>7s}")
    for name, t_default in best[None].items():
        t_one = best["1"][name]
        ok = "ok" if t_default <= GOAL * t_one else "MISSED"
        ratio = t_default / t_one
        print(f"  {name:30s} {1e3 * t_default:9.2f} {1e3 * t_one:9.2f} {ratio:6.2f}x {ok}")
    print(f"  goal: OPENBLAS_NUM_THREADS unset within {GOAL - 1:.0%} of =1")


if __name__ == "__main__":
    if "--child" in sys.argv:
        child(quick="--quick" in sys.argv)
    else:
        main()
