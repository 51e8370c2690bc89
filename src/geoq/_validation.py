"""Input validation at the public boundary.

Every public entry point converts its inputs with these helpers, so that a bad
input fails early with a message that says what was expected, and everything
downstream can assume C-contiguous, finite float64 arrays.
"""

from __future__ import annotations

import math
from numbers import Integral, Number, Real
from typing import Any

import numpy as np

from geoq._typing import ArrayLike, FloatArray

__all__ = [
    "MAX_BUDGET",
    "MAX_MAGNITUDE",
    "as_float_matrix",
    "as_float_point",
    "as_float_vector",
    "as_input_point",
    "as_inputs",
    "as_target",
    "as_targets",
    "check_budget",
    "check_count",
    "check_int",
    "check_learn_arguments",
    "check_magnitude",
    "check_nonnegative",
    "check_novelty_tol",
    "check_positive",
    "check_real",
    "check_seed",
]

#: Largest magnitude of a GP input coordinate or target: squares of differences of such
#: numbers (squared distances, deletion scores ``alpha^2``) stay inside float64
#: (``1e150^2 = 1e300 < 1.8e308``). Real data are far below; standardise or rescale.
MAX_MAGNITUDE = 1e150


def _check_finite(arr: FloatArray, name: str) -> None:
    if not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ValueError(f"{name} contains {bad} non-finite value(s) (NaN or inf); remove them")


def _to_float(value: ArrayLike, name: str) -> FloatArray:
    """``value`` as float64; only real numbers (bool, int, float) convert.

    Complex numbers (the imaginary part would be dropped), datetimes and
    timedeltas (they would become epoch counts), masked arrays (the mask would
    be lost), strings and objects are refused with a ``ValueError``.
    """
    if isinstance(value, np.ma.MaskedArray):
        raise ValueError(f"{name} is a masked array; fill or drop the masked entries first")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric, got {type(value).__name__}") from exc
    if raw.dtype.kind not in "biuf":
        what = {"c": "complex", "M": "datetime", "m": "timedelta"}.get(raw.dtype.kind)
        if what is not None:
            raise ValueError(f"{name} has {what} values (dtype {raw.dtype}); pass real numbers")
        if raw.dtype.kind != "O":
            raise ValueError(f"{name} must be numeric, got dtype {raw.dtype}")
        try:  # lists of numbers with None or mixed types: let numpy decide, once
            raw = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name} must be numeric, got {type(value).__name__}") from exc
    return np.asarray(raw, dtype=np.float64)


def as_float_matrix(X: ArrayLike, name: str = "X", n_cols: int | None = None) -> FloatArray:
    """Return ``X`` as a finite, C-contiguous float64 array of shape ``(n, d)``.

    A 1-D input is *not* silently reshaped: ambiguity between one point and
    many scalar points is an error.
    """
    arr = _to_float(X, name)
    if arr.ndim != 2:
        expected = f"(n, {n_cols})" if n_cols is not None else "(n, d)"
        raise ValueError(f"{name} has shape {arr.shape}; expected a 2-D array {expected}")
    if n_cols is not None and arr.shape[1] != n_cols:
        raise ValueError(f"{name} has shape {arr.shape}; expected (n, {n_cols})")
    _check_finite(arr, name)
    return np.ascontiguousarray(arr)


def as_float_vector(y: ArrayLike, name: str = "y", length: int | None = None) -> FloatArray:
    """Return ``y`` as a finite float64 array of shape ``(length,)``."""
    arr = _to_float(y, name)
    if arr.ndim != 1:
        raise ValueError(f"{name} has shape {arr.shape}; expected a 1-D array")
    if length is not None and arr.shape[0] != length:
        raise ValueError(f"{name} has {arr.shape[0]} entries; expected {length}")
    _check_finite(arr, name)
    return np.ascontiguousarray(arr)


