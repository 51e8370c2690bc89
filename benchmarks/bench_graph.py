"""MDP-graph speed: incremental shortest paths vs scipy, and the geodesic-GP fit vs SE.

Goals (issue 3), measured on graphs built from pendulum trajectories (inputs
scaled by ``PENDULUM_SCALING``; nodes thinned to a minimum spacing, as the
GP's novelty rule spaces its basis vectors):

* adding a node at n = 1000: <= 0.5 ms, >= 400x faster than recomputing all
  shortest paths with ``scipy.sparse.csgraph.dijkstra`` from scratch;
* deleting a node: no slower than recomputing, with scipy, only the sources
  whose shortest paths went through it (the baseline times the Dijkstra call
  alone, on a prebuilt graph);
* a full geodesic-GP fit of 750 trajectory points at ``max_bv = 100``: within
  3x of the squared-exponential fit (same budget, budget binding).

Two graph regimes: ``sparse`` (eps = 0.9 plus temporal edges, which connect
it) and ``dense`` (eps = 0.5, connected by JC12 eq. 2 alone). BLAS runs on one
thread (if threadpoolctl is installed) so timings do not depend on contention.
"""

from __future__ import annotations

import contextlib
import time
import warnings
from collections.abc import Callable

import numpy as np
from scipy.sparse.csgraph import connected_components, dijkstra

from geoq.gp import SparseOnlineGP
from geoq.gp.numerics import NumericalWarning
from geoq.graph import MDPGraph
from geoq.graph._apsp_delete import DELETE_RTOL, affected_sources
from geoq.kernels import GeodesicKernel, Kernel, SquaredExponential
from geoq.kernels.geodesic import GraphKernel
from geoq.learners import PENDULUM_SCALING
from geoq.policies import default_policy
from geoq.rollouts import collect_rollouts

STEPS = 250
SIZES = ((200, 0.03), (500, 0.01), (1000, 0.0035))  # (n, minimum squared node spacing)
REGIMES = (("sparse", 0.9, True), ("dense", 0.5, False))
N_ADD = 50
N_DELETE = {"sparse": 20, "dense": 5}
ADD_GOAL_MS = 0.5
ADD_GOAL_RATIO = 400.0
FIT_GOAL_RATIO = 3.0
PERIOD = PENDULUM_SCALING.scaled_periods()


def _single_threaded_blas() -> contextlib.AbstractContextManager[object]:
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - optional
        return contextlib.nullcontext()
    return threadpool_limits(1)


def trajectory_nodes(n: int, r2min: float) -> tuple[np.ndarray, np.ndarray]:
    """First ``n`` points of 40 roll-outs spaced by r^2 > ``r2min``: (X [n, 3], roll-out ids)."""
    rollouts = collect_rollouts(40, STEPS, default_policy(), np.random.default_rng(0))
    Z = np.vstack([np.column_stack([r.states, r.actions]) for r in rollouts])
    X = PENDULUM_SCALING.transform(Z)
    probe = MDPGraph(1.0, period=PERIOD)  # eps = 1: no edges, only the wrap-aware metric
    keep: list[int] = []
    for i, x in enumerate(X):
        if not keep or probe.squared_distances(x[None, :], X[keep]).min() > r2min:
            keep.append(i)
            if len(keep) == n:
                break
    idx = np.asarray(keep)
    return X[idx], idx // STEPS


def build(X: np.ndarray, rollout: np.ndarray, eps: float, temporal: bool) -> tuple[MDPGraph, list]:
    """Graph over the rows of ``X`` added in order; returns it and the per-add times."""
    g = MDPGraph(eps, period=PERIOD, temporal_edges=temporal)
    current, times = -1, []
    for x, r in zip(X, rollout, strict=True):
        if r != current:
            g.start_rollout()
            current = r
        start = time.perf_counter()
        g.add_node(x)
        times.append(time.perf_counter() - start)
    return g, times


