"""A kernel with state (a graph over the basis set) serves one GP; bad budgets name themselves."""

from __future__ import annotations

import copy
import gc

import numpy as np
import pytest

from geoq.gp import SparseOnlineGP
from geoq.kernels import GeodesicKernel, ResistanceKernel, SquaredExponential


def _data(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1, 1, (40, 2))
    return X, np.sin(3 * X[:, 0])


@pytest.mark.parametrize(
    "make",
    [lambda: GeodesicKernel(eps=0.3, method="nearest"), lambda: ResistanceKernel(eps=0.3)],
)
def test_a_graph_kernel_cannot_silently_couple_two_gps(make) -> None:  # type: ignore[no-untyped-def]
    kernel = make()
    first = SparseOnlineGP(kernel, noise=0.01, max_bv=20).fit(*_data(0))
    Xs = np.linspace(-1, 1, 7)[:, None].repeat(2, axis=1)
    before = first.predict(Xs)
    with pytest.raises(ValueError, match="already belongs to another model"):
        SparseOnlineGP(kernel, noise=0.01, max_bv=20)
    np.testing.assert_array_equal(first.predict(Xs), before)  # the first GP is untouched
    # A copy is independent: fitting it leaves the first GP's predictions unchanged.
    second = SparseOnlineGP(copy.deepcopy(kernel), noise=0.01, max_bv=20).fit(*_data(1))
    np.testing.assert_array_equal(first.predict(Xs), before)
    assert second.kernel is not first.kernel
    # Once its GP is gone, the kernel can serve a new one.
    del first, second
    gc.collect()
    SparseOnlineGP(kernel, noise=0.01, max_bv=20)


def test_stateless_kernels_are_shared_freely() -> None:
    kernel = SquaredExponential(0.5)
    a = SparseOnlineGP(kernel, noise=0.01, max_bv=20).fit(*_data(0))
    b = SparseOnlineGP(kernel, noise=0.01, max_bv=20).fit(*_data(1))
    assert a.kernel is b.kernel


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"resync_every": 0}, "resync_every must be an integer"),
        ({"tol": 1.5}, "no point would ever become a basis vector"),
    ],
)
def test_bad_settings_name_themselves(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        SparseOnlineGP(SquaredExponential(0.5), noise=0.01, max_bv=20, **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "make",
    [
        lambda: SquaredExponential(0.5),
        lambda: GeodesicKernel(eps=0.3, method="nearest", sigma_sp=4.0),
        lambda: ResistanceKernel(eps=0.3),
    ],
    ids=["se", "geodesic", "resistance"],
)
def test_copy_is_an_independent_model_in_the_same_state(make) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(5)
    X, y = rng.normal(size=(60, 2)), rng.normal(size=60)
    gp = SparseOnlineGP(make(), noise=0.1, max_bv=12).fit(X[:30], y[:30])
    twin = gp.copy()
    assert twin.kernel is not gp.kernel
    twin.partial_fit(X[30:], y[30:])  # the copy drives its own kernel (bound to it)
    gp.partial_fit(X[30:], y[30:])
    fresh = SparseOnlineGP(make(), noise=0.1, max_bv=12).fit(X, y)
    assert gp.diagnostics == twin.diagnostics == fresh.diagnostics  # before predict counts
    want = fresh.predict(X, return_std=True)
    for model in (gp, twin):
        for a, b in zip(model.predict(X, return_std=True), want, strict=True):
            np.testing.assert_array_equal(a, b)
