"""Oracle tests of the numerics helpers in :mod:`geoq.gp.numerics`."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.linalg

from geoq.gp.numerics import (
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
