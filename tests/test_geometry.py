"""The one wrap-aware distance: compiled and numpy forms agree bit for bit, and every
user (SE kernel, graph, graph kernels) computes the same distances with it."""

from __future__ import annotations

import numpy as np
import pytest

from geoq._geometry import (
    as_period_vector,
    scaled_wrapped_squared_distances,
    wrap,
    wrap_difference,
    wrapped_squared_distances,
)
from geoq.graph import MDPGraph
from geoq.kernels.stationary import Euclidean

PERIOD = np.array([2 * np.pi, 0.0, 3.0])


def _differences(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random differences plus the hard cases: exact half-period ties and multiples."""
    d = rng.uniform(-20.0, 20.0, (n, 3))
    ties = np.array([[k * 0.5 * p for p in (2 * np.pi, 1.0, 3.0)] for k in range(-7, 8)])
    return np.vstack([d, ties, -ties, np.zeros((1, 3))])


def test_numpy_wrap_is_the_compiled_wrap_bit_for_bit() -> None:
    diff = _differences(np.random.default_rng(0), 500)
    vec = wrap_difference(diff, PERIOD)
    for c, p in enumerate(PERIOD):
        scalar = wrap_difference(diff[:, c], float(p))
        compiled = np.array([wrap(float(v), float(p)) for v in diff[:, c]])
        assert np.array_equal(vec[:, c], compiled)
        assert np.array_equal(scalar, compiled)
    assert wrap_difference(diff, None) is diff


def test_wrap_is_the_nearest_image() -> None:
    diff = _differences(np.random.default_rng(1), 500)
    w = wrap_difference(diff, PERIOD)
    for c, p in enumerate(PERIOD):
        if p == 0.0:
            assert np.array_equal(w[:, c], diff[:, c])
            continue
        assert np.all(np.abs(w[:, c]) <= 0.5 * p * (1 + 1e-12))
        k = (diff[:, c] - w[:, c]) / p  # a whole number of periods was removed
        assert np.allclose(k, np.round(k), rtol=0, atol=1e-9)
    assert wrap(np.pi - (-np.pi), 2 * np.pi) == 0.0  # theta = pi and -pi coincide


def test_every_user_computes_the_same_wrapped_distances() -> None:
    rng = np.random.default_rng(2)
    X = rng.uniform(-4, 4, (30, 3))
    Y = rng.uniform(-4, 4, (20, 3))
    r2 = wrapped_squared_distances(X, Y, PERIOD)
    assert np.array_equal(Euclidean(scale=1.0, period=PERIOD).squared(X, Y), r2)
    assert np.array_equal(MDPGraph(eps=0.3, period=PERIOD).squared_distances(X, Y), r2)


def test_period_vector_validation() -> None:
    assert as_period_vector(None, 3) is None
    assert np.array_equal(as_period_vector([1.0, np.nan], None), [1.0, 0.0])
    with pytest.raises(ValueError, match="entries"):
        as_period_vector([1.0, 2.0], 3)
    with pytest.raises(ValueError, match=">= 0"):
        as_period_vector([-1.0], None)


def test_scaled_compiled_distances_are_numpys_per_dimension_passes_bit_for_bit() -> None:
    """The SE kernel's compiled periodic distance equals the numpy reference it replaced:
    per dimension, wrap, divide by the length-scale, square, add in dimension order."""
    rng = np.random.default_rng(3)
    X = np.vstack([rng.uniform(-9, 9, (40, 3)), _differences(rng, 0)[:15]])
    Y = rng.uniform(-9, 9, (25, 3))
    scale = np.array([0.3, 1.7, 0.05])
    reference = np.zeros((len(X), len(Y)))
    for k, p in enumerate(PERIOD):
        diff = wrap_difference(np.subtract.outer(X[:, k], Y[:, k]), float(p)) / scale[k]
        reference += diff * diff
    got = Euclidean(scale=scale, period=PERIOD).squared(X, Y)
    assert np.array_equal(got, reference)
    assert np.array_equal(scaled_wrapped_squared_distances(X, Y, PERIOD, scale), reference)
