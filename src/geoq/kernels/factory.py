"""Kernels by name: the four a Q-function learner or an agent can use."""

from __future__ import annotations

from typing import Literal

import numpy as np

from geoq._typing import ArrayLike, FloatArray
from geoq.kernels.base import Kernel
from geoq.kernels.geodesic import GeodesicKernel
from geoq.kernels.graph_pd import ResistanceKernel
from geoq.kernels.stationary import SquaredExponential

__all__ = ["KERNEL_NAMES", "PAPER_KERNELS", "KernelName", "make_kernel"]

#: The paper's three kernels (the values of ``kernel`` in ``fig3.csv``).
PAPER_KERNELS: tuple[str, ...] = ("euclidean", "nearest", "interpolated")
#: Every kernel a learner can use: the paper's and the positive-definite graph kernel.
KERNEL_NAMES: tuple[str, ...] = (*PAPER_KERNELS, "resistance")
KernelName = Literal["euclidean", "nearest", "interpolated", "resistance"]


def make_kernel(
    name: KernelName,
    *,
    lengthscale: float | ArrayLike = 1.0,
    amplitude: float = 1.0,
    eps: float = 0.3,
    sigma_sp: float = 1.0,
    sigma_se: float = 0.01,
    resistance_lengthscale: float = 1.0,
    period: FloatArray | None = None,
    normalize_weights: bool = False,
    attach_weights: bool = False,
    temporal_edges: bool = False,
) -> Kernel:
    """A fresh kernel (a graph kernel owns its graph: one per GP).

    ``euclidean``: :class:`SquaredExponential` (``lengthscale``, one or one per input);
    ``nearest`` / ``interpolated``: :class:`GeodesicKernel` (JC12 eq. 4 / 5; ``eps``,
    ``sigma_sp``, ``sigma_se``, ``normalize_weights``, ``attach_weights``);
    ``resistance``: :class:`ResistanceKernel` (``eps``, ``resistance_lengthscale``).
    ``amplitude`` is every kernel's prior variance; ``period`` ``[d]`` the wrap-around
    period of each input (0 = none; None: no input wraps).
    """
    if name == "euclidean":
        return SquaredExponential(
            lengthscale=np.asarray(lengthscale, dtype=np.float64),
            variance=amplitude,
            period=period,
        )
    if name == "resistance":
        return ResistanceKernel(
            eps=eps,
            lengthscale=resistance_lengthscale,
            amplitude=amplitude,
            period=period,
            temporal_edges=temporal_edges,
        )
    if name in ("nearest", "interpolated"):
        return GeodesicKernel(
            eps=eps,
            method=name,
            sigma_sp=sigma_sp,
            sigma_se=sigma_se,
            amplitude=amplitude,
            normalize=normalize_weights,
            attach=attach_weights,
            period=period,
            temporal_edges=temporal_edges,
        )
    raise ValueError(f"kernel must be one of {KERNEL_NAMES}, got {name!r}")
