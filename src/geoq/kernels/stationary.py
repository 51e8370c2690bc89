"""Euclidean distance (optionally wrap-aware) and the squared-exponential kernel."""

from __future__ import annotations

import numpy as np
import scipy.spatial.distance

from geoq._geometry import as_period_vector, scaled_wrapped_squared_distances, wrap_difference
from geoq._typing import ArrayLike, FloatArray
from geoq.kernels.base import Distance, GaussianOfDistance, SEParameters

__all__ = ["Euclidean", "SquaredExponential", "as_period_vector", "as_scale_vector"]


def as_scale_vector(value: ArrayLike, name: str) -> tuple[float | FloatArray, int | None]:
    """A positive scalar, or a positive per-dimension vector ``[d]`` (which fixes ``d``)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] == 0):
        raise ValueError(
            f"{name} must be a scalar or a 1-D per-dimension array, got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    with np.errstate(over="ignore", divide="ignore"):
        reciprocal_overflows = not np.all(np.isfinite(1.0 / arr))
    if reciprocal_overflows:  # subnormal: 0 * (1 / scale) would be NaN in every distance
        raise ValueError(
            f"{name} must be >= {1.0 / np.finfo(np.float64).max:.3g} (1/{name} overflows "
            f"float64 below), got {value!r}; rescale the inputs instead"
        )
    if arr.ndim == 0:
        return float(arr), None
    return arr.copy(), int(arr.shape[0])


class Euclidean(Distance):
    """``r^2(x, x') = sum_k ((x_k - x'_k) / scale_k)^2``, optionally wrap-aware.

    Parameters
    ----------
    scale : positive scalar or per-dimension array ``[d]`` (a length-scale).
    period : optional per-dimension period ``[d]`` (in input units, before
        scaling); ``0`` marks an ordinary dimension. On a periodic dimension the
        difference is taken on the circle (:func:`geoq._geometry.wrap`): ``theta = pi``
        and ``-pi`` coincide.
    """

    def __init__(self, scale: ArrayLike = 1.0, period: ArrayLike | None = None) -> None:
        self.scale, self.input_dim = as_scale_vector(scale, "scale")
        self.period = as_period_vector(period, self.input_dim)
        if self.period is not None and self.input_dim is None:
            self.input_dim = int(self.period.shape[0])

    def _scaled_difference(self, diff: FloatArray) -> FloatArray:
        return wrap_difference(diff, self.period) / self.scale

    def squared(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        if self.period is None:
            with np.errstate(over="ignore"):
                Xs, Ys = X / self.scale, Y / self.scale
            if np.isfinite(Xs).all() and np.isfinite(Ys).all():
                return scipy.spatial.distance.cdist(Xs, Ys, "sqeuclidean")
            # A tiny scale overflowed x / scale (inf - inf would be NaN): difference first;
            # the squared distances are then inf where they overflow, never NaN.
            with np.errstate(over="ignore"):
                diff = (X[:, None, :] - Y[None, :, :]) / self.scale  # [n, m, d]
                return np.einsum("ijk,ijk->ij", diff, diff)
        # Compiled: numpy's per-dimension passes are mostly call overhead on the small
        # matrices of an agent step; tests/test_geometry.py pins the bits to numpy's.
        scale = np.broadcast_to(np.asarray(self.scale, dtype=np.float64), (X.shape[1],))
        return scaled_wrapped_squared_distances(
            np.ascontiguousarray(X),
            np.ascontiguousarray(Y),
            self.period,
            np.ascontiguousarray(scale),
        )

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {"scale": np.asarray(self.scale)}
        if self.period is not None:
            out["period"] = self.period
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> Euclidean:
        return cls(scale=arrays["scale"], period=arrays.get("period"))

    def __repr__(self) -> str:
        return f"Euclidean(scale={self.scale!r}, period={self.period!r})"


class SquaredExponential(GaussianOfDistance):
    """``k(x, x') = variance * exp(-||x - x'||^2 / (2 lengthscale^2))``.

    Parameters
    ----------
    lengthscale : positive scalar or per-dimension array ``[d]`` (ARD).
    variance : prior variance ``k(x, x)``.
    period : optional per-dimension wrap-around period (see :class:`Euclidean`).
    """

    def __init__(
        self, lengthscale: ArrayLike = 1.0, variance: float = 1.0, period: ArrayLike | None = None
    ) -> None:
        super().__init__(Euclidean(scale=lengthscale, period=period), variance=variance)

    @property
    def lengthscale(self) -> float | FloatArray:
        assert isinstance(self.distance, Euclidean)
        return self.distance.scale

    @property
    def period(self) -> FloatArray | None:
        assert isinstance(self.distance, Euclidean)
        return self.distance.period

    def restricted(self, dims: slice, variance: float = 1.0) -> SquaredExponential:
        """The same kernel on input dimensions ``dims`` only, with prior variance ``variance``.

        The kernel is a product over dimensions, so it is the product of its restrictions
        to complementary sets of dimensions whose variances multiply to its own (up to
        rounding: ``exp(a) exp(b)`` for ``exp(a + b)``).
        """
        ls = self.lengthscale
        return SquaredExponential(
            lengthscale=ls if np.ndim(ls) == 0 else np.asarray(ls)[dims],
            variance=variance,
            period=None if self.period is None else self.period[dims],
        )

    def se_parameters(self) -> SEParameters | None:
        """``(lengthscale, period, variance)``, unless a subclass changed what the kernel
        computes (then the GP must call it)."""
        cls = type(self)
        if (
            cls._matrix is not GaussianOfDistance._matrix
            or cls.to_basis is not GaussianOfDistance.to_basis
            or cls._diag is not GaussianOfDistance._diag
            or type(self.distance) is not Euclidean
        ):
            return None
        return self.lengthscale, self.period, self.variance

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {"lengthscale": np.asarray(self.lengthscale), "variance": np.asarray(self.variance)}
        if self.period is not None:
            out["period"] = self.period
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> SquaredExponential:
        return cls(
            lengthscale=arrays["lengthscale"],
            variance=float(arrays["variance"]),
            period=arrays.get("period"),
        )

    def __repr__(self) -> str:
        return f"SquaredExponential(lengthscale={self.lengthscale!r}, variance={self.variance:g})"
