"""Issue 12, class 7: a batch is applied entirely or not at all; counters count what happened."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from geoq.gp import NumericalWarning, SparseOnlineGP, _stream
from geoq.kernels import GeodesicKernel, ResistanceKernel, SquaredExponential

RNG = np.random.default_rng(1)
X = RNG.uniform(-1, 1, (40, 2))
Y = np.sin(3 * X[:, 0])
XT = RNG.uniform(-1, 1, (7, 2))


class PoisonedSE(SquaredExponential):
    """A kernel that returns NaN for inputs with x_0 > threshold (a numerical failure)."""

    threshold = np.inf

    def to_basis(self, X, basis):  # type: ignore[no-untyped-def]
        K = super().to_basis(X, basis)
        K[X[:, 0] > self.threshold] = np.nan
        return K

    def basis_gram(self, basis):  # type: ignore[no-untyped-def]
        K = super().basis_gram(basis)
        if np.any(basis[:, 0] > self.threshold):
            K[0, 0] = np.nan
        return K


def _state(gp: SparseOnlineGP) -> tuple:
    mean, std = gp.predict(XT, return_std=True)
    return (gp.n_bv, gp.basis_vectors, mean, std, gp.diagnostics, *gp.whitened_posterior)


def _assert_same(a: tuple, b: tuple) -> None:
    assert len(a) == len(b)
    for u, v in zip(a, b, strict=True):
        if isinstance(u, np.ndarray):
            np.testing.assert_array_equal(u, v)
        else:
            assert u == v


def test_a_numerical_failure_mid_batch_leaves_the_gp_unchanged() -> None:
    kernel = PoisonedSE(0.4)
    gp = SparseOnlineGP(kernel, noise=0.01, max_bv=10).fit(X[:20], Y[:20])
    before = _state(gp)
    batch = X[20:].copy()
    batch[:, 0] = np.linspace(-0.9, 0.99, 20)  # the last rows fail, the first ones do not
    kernel.threshold = 0.95
    for call in (lambda: gp.partial_fit(batch, Y[20:]), lambda: gp.fit(batch, Y[20:])):
        with pytest.raises(ValueError, match="non-finite covariances"):
            call()
        kernel.threshold = np.inf
        _assert_same(_state(gp), before)
        kernel.threshold = 0.95
    kernel.threshold = np.inf
    gp.partial_fit(batch, Y[20:])  # and it still learns afterwards
    assert gp.diagnostics.n_seen == before[4].n_seen + 20


def test_a_non_finite_row_rejects_the_whole_batch_before_any_row() -> None:
    gp = SparseOnlineGP(SquaredExponential(0.4), noise=0.01, max_bv=10).fit(X[:20], Y[:20])
    before = _state(gp)
    y_bad = Y[20:].copy()
    y_bad[-1] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        gp.partial_fit(X[20:], y_bad)
    _assert_same(_state(gp), before)


@pytest.mark.parametrize(
    "make",
    [
        lambda: GeodesicKernel(eps=0.9, method="interpolated", normalize=True, attach=True),
        lambda: ResistanceKernel(eps=0.3),
    ],
)
def test_an_interrupted_batch_restores_the_kernels_graph_too(make, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    kernel = make()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        gp = SparseOnlineGP(kernel, noise=0.01, max_bv=30, tol=0).fit(X[:15], Y[:15])
        before = _state(gp)
        nodes = kernel.graph.n_nodes
        seen = {"rows": 0, "nodes": nodes}
        step = _stream.online_step_lower

        def interrupted(*args):  # type: ignore[no-untyped-def]
            seen["rows"] += 1
            seen["nodes"] = kernel.graph.n_nodes
            if seen["rows"] == 20:
                raise KeyboardInterrupt
            return step(*args)

        monkeypatch.setattr(_stream, "online_step_lower", interrupted)
        with pytest.raises(KeyboardInterrupt):
            gp.partial_fit(X[15:], Y[15:])
        monkeypatch.undo()
        assert seen["nodes"] > nodes  # the graph had grown before the interruption
        assert kernel.graph.n_nodes == nodes
        _assert_same(_state(gp), before)
        gp.partial_fit(X[15:], Y[15:])  # the restored kernel still serves this GP
        assert kernel.follows_basis(gp.basis_vectors)
        with pytest.raises(ValueError, match="already belongs"):
            SparseOnlineGP(kernel, noise=0.01, max_bv=5)


def test_a_failed_refit_changes_nothing_and_is_not_counted() -> None:
    kernel = PoisonedSE(0.4)
    gp = SparseOnlineGP(kernel, noise=0.01, max_bv=10).fit(X, Y)
    gp.refit(X, Y)
    assert gp.diagnostics.refits == 1
    before = _state(gp)
    kernel.threshold = -np.inf  # every covariance is NaN now
    with pytest.raises(ValueError, match="non-finite"):
        gp.refit(X, Y)
    kernel.threshold = np.inf
    _assert_same(_state(gp), before)
    assert gp.diagnostics.refits == 1
    with pytest.raises(ValueError, match="shape"):  # refused input: not counted either
        gp.refit(X[:, :1], Y)
    assert gp.diagnostics.refits == 1


def test_a_single_update_with_a_non_finite_kernel_row_changes_nothing() -> None:
    kernel = PoisonedSE(0.4)
    gp = SparseOnlineGP(kernel, noise=0.01, max_bv=10).fit(X, Y)
    before = _state(gp)
    kernel.threshold = 0.0
    with pytest.raises(ValueError, match="non-finite covariances"):
        gp.update(np.array([0.5, 0.5]), 1.0)
    kernel.threshold = np.inf
    _assert_same(_state(gp), before)
