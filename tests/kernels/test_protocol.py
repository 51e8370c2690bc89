"""The GP's fast paths are chosen by what a kernel offers, not by its class."""

from __future__ import annotations

import numpy as np

from geoq.kernels import GeodesicKernel, SquaredExponential


class _PlainSubclass(SquaredExponential):
    """Computes exactly the SE: keeps the compiled loop."""


class _ScaledSE(SquaredExponential):
    """Changes what the kernel computes: must lose the compiled loop."""

    def _matrix(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        return 2.0 * super()._matrix(X, Y)


def test_se_parameters_offered_only_by_an_unchanged_squared_exponential() -> None:
    period = np.array([2 * np.pi, 0.0])
    se = SquaredExponential(lengthscale=[0.5, 2.0], variance=3.0, period=period)
    params = se.se_parameters()
    assert params is not None
    ls, per, var = params
    assert np.array_equal(ls, [0.5, 2.0]) and np.array_equal(per, period) and var == 3.0
    assert _PlainSubclass(lengthscale=0.5).se_parameters() == (0.5, None, 1.0)
    assert _ScaledSE(lengthscale=0.5).se_parameters() is None
    assert GeodesicKernel(eps=0.3).se_parameters() is None
    assert SquaredExponential().fused_row() is None
    assert GeodesicKernel(eps=0.3).fused_row() is not None
