"""Oracle tests of the numerics helpers in :mod:`geoq.gp.numerics`."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.linalg

from geoq.gp.numerics import (
    VAR_ROUNDING,
    NotPSDError,
    NumericalWarning,
    cholesky_cannot_succeed,
    clip_eigenvalues,
    project_whitened_covariance,
    robust_cholesky,
    safe_cholesky,
)
from geoq.gp.pd_novelty import PDNoveltyOnlineGP
from geoq.kernels import GeodesicKernel


def test_whitened_covariance_projection_clips_the_spectrum_onto_unit_interval():
    rng = np.random.default_rng(0)
    U, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    w = np.array([-0.5, 0.2, 0.3, 0.9, 0.5, 3.0])
    S, projected = project_whitened_covariance((U * w) @ U.T)
    assert projected == 2
    assert np.array_equal(S, S.T)
    assert np.allclose(np.linalg.eigvalsh(S), np.sort(np.clip(w, 0.0, 1.0)), atol=1e-9)

    valid = (U * np.array([0.0, 0.1, 0.2, 0.5, 0.7, 1.0])) @ U.T
    S2, projected2 = project_whitened_covariance(valid)
    assert projected2 == 0
    assert np.array_equal(S2, 0.5 * (valid + valid.T))  # symmetrised only


def _frobenius_projection(S: np.ndarray) -> tuple[np.ndarray, int]:
    """Oracle: the full eigendecomposition, every eigenvalue clipped onto [0, 1]."""
    w, U = np.linalg.eigh(0.5 * (S + S.T))
    bad = int(np.count_nonzero((w < -VAR_ROUNDING) | (w > 1.0 + VAR_ROUNDING)))
    return (U * np.clip(w, 0.0, 1.0)) @ U.T, bad


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize(
    "above",
    [
        [1.5],
        [1.0 + 1e-6, 2.0, 30.0],  # a resistance re-anchoring: a few to many above 1
        [3e7, 2e6],  # pd_novelty: huge, the subtraction's result is checked
        list(np.linspace(1.1, 5.0, 40)),
    ],
)
def test_projection_above_one_matches_the_full_eigendecomposition(seed, above):
    """Issue 31: only the eigenpairs above 1 are computed when S >= 0 holds; the result is
    the Frobenius projection (oracle: numpy's full eigendecomposition) to rounding."""
    rng = np.random.default_rng(seed)
    m = 60
    w = np.concatenate([rng.uniform(0.0, 1.0, m - len(above) - 2), [0.0, -1e-12], above])
    S = _symmetric_with_spectrum(w, rng)
    got, projected = project_whitened_covariance(S)
    want, n_bad = _frobenius_projection(S)
    assert projected == n_bad == len(above)
    assert np.array_equal(got, got.T)
    tol = 100 * m * np.finfo(float).eps * max(1.0, float(np.max(above)))
    assert np.max(np.abs(got - want)) <= tol
    lam = np.linalg.eigvalsh(got)
    assert lam.min() >= -VAR_ROUNDING and lam.max() <= 1.0 + VAR_ROUNDING


def test_projection_above_one_needs_no_full_eigendecomposition(monkeypatch):
    """The speed path of a re-anchoring (issue 31): S >= 0 holds, S <= I does not."""
    import geoq.gp.numerics as numerics

    def forbidden(A: np.ndarray) -> None:
        raise AssertionError("full eigendecomposition called")

    monkeypatch.setattr(numerics, "_eigh", forbidden)
    rng = np.random.default_rng(4)
    S = _symmetric_with_spectrum(np.array([0.0, 0.2, 0.5, 2.0, 7.0]), rng)
    assert project_whitened_covariance(S)[1] == 2


def test_projection_of_a_negative_spectrum_falls_back_to_the_full_clip():
    rng = np.random.default_rng(3)
    S = _symmetric_with_spectrum(np.array([-0.3, 0.2, 0.5, 2.0, 7.0]), rng)
    got, projected = project_whitened_covariance(S)
    want, n_bad = _frobenius_projection(S)
    assert projected == n_bad == 3
    assert np.allclose(got, want, atol=1e-12)


# -- issue 13: jittered tries proven hopeless by the spectrum are skipped, same result -----
def _old_robust_cholesky(K: np.ndarray) -> tuple[np.ndarray, int, int]:
    """robust_cholesky before the skip (the reference): every try, then the clipping."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        try:
            L, jitter = safe_cholesky(K)
            return L, int(jitter > 0.0), 0
        except NotPSDError:
            K_pd, n_clipped = clip_eigenvalues(K)
            L, jitter = safe_cholesky(K_pd)
            return L, int(jitter > 0.0), n_clipped


def _symmetric_with_spectrum(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    Q, _ = np.linalg.qr(rng.normal(size=(w.size, w.size)))
    K = (Q * w) @ Q.T
    return 0.5 * (K + K.T)


def _cases() -> list[np.ndarray]:
    rng = np.random.default_rng(13)
    X = rng.uniform(-2.0, 2.0, size=(40, 2))
    gram = GeodesicKernel(eps=0.3, sigma_sp=1.0)
    cases = [
        _symmetric_with_spectrum(rng.uniform(0.1, 2.0, 30), rng),  # PD
        _symmetric_with_spectrum(np.r_[-1e-12, rng.uniform(0.1, 2.0, 29)], rng),  # jitter helps
        _symmetric_with_spectrum(np.r_[-3e-6, rng.uniform(0.1, 2.0, 29)], rng),  # big jitter
        _symmetric_with_spectrum(np.r_[-3e-4, rng.uniform(0.1, 2.0, 29)], rng),  # beyond it
        _symmetric_with_spectrum(np.r_[-0.3, -1e-3, rng.uniform(0.1, 2.0, 28)], rng),
        _symmetric_with_spectrum(np.r_[np.zeros(5), rng.uniform(0.1, 2.0, 25)], rng),
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        gp = PDNoveltyOnlineGP(gram, noise=0.01, max_bv=40).fit(X, np.sin(X[:, 0]))
    K = gram.basis_gram(gp.basis_vectors)
    assert np.linalg.eigvalsh(K).min() < -1e-3
    return [*cases, 0.5 * (K + K.T)]  # an indefinite geodesic Gram


def test_robust_cholesky_equals_trying_every_jitter_bit_for_bit() -> None:
    clipped = 0
    for K in _cases():
        got, want = robust_cholesky(K, "K"), _old_robust_cholesky(K)
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1:] == want[1:]
        clipped += got[2] > 0
    assert clipped >= 3  # the skip was exercised


def test_a_try_called_hopeless_does_fail() -> None:
    # Soundness of the skip: whenever the spectrum says a shifted factorisation cannot
    # succeed, it does not; and clearly indefinite shifts are recognised.
    recognised = 0
    for K in _cases():
        w = np.linalg.eigvalsh(K)
        for shift in (0.0, *np.geomspace(1e-14, 1.0, 40)):
            if cholesky_cannot_succeed(w, K, shift):
                recognised += 1
                with pytest.raises(np.linalg.LinAlgError):
                    scipy.linalg.cholesky(K + shift * np.eye(K.shape[0]), lower=True)
            elif w.min() + shift > 1e-6 * np.abs(w).max():
                scipy.linalg.cholesky(K + shift * np.eye(K.shape[0]), lower=True)
    assert recognised > 50


def test_eigenvalues_above_one_by_rounding_only_leave_the_covariance_alone():
    """A re-anchored S whose Cholesky check failed by rounding only: no projection."""
    from geoq.gp.numerics import _clip_above_one

    rng = np.random.default_rng(5)
    S = _symmetric_with_spectrum(np.array([0.1, 0.4, 1.0 + 0.5 * VAR_ROUNDING]), rng)
    out = _clip_above_one(S)
    assert out is not None and out[1] == 0 and np.array_equal(out[0], S)
