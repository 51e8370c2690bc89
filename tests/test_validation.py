"""Input conversion at the public boundary: only real numbers become float64."""

from __future__ import annotations

import numpy as np
import pytest

from geoq._validation import as_float_matrix, as_float_vector
from geoq.gp import ExactGP, SparseOnlineGP
from geoq.kernels import SquaredExponential


@pytest.mark.parametrize(
    ("value", "match"),
    [
        (np.array([[1.0 + 1j, 2.0]]), "complex"),
        (np.array([["2020-01-01", "2020-01-02"]], dtype="datetime64[D]"), "datetime"),
        (np.array([[1, 2]], dtype="timedelta64[s]"), "timedelta"),
        (np.ma.masked_array([[1.0, 2.0]], mask=[[False, True]]), "masked"),
        (np.array([["a", "b"]]), "numeric"),
    ],
)
def test_non_real_inputs_are_refused(value: np.ndarray, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        as_float_matrix(value, "X")
    with pytest.raises(ValueError, match=match):
        as_float_vector(value.reshape(-1), "y")


def test_real_inputs_still_convert() -> None:
    np.testing.assert_array_equal(as_float_matrix([[1, 2]], "X"), [[1.0, 2.0]])
    np.testing.assert_array_equal(as_float_vector([True, False], "y"), [1.0, 0.0])
    with pytest.raises(ValueError, match="non-finite"):
        as_float_vector([1.0, None], "y")


def test_gps_refuse_complex_data_and_keep_their_state() -> None:
    X = np.linspace(0, 1, 8)[:, None]
    gp = SparseOnlineGP(SquaredExponential(0.3), noise=0.01, max_bv=5).fit(X, np.sin(X[:, 0]))
    before = gp.predict(X)
    with pytest.raises(ValueError, match="complex"):
        gp.update(np.array([0.5 + 0.1j]), 1.0)
    with pytest.raises(ValueError, match="complex"):
        gp.fit(X, np.sin(X[:, 0]) + 0j)
    np.testing.assert_array_equal(gp.predict(X), before)
    with pytest.raises(ValueError, match="complex"):
        ExactGP(SquaredExponential(0.3), noise=0.01).fit(X.astype(complex), np.zeros(8))
