"""Input conversion at the public boundary: only real numbers become float64."""

from __future__ import annotations

from decimal import Decimal
from fractions import Fraction
from numbers import Integral, Number
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tests._fuzz import fuzz_settings

from geoq._validation import MAX_BUDGET, as_float_matrix, as_float_vector, check_budget, check_int
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


# Budgets (B13): each wrong kind of max_bv is told what is wrong with it; the note that a
# GP of more basis vectors needs gigabytes is for integers above MAX_BUDGET only.
BUDGET_VALUES = st.one_of(
    st.integers(-10, MAX_BUDGET + 10),
    st.integers(),
    st.booleans(),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-10, MAX_BUDGET + 10).map(float),
    st.integers(-10, MAX_BUDGET + 10).map(np.int64),
    st.integers(-10, MAX_BUDGET + 10).map(np.float64),
    st.integers(-10, MAX_BUDGET + 10).map(lambda n: Fraction(n, 1)),
    st.integers(-10, MAX_BUDGET + 10).map(str),
    st.text(max_size=6),
    st.sampled_from([None, [3], (3,), {"max_bv": 3}, 1j, 3 + 0j, np.True_, Decimal("4"),
                     Decimal("NaN"), b"10", Fraction(5, 2)]),
)  # fmt: skip


def _is_int(value: Any) -> bool:
    return isinstance(value, Integral) and not isinstance(value, bool | np.bool_)


@fuzz_settings(300)
@given(value=BUDGET_VALUES)
def test_a_budget_is_accepted_as_check_int_does_and_refused_with_its_own_reason(
    value: Any,
) -> None:
    try:
        expected = check_int(value, "max_bv", 1, MAX_BUDGET)
    except ValueError:
        expected = None
    if expected is not None:
        got = check_budget(value)
        assert got == expected and type(got) is int
        return
    with pytest.raises(ValueError) as info:
        check_budget(value)
    message = str(info.value)
    assert message.startswith(f"max_bv must be an integer in [1, {MAX_BUDGET}], got {value!r}: ")
    reason = message.split(f"got {value!r}: ", 1)[1]
    assert ("gigabytes" in message) == (_is_int(value) and value > MAX_BUDGET), message
    if isinstance(value, bool | np.bool_):
        assert reason == "a bool, not an integer"
    elif not isinstance(value, Number):
        assert reason.startswith("not a number")
    elif not _is_int(value):
        assert reason.startswith("not an integer")
    elif value < 1:
        assert reason.startswith("below 1")
    else:
        assert reason.startswith(f"above {MAX_BUDGET}")


@pytest.mark.parametrize(
    ("value", "reason"),
    [
        ("10", "not a number (a string; write 10 without quotes)"),
        ("ten", "not a number (a string)"),
        (True, "a bool, not an integer"),
        (20.0, "not an integer (a float; write 20)"),
        (2.5, "not an integer (a float)"),
        (0, "below 1 (a GP needs at least one basis vector)"),
        (MAX_BUDGET + 1, f"above {MAX_BUDGET} (a GP of more basis vectors needs gigabytes)"),
    ],
)
def test_every_maker_of_a_gp_says_what_is_wrong_with_a_budget(value: Any, reason: str) -> None:
    from geoq.agents import GPQAgent, GPQConfig

    expected = f"max_bv must be an integer in [1, {MAX_BUDGET}], got {value!r}: {reason}"
    makers = (
        lambda: check_budget(value),
        lambda: GPQConfig(max_bv=value),
        lambda: GPQConfig.from_dict({"max_bv": value}),
        lambda: GPQAgent("geoq/TwoRooms-v0", max_bv=value),
        lambda: SparseOnlineGP(SquaredExponential(0.3), noise=0.1, max_bv=value),
    )
    for make in makers:
        with pytest.raises(ValueError) as info:
            make()
        assert str(info.value) == expected
