"""The factor of ``K_BV`` kept for the last matrix factorised (issue 13: resyncs that
find ``K_BV`` unchanged reuse it): the same numbers as factorising every time."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from geoq.gp import NumericalWarning, SparseOnlineGP
from geoq.gp._resync import FactorMemo
from geoq.gp.numerics import robust_cholesky
from geoq.gp.pd_novelty import PDNoveltyOnlineGP
from geoq.kernels import GeodesicKernel, ResistanceKernel


def _data() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 6.0, 160)
    X = np.column_stack([np.sin(t), np.cos(1.3 * t), 0.1 * rng.normal(size=t.size)])
    return X, np.sin(2.0 * t) + 0.05 * rng.normal(size=t.size)


@pytest.mark.parametrize(
    ("make_gp"),
    [
        lambda: PDNoveltyOnlineGP(GeodesicKernel(eps=0.3, sigma_sp=1.0), noise=0.01, max_bv=25),
        lambda: SparseOnlineGP(ResistanceKernel(eps=0.3), noise=0.01, max_bv=25),
    ],
    ids=["pd_novelty_geodesic", "resistance"],
)
def test_reusing_the_factor_gives_the_numbers_of_factorising_every_time(
    make_gp, monkeypatch: pytest.MonkeyPatch
) -> None:
    X, y = _data()
    hits = []
    same_input = FactorMemo.same_input

    def spy(self: FactorMemo, K: np.ndarray, config: object) -> bool:
        hit = same_input(self, K, config)  # type: ignore[arg-type]
        hits.append(hit)
        return hit

    def fit(memo: bool) -> tuple[SparseOnlineGP, tuple[np.ndarray, ...]]:
        with monkeypatch.context() as mp:
            mp.setattr(FactorMemo, "same_input", spy if memo else lambda *_: False)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NumericalWarning)
                gp = make_gp()
                gp.kernel.start_rollout()
                gp.partial_fit(X[:80], y[:80])
                gp.kernel.start_rollout()
                gp.partial_fit(X[80:], y[80:])
                gp.refit(X, y)
                return gp, (*gp.predict(X, return_std=True), gp.alpha, gp.C)

    with_memo, got = fit(True)
    without, want = fit(False)
    assert any(hits), "no resync found K_BV unchanged: the memo was not exercised"
    assert with_memo.diagnostics == without.diagnostics  # repair counts replayed
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_kept_factor_is_the_factor_of_the_current_gram() -> None:
    X, y = _data()
    gp = PDNoveltyOnlineGP(GeodesicKernel(eps=0.3, sigma_sp=1.0), noise=0.01, max_bv=25)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        gp.fit(X, y)
        R = gp._factor_gram()
    assert not R.flags.writeable  # shared with the memo: callers copy it
    K = gp.kernel.basis_gram(gp.basis_vectors)
    L, _, _ = robust_cholesky(0.5 * (K + K.T), "K_BV")
    np.testing.assert_array_equal(R, L.T)
    np.testing.assert_array_equal(gp.cholesky_factor, R)  # the last resync re-anchored on it
