"""Sparse online GP speed: streaming updates with a full budget, and prediction.

Every streamed point is novel (length-scale 0.05 in a 200 x 200 box), so past the
budget each update is an addition *and* a KL-optimal deletion: the worst case.
Goals (issue 2): >= 100k points/s at max_bv=50, >= 15k points/s at max_bv=200,
<= 1 ms/point at max_bv=1000; predicting 1e5 points with std at 200 BVs well
under 1 s. Baselines measured in the same process: the plain-numpy reference
step of ``tests/gp/reference.py`` and scikit-learn's exact GP refitted per point.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

from geoq.gp import SparseOnlineGP
from geoq.kernels import SquaredExponential

LENGTHSCALE = 0.05
NOISE = 0.01
BUDGETS = {50: 200_000, 200: 40_000, 1000: 3_000}  # max_bv -> streamed points
REFERENCE_POINTS = {50: 2_000, 200: 500, 1000: 30}
GOALS = {50: 100_000.0, 200: 15_000.0, 1000: 1_000.0}  # points/s
SKLEARN_POINTS = 200
N_PREDICT = 100_000


def _reference_cls():  # type: ignore[no-untyped-def]
    path = Path(__file__).resolve().parents[1] / "tests" / "gp" / "reference.py"
    spec = importlib.util.spec_from_file_location("_gp_reference", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses need the module registered
    spec.loader.exec_module(module)
    return module.ReferenceOnlineGP


def _stream(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    return rng.uniform(-100, 100, (n, 2)), rng.normal(size=n)


def _best_of(fn, repeats: int = 3) -> float:  # type: ignore[no-untyped-def]
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return float(best)


def _compiled_rate(max_bv: int, n: int, rng: np.random.Generator) -> tuple[float, int]:
    kern = SquaredExponential(LENGTHSCALE)
    Xf, yf = _stream(max_bv, rng)
    X, y = _stream(n, rng)
    gp = SparseOnlineGP(kern, noise=NOISE, max_bv=max_bv, tol=1e-6)

    def run() -> None:
        gp.fit(Xf, yf)  # fill the budget (not timed separately: cheap next to n points)
        gp.partial_fit(X, y)

    seconds = _best_of(run, repeats=2 if max_bv >= 1000 else 3)
    d = gp.diagnostics
    assert d.n_deleted >= n, "benchmark stream must delete a BV at every point"
    return (n + max_bv) / seconds, d.n_deleted


def _reference_rate(max_bv: int, n: int, rng: np.random.Generator) -> float:
    ReferenceOnlineGP = _reference_cls()
    kern = SquaredExponential(LENGTHSCALE)
    ref = ReferenceOnlineGP(kern=kern, kxx=1.0, noise=NOISE, max_bv=max_bv, tol=1e-6, dim=2)
    Xf, yf = _stream(max_bv, rng)
    for x, t in zip(Xf, yf, strict=True):
        ref.update(x, t)
    X, y = _stream(n, rng)
    start = time.perf_counter()
    for x, t in zip(X, y, strict=True):
        ref.update(x, t)
    return n / (time.perf_counter() - start)


def _sklearn_rate(n: int, rng: np.random.Generator) -> float | None:
    try:
        from sklearn.gaussian_process import GaussianProcessRegressor
        from sklearn.gaussian_process.kernels import RBF
    except ImportError:  # pragma: no cover - optional baseline
        return None
    X, y = _stream(n, rng)
    gpr = GaussianProcessRegressor(RBF(LENGTHSCALE), alpha=NOISE, optimizer=None)
    start = time.perf_counter()
    for t in range(1, n + 1):  # the exact GP has no update: refit on all points so far
        gpr.fit(X[:t], y[:t])
    return n / (time.perf_counter() - start)


def _predict_seconds(rng: np.random.Generator, n_predict: int = N_PREDICT) -> float:
    kern = SquaredExponential(0.3)
    X = rng.uniform(-1, 1, (5_000, 2))
    gp = SparseOnlineGP(kern, noise=1e-3, max_bv=200, tol=1e-6).fit(X, np.sin(3 * X[:, 0]))
    assert gp.n_bv == 200
    Xs = rng.uniform(-1, 1, (n_predict, 2))
    return _best_of(lambda: gp.predict(Xs, return_std=True))


def main(quick: bool = False) -> None:
    """``quick``: tiny sizes, figures of no meaning (``benchmarks/run.py --quick``)."""
    rng = np.random.default_rng(0)
    budgets, reference = BUDGETS, REFERENCE_POINTS
    sklearn_points, n_predict = SKLEARN_POINTS, N_PREDICT
    if quick:
        budgets, reference, sklearn_points, n_predict = {20: 100}, {20: 20}, 10, 1_000
    start = time.perf_counter()
    _compiled_rate(10, 200, rng)  # warm up numba (compiles or loads the on-disk cache)
    print(f"numba warm-up {time.perf_counter() - start:.2f} s")
    print(
        f"Streaming updates, every point novel (SE length-scale {LENGTHSCALE}): "
        "add + KL deletion per point"
    )
    print(
        f"  {'max_bv':>6}  {'compiled pts/s':>14}  {'us/pt':>8}  {'goal pts/s':>10}  "
        f"{'numpy ref pts/s':>15}  {'speed-up':>8}"
    )
    rates: dict[int, float] = {}
    for max_bv, n in budgets.items():
        rate, _ = _compiled_rate(max_bv, n, rng)
        ref = _reference_rate(max_bv, reference[max_bv], rng)
        rates[max_bv] = rate
        goal = GOALS.get(max_bv, np.nan)
        ok = "-" if np.isnan(goal) else "ok" if rate >= goal else "MISSED"
        print(
            f"  {max_bv:>6}  {rate:>14,.0f}  {1e6 / rate:>8.1f}  {goal:>10,.0f} {ok:<6}"
            f"  {ref:>9,.0f}  {rate / ref:>7.0f}x"
        )
    sk = _sklearn_rate(sklearn_points, rng)
    if sk is not None:
        m = max(b for b in rates if b <= 200)
        print(
            f"  scikit-learn GaussianProcessRegressor, refit per point ({sklearn_points} points, "
            f"optimizer=None): {sk:,.0f} pts/s; compiled at max_bv={m} is "
            f"{rates[m] / sk:,.0f}x faster"
        )
    seconds = _predict_seconds(rng, n_predict)
    ok = "ok" if seconds < 1.0 else "MISSED"
    print(
        f"\nPredict {n_predict:,} points with std at 200 BVs: {seconds:.3f} s  "
        f"(goal well under 1 s: {ok})"
    )


if __name__ == "__main__":
    main()
