"""The one wrap-aware distance of geoq, used by the kernels and the graph alike.

A dimension with period ``p > 0`` is a circle: the difference of two
coordinates is taken to its nearest image, ``wrap(d) = d - p * rint(d / p)``
(round half to even), so ``theta = pi`` and ``-pi`` coincide. ``p = 0`` marks
an ordinary dimension. :func:`wrap` is the definition (compiled, one scalar);
:func:`wrap_difference` applies it to numpy arrays with the same IEEE
operations, and ``tests/test_geometry.py`` pins the two to the same bits.

A leaf module: it imports nothing from geoq but the type aliases.
"""

from __future__ import annotations

import numba
import numpy as np

from geoq._typing import ArrayLike, FloatArray

__all__ = [
    "as_period_vector",
    "scaled_wrapped_squared_distances",
    "squared_distances_row",
    "wrap",
    "wrap_difference",
    "wrapped_r2",
    "wrapped_squared_distances",
]


def as_period_vector(period: ArrayLike | None, dim: int | None) -> FloatArray | None:
    """Per-dimension wrap-around periods ``[d]``; ``0`` or ``nan`` marks a non-periodic dim."""
    if period is None:
        return None
    arr = np.asarray(period, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"period must be a 1-D per-dimension array, got shape {arr.shape}")
    if dim is not None and arr.shape[0] != dim:
        raise ValueError(f"period has {arr.shape[0]} entries; expected {dim}")
    arr = np.where(np.isnan(arr), 0.0, arr)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError(f"period entries must be >= 0 (0 = not periodic), got {period!r}")
    return arr


@numba.njit(cache=True, nogil=True)
def wrap(diff: float, p: float) -> float:  # pragma: no cover - compiled
    """The difference ``diff`` taken to its nearest image on a circle of period ``p`` (if > 0)."""
    if p > 0.0:
        return diff - p * np.rint(diff / p)
    return diff


def wrap_difference(diff: FloatArray, period: FloatArray | float | None) -> FloatArray:
    """:func:`wrap` on an array of differences ``[..., d]`` with periods ``[d]``, one
    period for every entry (a scalar), or None (no periodic dimension)."""
    if period is None:
        return diff
    p = np.asarray(period, dtype=np.float64)
    if p.ndim == 0:
        return diff - p * np.rint(diff / p) if p > 0 else diff
    wrapped = diff - p * np.rint(diff / np.where(p > 0, p, 1.0))
    return np.where(p > 0, wrapped, diff)


@numba.njit(cache=True, nogil=True)
def wrapped_r2(
    x: FloatArray, Y: FloatArray, j: int, period: FloatArray
) -> float:  # pragma: no cover - compiled
    """``|x - Y_j|^2`` [scalar], each dimension wrapped by :func:`wrap`."""
    s = 0.0
    for k in range(x.shape[0]):
        diff = wrap(x[k] - Y[j, k], period[k])
        s += diff * diff
    return s


@numba.njit(cache=True, nogil=True)
def wrapped_squared_distances(
    X: FloatArray, Y: FloatArray, period: FloatArray
) -> FloatArray:  # pragma: no cover - compiled
    """``[N, d] x [M, d] -> [N, M]`` squared distances, each dimension wrapped by :func:`wrap`."""
    N, M = X.shape[0], Y.shape[0]
    out = np.empty((N, M))
    for i in range(N):
        for j in range(M):
            out[i, j] = wrapped_r2(X[i], Y, j, period)
    return out


@numba.njit(cache=True, nogil=True)
def scaled_wrapped_squared_distances(
    X: FloatArray, Y: FloatArray, period: FloatArray, scale: FloatArray
) -> FloatArray:  # pragma: no cover - compiled
    """``[N, d] x [M, d] -> [N, M]``: ``sum_k (wrap(x_k - y_k, p_k) / scale_k)^2``, summed
    over ``k`` in order (the squared-exponential kernel's distance on periodic inputs).

    The inner loop runs over the ``M`` columns of one dimension (``Y`` transposed, so
    contiguous, and the period test hoisted out of it): it vectorises. Each entry is
    summed in the same order as a per-pair loop over ``k`` would, so the result is the
    same to the bit."""
    N, M, d = X.shape[0], Y.shape[0], X.shape[1]
    Yt = np.ascontiguousarray(Y.T)  # [d, M]
    out = np.zeros((N, M))
    for i in range(N):
        row = out[i]
        for k in range(d):
            xk, p, s, yk = X[i, k], period[k], scale[k], Yt[k]
            if p > 0.0:
                for j in range(M):
                    diff = xk - yk[j]
                    diff = (diff - p * np.rint(diff / p)) / s
                    row[j] += diff * diff
            else:
                for j in range(M):
                    diff = (xk - yk[j]) / s
                    row[j] += diff * diff
    return out


@numba.njit(cache=True, nogil=True)
def squared_distances_row(
    x: FloatArray, X: FloatArray, n: int, period: FloatArray, r2: FloatArray, neg: FloatArray
) -> None:
    """``r2[j]`` = wrapped ``|x - X_j|^2`` (as :func:`wrapped_squared_distances`) and
    ``neg[j] = -r2[j]``, ``j < n``."""
    for j in range(n):
        s = wrapped_r2(x, X, j, period)
        r2[j] = s
        neg[j] = -s
