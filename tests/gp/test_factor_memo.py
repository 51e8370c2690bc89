"""The factor of ``K_BV`` kept for the last matrix factorised (issue 13: resyncs that
find ``K_BV`` unchanged reuse it): the same numbers as factorising every time when
``K_BV`` is the same bit for bit; within one batch also a ``K_BV`` within rounding of
it (issue 31), and a GP saved between batches continues with the same numbers."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from geoq.gp import NumericalWarning, SparseOnlineGP
from geoq.gp._resync import FactorMemo
from geoq.gp.numerics import CONFIG, robust_cholesky
from geoq.gp.pd_novelty import PDNoveltyOnlineGP
from geoq.kernels import GeodesicKernel, ResistanceKernel
from geoq.learners import GPQFunction, QGPConfig
from geoq.policies import DEFAULT_POLICY_SIGMA, default_policy
from geoq.rollouts import collect_rollouts


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

    def spy(self: FactorMemo, K: np.ndarray, config: object, batch: object = None) -> bool:
        hit = same_input(self, K, config)  # type: ignore[arg-type]  # bit for bit only
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


def test_within_a_batch_a_gram_within_rounding_reuses_the_factor() -> None:
    rng = np.random.default_rng(3)
    A = rng.normal(size=(30, 30))
    K = A @ A.T + 30.0 * np.eye(30)
    L, jit, clips = robust_cholesky(K, "K")
    memo = FactorMemo(K, CONFIG, L.T, jit, clips, batch=5)
    near = K.copy()
    near[3, 4] = near[4, 3] = np.nextafter(np.nextafter(K[3, 4], np.inf), np.inf)
    far = K.copy()
    far[3, 4] = far[4, 3] = K[3, 4] + 1e-9 * np.abs(K).max()
    assert memo.same_input(K, CONFIG, None)  # bit for bit: always
    assert memo.same_input(near, CONFIG, 5)
    assert not memo.same_input(near, CONFIG, 7)  # another batch: bit for bit only
    assert not memo.same_input(near, CONFIG, None)
    assert not memo.same_input(far, CONFIG, 5)


def _pendulum_stream() -> tuple[GPQFunction, np.ndarray, np.ndarray]:
    """A ``pd_novelty`` learner on the pendulum and one roll-out's inputs and targets: a
    geodesic graph large enough that points added and deleted again leave ``K_BV``
    within rounding of the memo's (the geodesic paths summed in another order)."""
    rollouts = collect_rollouts(
        1, 250, default_policy(DEFAULT_POLICY_SIGMA), np.random.default_rng(0), gamma=0.95
    )
    learner = GPQFunction(
        QGPConfig(kernel="nearest", pd_novelty=True, max_bv=60, eps=0.3, sigma_sp=0.3, noise=0.175)
    )
    (X,), (z,) = learner._targets(rollouts)
    return learner, X, z


def _save_load_continue(tmp_path, split: int) -> bool:  # type: ignore[no-untyped-def]
    """Whether a GP saved after ``split`` points and loaded continues as the one kept."""
    learner, X, z = _pendulum_stream()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        kept = learner._new_gp()
        kept.kernel.start_rollout()
        kept.partial_fit(X[:split], z[:split])
        kept.save(tmp_path / f"gp{split}.npz")
        reloaded = PDNoveltyOnlineGP.load(tmp_path / f"gp{split}.npz")  # no factor memo
        for gp in (kept, reloaded):
            gp.partial_fit(X[split:], z[split:])
    return np.array_equal(kept.cholesky_factor, reloaded.cholesky_factor) and all(
        np.array_equal(a, b)
        for a, b in zip(kept.whitened_posterior, reloaded.whitened_posterior, strict=True)
    )


def test_a_gp_saved_between_batches_continues_with_the_same_numbers(
    tmp_path, monkeypatch: pytest.MonkeyPatch
) -> None:  # type: ignore[no-untyped-def]
    assert _save_load_continue(tmp_path, 210)
    assert _save_load_continue(tmp_path, 240)
    # The pin can fail: with the tolerance across batches the continuations differ.
    same_input = FactorMemo.same_input
    monkeypatch.setattr(
        FactorMemo,
        "same_input",
        lambda self, K, config, batch=None: same_input(self, K, config, self.batch),
    )
    assert not _save_load_continue(tmp_path, 240)
