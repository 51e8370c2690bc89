"""Re-anchoring shortcuts of issue 31: the same posterior as the general path, to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.gp._resync import reanchor
from geoq.gp.numerics import project_whitened_covariance


def _spd(rng: np.random.Generator, m: int, scale: float = 1.0) -> np.ndarray:
    A = rng.normal(size=(m, m))
    return scale * (A @ A.T) / m + 0.5 * np.eye(m)


def test_an_unchanged_factor_skips_the_transform_and_keeps_the_projection() -> None:
    rng = np.random.default_rng(0)
    m = 40
    R = np.linalg.cholesky(_spd(rng, m)).T
    mu = rng.normal(size=m)
    S = _spd(rng, m, 0.8)  # eigenvalues above 1: the projection must still happen
    mu_new, S_new, projected = reanchor(R, R.copy(), mu, S)
    assert projected > 0
    np.testing.assert_array_equal(mu_new, mu)
    np.testing.assert_array_equal(S_new, project_whitened_covariance(S)[0])
    # The general path (a factor that differs in one bit) gives the same to rounding.
    R2 = R.copy()
    R2[0, 0] = np.nextafter(R2[0, 0], np.inf)
    mu_gen, S_gen, projected_gen = reanchor(R, R2, mu, S)
    assert projected_gen == projected
    np.testing.assert_allclose(mu_gen, mu_new, rtol=0, atol=1e-13)
    np.testing.assert_allclose(S_gen, S_new, rtol=0, atol=1e-13)


def test_a_non_finite_mean_takes_the_general_path() -> None:
    """``T = I`` times ``inf`` is not ``inf`` (``0 * inf = nan``): no shortcut there."""
    rng = np.random.default_rng(1)
    R = np.linalg.cholesky(_spd(rng, 5)).T
    mu = np.array([np.inf, 0.0, 0.0, 0.0, 0.0])
    with np.errstate(invalid="ignore"):
        mu_new, _, _ = reanchor(R, R.copy(), mu, 0.5 * np.eye(5))
    assert np.isnan(mu_new).any()


@pytest.mark.parametrize("above", [0, 3, 25])
def test_both_projections_agree_to_rounding(above: int) -> None:
    rng = np.random.default_rng(above)
    m = 60
    U, _ = np.linalg.qr(rng.normal(size=(m, m)))
    w = np.concatenate([rng.uniform(1.5, 4.0, above), rng.uniform(0.0, 1.0, m - above)])
    S = (U * w) @ U.T
    S = 0.5 * (S + S.T)
    partial, n_partial = project_whitened_covariance(S)
    full, n_full = project_whitened_covariance(S, many_above_one=True)
    assert n_partial == n_full == above
    np.testing.assert_allclose(partial, full, rtol=0, atol=1e-12)
    eig = np.linalg.eigvalsh(full)
    assert eig.min() > -1e-9 and eig.max() < 1 + 1e-9


def _stream_data() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 6.0, 160)
    X = np.column_stack([np.sin(t), np.cos(1.3 * t), 0.1 * rng.normal(size=t.size)])
    return X, np.sin(2.0 * t) + 0.05 * rng.normal(size=t.size)


@pytest.mark.parametrize("kind", ["resistance", "pd_novelty_geodesic"])
def test_a_resync_that_finds_the_factor_unchanged_matches_a_full_one(
    kind: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Oracle (issue 31): a resync that finds the factor of ``K_BV`` unchanged keeps the
    posterior and the step's scores (refreshed every ``score_refresh_every`` resyncs);
    the full resync (re-anchoring, projection, exact scores) gives the same basis set
    and the same predictions to rounding."""
    import warnings

    from geoq.gp import NumericalWarning, SparseOnlineGP
    from geoq.gp.pd_novelty import PDNoveltyOnlineGP
    from geoq.kernels import GeodesicKernel, ResistanceKernel

    X, y = _stream_data()
    skipped: list[bool] = []
    unchanged = SparseOnlineGP._factor_unchanged

    def spy(self: SparseOnlineGP, R_new: np.ndarray) -> bool:
        out = unchanged(self, R_new)
        skipped.append(out)
        return out

    def fit(skip: bool) -> tuple[SparseOnlineGP, np.ndarray, np.ndarray]:
        with monkeypatch.context() as mp:
            mp.setattr(SparseOnlineGP, "_factor_unchanged", spy if skip else lambda *_: False)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", NumericalWarning)
                if kind == "resistance":
                    gp: SparseOnlineGP = SparseOnlineGP(
                        ResistanceKernel(eps=0.3), noise=0.01, max_bv=25
                    )
                else:
                    gp = PDNoveltyOnlineGP(
                        GeodesicKernel(eps=0.3, sigma_sp=1.0), noise=0.01, max_bv=25
                    )
                gp.fit(X, y)
                mean, std = gp.predict(X, return_std=True)
        return gp, mean, std

    fast, mean, std = fit(True)
    assert any(skipped), "no resync found the factor unchanged"
    full, mean_full, std_full = fit(False)
    np.testing.assert_array_equal(fast.basis_vectors, full.basis_vectors)
    scale = float(np.max(np.abs(mean_full)))
    np.testing.assert_allclose(mean, mean_full, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(std, std_full, rtol=0, atol=1e-8 * float(np.max(std_full)))
    assert fast.diagnostics.q_resyncs == full.diagnostics.q_resyncs
