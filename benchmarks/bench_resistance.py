"""Resistance-kernel GP fit vs the squared-exponential fit, same process, same data.

The data of ``bench_graph.bench_fit`` (3 pendulum roll-outs x 250 steps, scaled
inputs, wrapped angle), ``max_bv = 200`` (issue 13's goal: resistance within 3x
of SE). Rows:

* ``as shipped``: effective resistances updated per added / removed node where
  that is cheaper than recomputing, else recomputed once at the next use
  (``geoq.kernels.graph_pd``); with the time inside the graph and ``R`` work
  (basis hooks: graph shortest paths and ``R`` updates; plus recomputations);
  the rest is the GP's own work, mostly its re-factorisation of ``K_BV`` after
  every change (``SparseOnlineGP.resync_every = 1`` for this kernel);
* ``recompute per change``: ``R`` recomputed from scratch after every change (the
  policy before issue 13, with today's from-scratch code);
* ``floor``: a lower bound on any exact resistance fit of this design, one
  Cholesky factorisation of the new ``K_BV`` per resync at the basis sizes the
  shipped fit went through (timed alone on random SPD matrices). Every point
  changes the basis set and ``exp(-R / l)`` changes in every entry when the graph
  gains or loses a node, so ``K_BV`` must be factorised afresh; the re-anchoring,
  the score refresh and the ``R`` updates all come on top.

Then the cost of one change, incremental vs from scratch, on random connected
graphs of ``s`` nodes for a new node of degree ``k``: the updates pay when ``k``
is a small fraction of ``s``. All with one BLAS thread (``geoq._threads``).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from functools import partial

import numpy as np
import scipy.linalg

from geoq._threads import one_blas_thread
from geoq.gp import NumericalWarning, SparseOnlineGP
from geoq.kernels import Kernel, ResistanceKernel, SquaredExponential
from geoq.kernels.geodesic import GraphKernel
from geoq.kernels.graph_pd import (
    ResistanceDistance,
    add_edges,
    effective_resistance,
    remove_node_resistances,
)
from geoq.learners import PENDULUM_SCALING
from geoq.policies import default_policy
from geoq.rollouts import collect_rollouts

MAX_BV = 200
STEPS = 250
GOAL_RATIO = 3.0
PERIOD = PENDULUM_SCALING.scaled_periods()


class _ScratchResistance(ResistanceDistance):
    """The pre-issue-13 behaviour: ``R`` recomputed from scratch after every change."""

    def basis_added(self, x: np.ndarray) -> None:
        super(ResistanceDistance, self).basis_added(x)

    def basis_removed(self, index: int) -> None:
        super(ResistanceDistance, self).basis_removed(index)


def _scratch_kernel() -> ResistanceKernel:
    k = ResistanceKernel(eps=0.3, lengthscale=1.0, period=PERIOD)
    k.distance = _ScratchResistance(k.graph, 1.0)
    return k


def pendulum_data(steps: int = STEPS) -> list[tuple[np.ndarray, np.ndarray]]:
    rollouts = collect_rollouts(3, steps, default_policy(), np.random.default_rng(0))
    Xs = [PENDULUM_SCALING.transform(np.column_stack([r.states, r.actions])) for r in rollouts]
    y_all = np.concatenate([r.returns for r in rollouts])
    return [
        (X, (r.returns - y_all.mean()) / y_all.std()) for X, r in zip(Xs, rollouts, strict=True)
    ]


def fit_time(
    make: Callable[[], Kernel], data: list, repeats: int, max_bv: int = MAX_BV
) -> tuple[float, SparseOnlineGP, float, list[int]]:
    """Best wall time of a streamed fit, the GP, the seconds inside the basis hooks and
    the basis size at each resync."""
    best, gp, hooks, sizes = np.inf, None, 0.0, []
    for _ in range(repeats):
        kernel = make()
        spent = [0.0]
        if isinstance(kernel, GraphKernel):
            dist = kernel.basis_distance
            for name in ("basis_added", "basis_removed", "_current"):
                hook = getattr(dist, name)

                def timed(*a, _hook=hook, _spent=spent):  # type: ignore[no-untyped-def]
                    t0 = time.perf_counter()
                    out = _hook(*a)
                    _spent[0] += time.perf_counter() - t0
                    return out

                setattr(dist, name, timed)
        gp = SparseOnlineGP(kernel, noise=0.01, max_bv=max_bv)
        resync_sizes: list[int] = []
        resync = gp._resync_q

        def counted(_gp=gp, _resync=resync, _sizes=resync_sizes):  # type: ignore[no-untyped-def,unused-ignore]
            _sizes.append(_gp.n_bv)
            _resync()

        gp._resync_q = counted  # type: ignore[method-assign,unused-ignore]
        start = time.perf_counter()
        for X, y in data:
            if isinstance(kernel, GraphKernel):
                kernel.start_rollout()
            gp.partial_fit(X, y)
        t = time.perf_counter() - start
        if t < best:
            best, hooks, sizes = t, spent[0], resync_sizes
    assert gp is not None
    return best, gp, hooks, sizes


def cholesky_floor(sizes: list[int]) -> float:
    """Seconds of one Cholesky factorisation of an ``m x m`` SPD matrix per entry of
    ``sizes`` (best of 3 per distinct ``m``, one BLAS thread)."""
    rng = np.random.default_rng(0)
    counts = np.bincount(np.asarray(sizes, dtype=np.int64))
    total = 0.0
    with one_blas_thread():
        for m in map(int, np.flatnonzero(counts)):
            A = rng.standard_normal((m, m))
            A = A @ A.T + m * np.eye(m)
            best = min(
                _seconds(partial(scipy.linalg.cholesky, A, check_finite=False), 20)
                for _ in range(3)
            )
            total += counts[m] * best
    return total


def _seconds(fn: Callable[[], object], repeats: int) -> float:
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - start) / repeats


def main(quick: bool = False) -> None:
    """``quick``: tiny sizes, figures of no meaning (``benchmarks/run.py --quick``)."""
    data = pendulum_data(40 if quick else STEPS)
    max_bv = 20 if quick else MAX_BV
    n = sum(len(y) for _, y in data)
    resistance = lambda: ResistanceKernel(eps=0.3, lengthscale=1.0, period=PERIOD)  # noqa: E731
    runs: list[tuple[str, Callable[[], Kernel], int]] = [
        ("squared exponential", lambda: SquaredExponential(0.3, period=PERIOD), 5),
        ("resistance, as shipped", resistance, 2),
        ("resistance, recompute per change", _scratch_kernel, 1),
    ]
    print(f"sparse online GP fit, {n} pendulum points, max_bv = {max_bv} (one BLAS thread):")
    t_se = None
    shipped_sizes: list[int] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        for name, make, repeats in runs:
            t, gp, hooks, sizes = fit_time(make, data, repeats, max_bv)
            t_se = t if t_se is None else t_se
            shipped_sizes = sizes if name == "resistance, as shipped" else shipped_sizes
            d = gp.diagnostics
            extra = f"  graph + R {hooks:5.2f} s" if hooks else ""
            print(
                f"  {name:33s} {t:8.3f} s  {t / t_se:6.1f}x SE  n_bv {gp.n_bv}, added "
                f"{d.n_added}, deleted {d.n_deleted}, resyncs {d.q_resyncs}{extra}"
            )
    assert t_se is not None
    floor = cholesky_floor(shipped_sizes)
    print(
        f"  {'floor: a Cholesky of K_BV per resync':33s} {floor:8.3f} s  {floor / t_se:6.1f}x SE"
        f"  ({len(shipped_sizes)} resyncs, mean m {np.mean(shipped_sizes):.0f}; nothing else)"
    )
    print(f"  goal: resistance (as shipped) <= {GOAL_RATIO:.0f}x SE")
    change_costs((40,) if quick else (200, 400), (5, 20) if quick else (5, 20, 50, 150))


def _random_graph(s: int, rng: np.random.Generator) -> np.ndarray:
    """Edge resistances [s, s] of a connected graph: a chain plus 30% of all pairs."""
    W = np.full((s, s), np.inf)
    i = np.arange(s - 1)
    W[i, i + 1] = W[i + 1, i] = rng.uniform(0.1, 1.0, s - 1)
    extra = np.triu(rng.random((s, s)) < 0.3, 1)
    W[extra] = rng.uniform(0.1, 1.2, int(extra.sum()))
    return np.minimum(W, W.T)


def _cpu_ms(fn: Callable[[], object], repeats: int = 10) -> float:
    best = np.inf
    for _ in range(3):
        start = time.process_time()
        for _ in range(repeats):
            fn()
        best = min(best, (time.process_time() - start) / repeats)
    return 1e3 * best


def change_costs(sizes: tuple[int, ...], ks: tuple[int, ...]) -> None:
    rng = np.random.default_rng(0)
    print("\none change, CPU ms (best of 3): add a node of degree k / remove one / from scratch")
    print(f"  {'s':>4}  " + "  ".join(f"{'k=' + str(k):>15}" for k in ks) + f"  {'scratch':>8}")
    with one_blas_thread():
        for s in sizes:
            W = _random_graph(s, rng)
            cells = []
            for k in ks:  # node 0 gets exactly k edges (the chain keeps the rest connected)
                q = rng.choice(np.arange(1, s), k, replace=False)
                w = rng.uniform(0.1, 1.2, k)
                Wk = W.copy()
                Wk[0, :] = Wk[:, 0] = np.inf
                Wk[0, q] = Wk[q, 0] = w
                R = effective_resistance(Wk)
                assert remove_node_resistances(R, 0, q, w) is not None
                t_add = _cpu_ms(lambda q=q, w=w, R=R: add_edges(R, 0, q, w))
                t_rm = _cpu_ms(lambda q=q, w=w, R=R: remove_node_resistances(R, 0, q, w))
                cells.append(f"{t_add:6.2f} / {t_rm:6.2f}")
            t_full = _cpu_ms(lambda W=W: effective_resistance(W))
            print(f"  {s:>4}  " + "  ".join(f"{c:>15}" for c in cells) + f"  {t_full:8.2f}")


if __name__ == "__main__":
    main()
