"""``libm_square``: the C library's ``pow(x, 2)``, elementwise, equals scalar arithmetic."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from geoq.tasks._libm import libm_square, scalar_square


@settings(max_examples=200, deadline=None)
@given(
    arrays(
        st.sampled_from([np.float64, np.float32]),
        st.integers(0, 40),
        elements=st.floats(-(2.0**60), 2.0**60, width=32),  # squares below float32's overflow
    )
)
def test_equals_numpy_scalar_power_bit_for_bit(x: np.ndarray) -> None:
    np.testing.assert_array_equal(libm_square(x), scalar_square(x), strict=True)


def test_equals_scalars_where_array_power_does_not() -> None:
    rng = np.random.default_rng(0)
    for dtype in (np.float64, np.float32):
        x = rng.normal(0.0, 3.0, 20_000).astype(dtype)
        got = libm_square(x)
        assert got.dtype == dtype
        np.testing.assert_array_equal(got, [v**2 for v in x])
    x64 = rng.normal(0.0, 3.0, 20_000)
    np.testing.assert_array_equal(libm_square(x64), [math.pow(v, 2) for v in x64.tolist()])


def test_shapes_and_dtypes() -> None:
    x = np.arange(12.0).reshape(3, 4)[:, ::2]  # not contiguous
    np.testing.assert_array_equal(libm_square(x), scalar_square(x))
    assert libm_square(np.float32(1.5)).shape == ()
    assert libm_square(np.zeros((0, 2))).shape == (0, 2)
    with pytest.raises(TypeError, match="float64 or float32"):
        libm_square(np.arange(3))