def as_float_point(x: ArrayLike, name: str = "x", dim: int | None = None) -> FloatArray:
    """Return a single input point as a finite float64 array of shape ``(dim,)``."""
    arr = _to_float(x, name)
    if arr.ndim != 1:
        expected = f"({dim},)" if dim is not None else "(d,)"
        raise ValueError(f"{name} has shape {arr.shape}; expected one point of shape {expected}")
    if dim is not None and arr.shape[0] != dim:
        raise ValueError(f"{name} has shape {arr.shape}; expected ({dim},)")
    _check_finite(arr, name)
    return arr


def check_magnitude(arr: FloatArray, name: str, what: str) -> FloatArray:
    """``arr`` (finite) if every ``|value| <= MAX_MAGNITUDE``, else a ``ValueError``.

    ``what`` says what to do, e.g. ``"standardise them"``: past the bound squares of
    differences overflow float64 and results would be NaN or inf.
    """
    if arr.size and float(np.max(np.abs(arr))) > MAX_MAGNITUDE:
        raise ValueError(
            f"{name} must be below {MAX_MAGNITUDE:g} in magnitude (got "
            f"{float(np.max(np.abs(arr))):.3g}; squares of such numbers overflow float64): "
            f"{what}"
        )
    return arr


# What the GPs and kernels accept: finite real numbers of magnitude <= MAX_MAGNITUDE
# (squared distances and deletion scores stay inside float64).
def as_inputs(X: ArrayLike, name: str = "X", dim: int | None = None) -> FloatArray:
    """Inputs ``[n, dim]`` (:func:`as_float_matrix`) of magnitude <= ``MAX_MAGNITUDE``."""
    return check_magnitude(as_float_matrix(X, name, dim), name, "rescale the inputs")


def as_input_point(x: ArrayLike, dim: int | None = None) -> FloatArray:
    """One input ``x`` [dim] (:func:`as_float_point`) of magnitude <= ``MAX_MAGNITUDE``."""
    return check_magnitude(as_float_point(x, "x", dim), "x", "rescale the inputs")


def as_targets(y: ArrayLike, length: int) -> FloatArray:
    """Targets ``y`` [length] (:func:`as_float_vector`) of magnitude <= ``MAX_MAGNITUDE``."""
    return check_magnitude(as_float_vector(y, "y", length), "y", "standardise the targets")


def as_target(y: Any) -> FloatArray:
    """One target ``y`` as a 0-d float64 array, finite and of magnitude <= ``MAX_MAGNITUDE``."""
    try:
        ya = np.asarray(y, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"y must be a finite number, got {y!r}") from exc
    if ya.ndim != 0 or not np.isfinite(ya):
        raise ValueError(f"y must be one finite number, got {y!r}")
    return check_magnitude(ya, "y", "standardise the targets")


def check_positive(value: float, name: str) -> float:
    """Return ``float(value)`` if it is finite and > 0, else raise ``ValueError``."""
    v = float(value)
    if not np.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return v


def check_nonnegative(value: float, name: str) -> float:
    """Return ``float(value)`` if it is finite and >= 0, else raise ``ValueError``."""
    v = float(value)
    if not np.isfinite(v) or v < 0.0:
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return v


def check_count(value: Any, name: str) -> int:
    """``value`` as an int, if it is an integer >= 1 (not a bool); else ``ValueError``."""
    if isinstance(value, bool) or not isinstance(value, Integral) or int(value) < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def check_novelty_tol(tol: Any) -> float:
    """A GP's relative novelty threshold ``tol`` as a float in ``[0, 1]``; else ``ValueError``."""
    try:
        t = float(tol)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"tol must be a finite number >= 0, got {tol!r}") from exc
    if not np.isfinite(t) or t < 0.0 or t > 1.0:
        raise ValueError(
            f"tol must be a finite number >= 0 and <= 1 (a novelty threshold relative to "
            f"k(x, x): above 1 no point would ever become a basis vector), got {tol!r}"
        )
    return t


#: Largest basis budget a GP configuration accepts: a GP keeps a few [max_bv, max_bv]
#: float64 matrices (5000: ~200 MB each).
MAX_BUDGET = 5000


