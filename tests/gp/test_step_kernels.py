"""Oracle tests of the compiled building blocks (:mod:`geoq.gp._nb_linalg`, `_nb_delete`).

The step keeps the whitened covariance as its lower triangle; these tests check
the lower-triangle kernels (symmetric matvec, the Givens deletion of a whitened
coordinate) against dense numpy at sizes where every block/remainder case of the
four-row lockstep recurrences occurs.
"""

from __future__ import annotations

import numpy as np
import pytest

from geoq.gp._nb_delete import delete_cholesky, delete_whitened
from geoq.gp._nb_linalg import symv_lower


def _spd(rng: np.random.Generator, m: int, cap: int) -> np.ndarray:
    A = rng.normal(size=(m, m))
    S = np.zeros((cap, cap))
    S[:m, :m] = A @ A.T / m + 0.1 * np.eye(m)
    return S


@pytest.mark.parametrize("m", [1, 2, 5, 13, 40])
@pytest.mark.parametrize("lo_frac", [0.0, 0.5, 0.99])
def test_symv_lower_matches_dense(m: int, lo_frac: float) -> None:
    rng = np.random.default_rng(m)
    cap = m + 3
    S = _spd(rng, m, cap)
    lo = min(int(lo_frac * m), m - 1)
    v = rng.normal(size=cap)
    v[:lo] = 0.0
    Sl = np.tril(S) + np.triu(rng.normal(size=(cap, cap)), 1)  # garbage upper triangle
    out = np.full(cap, np.nan)
    symv_lower(Sl, v, lo, m, out)
    np.testing.assert_allclose(out[:m], S[:m, :m] @ v[:m], rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("m", [2, 3, 6, 9, 31])
def test_delete_whitened_matches_dense_rotation_and_conditioning(m: int) -> None:
    rng = np.random.default_rng(100 + m)
    cap = m + 2
    for i in sorted({0, 1, m // 2, m - 5, m - 2, m - 1} & set(range(m))):
        # Rotations from a genuine Cholesky deletion.
        A = rng.normal(size=(m, m))
        K = A @ A.T + m * np.eye(m)
        R = np.zeros((cap, cap))
        R[:m, :m] = np.linalg.cholesky(K).T
        cth, sth, x = np.zeros(cap), np.zeros(cap), np.zeros(cap)
        delete_cholesky(R, i, m, x, cth, sth)
        G = np.eye(m)
        for j in range(i + 1, m):  # G^T acts on rows (j, i), in this order
            Gj = np.eye(m)
            Gj[j, j], Gj[j, i], Gj[i, j], Gj[i, i] = cth[j], sth[j], -sth[j], cth[j]
            G = G @ Gj.T
        S = _spd(rng, m, cap)
        S[:m, :m] /= 1.1 * np.linalg.eigvalsh(S[:m, :m]).max()  # 0 <= S <= I
        mu = np.zeros(cap)
        mu[:m] = rng.normal(size=m)
        Sr = G.T @ S[:m, :m] @ G
        mur = G.T @ mu[:m]
        sig = Sr[:, i]
        keep = np.arange(m) != i
        S_ref = (Sr - np.outer(sig, sig) / sig[i])[np.ix_(keep, keep)]
        mu_ref = (mur - sig * mur[i] / sig[i])[keep]

        Sl = np.tril(S) + np.triu(np.full((cap, cap), np.nan), 1)  # upper never read
        counters = np.zeros(9, dtype=np.int64)
        scratch = np.zeros((2, cap))
        delete_whitened(Sl, mu, scratch[0], scratch[1], i, m, cth, sth, counters)
        got = np.tril(Sl[: m - 1, : m - 1])
        np.testing.assert_allclose(got, np.tril(S_ref), rtol=0, atol=1e-12, err_msg=f"i={i}")
        np.testing.assert_allclose(mu[: m - 1], mu_ref, rtol=0, atol=1e-12, err_msg=f"i={i}")
        assert counters.sum() == 0
