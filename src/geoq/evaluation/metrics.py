"""Error and uncertainty metrics of value-function estimates (paper Fig. 3)."""

from __future__ import annotations

import numpy as np
from scipy import stats

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import as_float_vector

__all__ = ["mean_confidence_interval", "mse", "normalized_variance"]


def mse(predicted: ArrayLike, target: ArrayLike) -> float:
    """Mean squared error ``mean((predicted - target)^2)`` over ``N`` pairs (Fig. 3a)."""
    p = as_float_vector(predicted, "predicted")
    t = as_float_vector(target, "target", length=p.shape[0])
    if p.shape[0] == 0:
        raise ValueError("mse of zero pairs is undefined")
    return float(np.mean((p - t) ** 2))


def normalized_variance(variance: ArrayLike, prior_variance: ArrayLike) -> float:
    """Mean ratio of posterior to prior variance, ``mean(var_i / prior_var_i)`` (Fig. 3b).

    ``1`` means the model learned nothing at the test points, ``0`` that it is
    certain. ``prior_variance`` is ``k(x_i, x_i)`` (a scalar broadcasts).
    """
    v = as_float_vector(variance, "variance")
    prior = np.broadcast_to(np.asarray(prior_variance, dtype=np.float64), v.shape)
    if v.shape[0] == 0:
        raise ValueError("normalized_variance of zero points is undefined")
    if np.any(v < 0):
        raise ValueError("variance must be >= 0")
    if not np.all(np.isfinite(prior)) or np.any(prior <= 0):
        raise ValueError("prior_variance must be finite and > 0")
    return float(np.mean(v / prior))


def mean_confidence_interval(
    samples: ArrayLike, level: float = 0.95, axis: int = 0
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Mean and Student-t confidence interval over independent runs (e.g. seeds).

    Returns ``(mean, low, high)`` reduced along ``axis``; needs >= 2 samples.
    """
    x = np.asarray(samples, dtype=np.float64)
    n = x.shape[axis]
    if n < 2:
        raise ValueError(f"need >= 2 samples along axis {axis} for an interval, got {n}")
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    mean = np.mean(x, axis=axis)
    sem = np.std(x, axis=axis, ddof=1) / np.sqrt(n)
    half = stats.t.ppf(0.5 + level / 2.0, df=n - 1) * sem
    return mean, mean - half, mean + half
