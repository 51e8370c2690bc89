"""Oracle tests of the numerics helpers in :mod:`geoq.gp.numerics`."""

from __future__ import annotations

import numpy as np

from geoq.gp.numerics import project_whitened_covariance


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
