"""The BLAS threading policy: one thread inside the GP's entry points, the caller's outside."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from geoq._threads import blas_controllers, one_blas_thread
from geoq.gp import SparseOnlineGP
from geoq.kernels import ResistanceKernel, SquaredExponential


def counts() -> list[int]:
    return [c.get_num_threads() for c in blas_controllers()]


@pytest.fixture
def two_threads() -> Iterator[None]:
    """The caller runs BLAS on 2 threads (skips where a BLAS cannot be set to 2)."""
    if not blas_controllers():
        pytest.skip("no BLAS library found by threadpoolctl")
    before = counts()
    for c in blas_controllers():
        c.set_num_threads(2)
    try:
        if counts() != [2] * len(before):
            pytest.skip("this BLAS cannot run 2 threads here")
        yield
    finally:
        for c, n in zip(blas_controllers(), before, strict=True):
            c.set_num_threads(n)


def test_gp_entry_points_run_on_one_thread_and_restore_the_callers(two_threads, monkeypatch):
    seen: list[list[int]] = []
    stream = SparseOnlineGP._stream

    def spy(self, X, y):  # type: ignore[no-untyped-def]
        seen.append(counts())
        return stream(self, X, y)

    monkeypatch.setattr(SparseOnlineGP, "_stream", spy)
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (40, 2))
    y = np.sin(X[:, 0])
    gp = SparseOnlineGP(SquaredExponential(0.5), noise=0.01, max_bv=10)
    gp.fit(X[:20], y[:20]).partial_fit(X[20:], y[20:])
    assert seen == [[1] * len(counts())] * 2
    assert counts() == [2] * len(seen[0])  # restored
    gp.update(X[0], y[0])  # not wrapped (module doc): runs with the caller's setting
    assert seen[-1] == [2] * len(seen[0])


def test_resistance_hooks_run_on_one_thread(two_threads, monkeypatch):
    rk = ResistanceKernel(eps=0.3)
    seen: list[list[int]] = []
    import geoq.kernels.graph_pd as graph_pd

    add_edges = graph_pd.add_edges

    def spy(*args):  # type: ignore[no-untyped-def]
        seen.append(counts())
        return add_edges(*args)

    monkeypatch.setattr(graph_pd, "add_edges", spy)
    assert rk.distance.resistance.shape == (0, 0)  # type: ignore[attr-defined]  # now current
    for x in ([0.0, 0.0], [0.3, 0.0], [0.3, 0.3], [0.0, 0.3]):
        rk.basis_added(np.asarray(x))
    assert seen and all(s == [1] * len(s) for s in seen)
    assert counts() == [2] * len(seen[0])


def test_nested_and_failing_blocks_restore_only_at_the_outermost_exit(two_threads):
    n = len(blas_controllers())
    with one_blas_thread():
        with one_blas_thread():
            assert counts() == [1] * n
        assert counts() == [1] * n  # the inner exit does not restore
    assert counts() == [2] * n
    with pytest.raises(RuntimeError), one_blas_thread():
        raise RuntimeError("boom")
    assert counts() == [2] * n


def test_predict_uses_one_thread_for_small_batches_only(two_threads, monkeypatch):
    import geoq._threads as threads

    rng = np.random.default_rng(1)
    X = rng.uniform(-1, 1, (30, 2))
    gp = SparseOnlineGP(SquaredExponential(0.5), noise=0.01, max_bv=10).fit(X, np.sin(X[:, 0]))
    seen: list[list[int]] = []
    import geoq.gp.sparse_online as sparse_online

    predict_factored = sparse_online.predict_factored

    def spy(*args):  # type: ignore[no-untyped-def]
        seen.append(counts())
        return predict_factored(*args)

    monkeypatch.setattr(sparse_online, "predict_factored", spy)  # the name predict() calls
    monkeypatch.setattr(threads, "SMALL_BATCH", 100)
    gp.predict(rng.uniform(-1, 1, (100, 2)), return_std=True)  # small: one thread
    gp.predict(X=rng.uniform(-1, 1, (101, 2)))  # large: the caller's setting
    n = len(counts())
    assert seen == [[1] * n, [2] * n]
    assert counts() == [2] * n