def bench_graph(sizes: tuple[tuple[int, float], ...] = SIZES, n_delete: int | None = None) -> None:
    print(
        f"{'regime':7s} {'n':>5s} {'comp':>4s} {'degree':>6s} | {'add ms':>7s} "
        f"{'scipy APSP ms':>13s} {'ratio':>7s} | {'delete ms':>9s} {'scipy affected ms':>17s} "
        f"{'ratio':>6s} {'affected':>8s}"
    )
    rng = np.random.default_rng(1)
    for name, eps, temporal in REGIMES:
        for n, r2min in sizes:
            X, rollout = trajectory_nodes(n, r2min)
            g, times = build(X, rollout, eps, temporal)
            t_add = float(np.mean(times[-N_ADD:]))  # adds at n - N_ADD ... n nodes
            A = g.adjacency
            start = time.perf_counter()
            D = dijkstra(A, directed=False)
            t_full = time.perf_counter() - start
            if not np.allclose(D, g.shortest_paths, rtol=1e-12, atol=1e-12):
                raise AssertionError("incremental shortest paths differ from Dijkstra")
            n_comp = connected_components(A, directed=False)[0]
            degree = g.degrees().mean()
            t_del, t_base, n_aff = [], [], []
            for _ in range(N_DELETE[name] if n_delete is None else n_delete):
                v = int(rng.integers(g.n_nodes))
                affected = affected_sources(g._P, g.n_nodes, v, DELETE_RTOL)
                keep = np.r_[0:v, v + 1 : g.n_nodes]
                A_without = A[keep][:, keep]
                src = np.flatnonzero(affected[keep])
                start = time.perf_counter()
                dijkstra(A_without, directed=False, indices=src)
                t_base.append(time.perf_counter() - start)
                start = time.perf_counter()
                g.remove_node(v)
                t_del.append(time.perf_counter() - start)
                n_aff.append(src.size)
                A = g.adjacency
            if not np.allclose(
                dijkstra(A, directed=False), g.shortest_paths, rtol=1e-12, atol=1e-12
            ):
                raise AssertionError("shortest paths after deletions differ from Dijkstra")
            td, tb = float(np.mean(t_del)), float(np.mean(t_base))
            print(
                f"{name:7s} {len(X):5d} {n_comp:4d} {degree:6.1f} | {t_add * 1e3:7.3f} "
                f"{t_full * 1e3:13.1f} {t_full / t_add:6.0f}x | {td * 1e3:9.3f} "
                f"{tb * 1e3:17.3f} {tb / td:5.1f}x {np.mean(n_aff):8.0f}"
            )
    print(
        f"  goals: add <= {ADD_GOAL_MS} ms and >= {ADD_GOAL_RATIO:.0f}x at n = 1000; "
        "delete ratio >= 1x"
    )


def _fit_time(make: Callable[[], Kernel], data: list, repeats: int = 3) -> tuple[float, object]:
    best, gp = np.inf, None
    for _ in range(repeats):
        kernel = make()
        gp = SparseOnlineGP(kernel, noise=0.01, max_bv=100)
        start = time.perf_counter()
        for X, y in data:
            if isinstance(kernel, GraphKernel):
                kernel.start_rollout()
            gp.partial_fit(X, y)
        best = min(best, time.perf_counter() - start)
    return best, gp


def bench_fit(steps: int = STEPS, repeats: int = 3) -> None:
    rollouts = collect_rollouts(3, steps, default_policy(), np.random.default_rng(0))
    Xs = [PENDULUM_SCALING.transform(np.column_stack([r.states, r.actions])) for r in rollouts]
    y_all = np.concatenate([r.returns for r in rollouts])
    data = [
        (X, (r.returns - y_all.mean()) / y_all.std()) for X, r in zip(Xs, rollouts, strict=True)
    ]
    kernels = {
        "squared exponential": lambda: SquaredExponential(0.3, period=PERIOD),
        "nearest (eq. 4)": lambda: GeodesicKernel(eps=0.3, sigma_sp=0.001, period=PERIOD),
        "interpolated (eq. 5)": lambda: GeodesicKernel(
            eps=0.3,
            method="interpolated",
            sigma_sp=0.001,
            sigma_se=0.001,
            normalize=True,
            attach=True,
            period=PERIOD,
        ),
    }
    print(f"\nsparse online GP fit, {sum(len(y) for _, y in data)} points, max_bv = 100:")
    t_se = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        for name, make in kernels.items():
            t, gp = _fit_time(make, data, repeats)
            assert isinstance(gp, SparseOnlineGP)
            d = gp.diagnostics
            t_se = t if t_se is None else t_se
            print(
                f"  {name:22s} {t * 1e3:8.1f} ms  ({t / t_se:4.1f}x SE; goal <= "
                f"{FIT_GOAL_RATIO:.0f}x)  n_bv {gp.n_bv}, added {d.n_added}, deleted {d.n_deleted}"
            )


def main(quick: bool = False) -> None:
    """``quick``: tiny sizes, figures of no meaning (``benchmarks/run.py --quick``)."""
    with _single_threaded_blas():
        if quick:
            bench_graph(sizes=((60, 0.03),), n_delete=3)
            bench_fit(steps=40, repeats=1)
        else:
            bench_graph()
            bench_fit()


if __name__ == "__main__":
    main()