def check_int(value: Any, name: str, minimum: int, maximum: int | None = None) -> int:
    """``value`` as an int if it is an integer (not a bool) in ``[minimum, maximum]``."""
    ok = not isinstance(value, bool | np.bool_) and isinstance(value, Integral)
    if not ok or value < minimum or (maximum is not None and value > maximum):
        bound = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
        raise ValueError(f"{name} must be an integer {bound}, got {value!r}")
    return int(value)


def _budget_problem(value: Any) -> str | None:
    """What is wrong with ``value`` as a basis budget, or None if it is one."""

    def hint(whole: Any) -> str:  # an integral value written otherwise: what to write
        ok = isinstance(whole, int) and 1 <= whole <= MAX_BUDGET
        return f"; write {whole}" if ok else ""

    if isinstance(value, bool | np.bool_):
        return "a bool, not an integer"
    if isinstance(value, str):
        try:
            write = hint(int(value))
        except ValueError:  # not an integer's digits (or past int's 4300 of them)
            write = ""
        return f"not a number (a string{write}{' without quotes' if write else ''})"
    if not isinstance(value, Number):
        return f"not a number ({'None' if value is None else 'a ' + type(value).__name__})"
    if not isinstance(value, Integral):
        try:
            whole = int(value) if int(value) == value else None  # type: ignore[call-overload]
        except (ArithmeticError, ValueError, TypeError):  # nan, inf, complex
            whole = None
        return f"not an integer (a {type(value).__name__}{hint(whole)})"
    if int(value) < 1:
        return "below 1 (a GP needs at least one basis vector)"
    if int(value) > MAX_BUDGET:
        return f"above {MAX_BUDGET} (a GP of more basis vectors needs gigabytes)"
    return None


def check_budget(value: Any, name: str = "max_bv") -> int:
    """A basis-vector budget: an integer (not a bool) in ``[1, MAX_BUDGET]``, as an int.

    The ``ValueError`` says what is wrong: not a number, not an integer, below 1, or
    above ``MAX_BUDGET`` (only there: a GP of more basis vectors needs gigabytes).
    """
    problem = _budget_problem(value)
    if problem is not None:
        raise ValueError(
            f"{name} must be an integer in [1, {MAX_BUDGET}], got {value!r}: {problem}"
        )
    return int(value)


def check_real(
    value: Any,
    name: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """``value`` as a float if it is a finite real number (not a bool or a string) in range."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, Real):
        raise ValueError(f"{name} must be a number, got {value!r}")
    v = float(value)
    below = low is not None and (v <= low if low_open else v < low)
    above = high is not None and (v >= high if high_open else v > high)
    if not math.isfinite(v) or below or above:
        lo = "" if low is None else f"{'>' if low_open else '>='} {low:g}"
        hi = "" if high is None else f"{'<' if high_open else '<='} {high:g}"
        bounds = " and ".join(p for p in (lo, hi) if p)
        raise ValueError(f"{name} must be a finite number {bounds}, got {value!r}")
    return v


def check_seed(seed: Any) -> int | None:
    """``seed`` as a Python int: None or an integer >= 0 (NumPy's included, not a bool)."""
    if seed is None:
        return None
    if isinstance(seed, bool | np.bool_) or not isinstance(seed, Integral) or seed < 0:
        raise ValueError(
            f"seed must be None or an integer >= 0 (NumPy's SeedSequence entropy), got {seed!r}"
        )
    return int(seed)


def check_learn_arguments(total_timesteps: Any, progress_bar: Any, callback: Any) -> None:
    """The arguments of :meth:`GPQAgent.learn`, checked before any step."""
    check_int(total_timesteps, "total_timesteps", 0)
    if not isinstance(progress_bar, bool | np.bool_):
        raise ValueError(f"progress_bar must be True or False, got {progress_bar!r}")
    if callback is not None and not callable(callback):
        raise ValueError(
            "callback must be None or a function called with each finished episode's "
            f"EpisodeRecord (return False to stop), got {callback!r}"
        )
