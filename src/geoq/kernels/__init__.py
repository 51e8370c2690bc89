"""Kernels ``k(X, Y=None) -> [n, m]``, ``k.diag(X) -> [n]``: a kernel is a profile of a distance."""

from geoq.kernels.base import (
    Distance,
    GaussianOfDistance,
    Kernel,
    kernel_from_arrays,
    kernel_to_arrays,
)
from geoq.kernels.factory import KERNEL_NAMES, PAPER_KERNELS, KernelName, make_kernel
from geoq.kernels.geodesic import GeodesicKernel
from geoq.kernels.graph_distance import GraphDistance
from geoq.kernels.graph_pd import ResistanceDistance, ResistanceKernel
from geoq.kernels.stationary import Euclidean, SquaredExponential

__all__ = [
    "KERNEL_NAMES",
    "PAPER_KERNELS",
    "Distance",
    "Euclidean",
    "GaussianOfDistance",
    "GeodesicKernel",
    "GraphDistance",
    "Kernel",
    "KernelName",
    "ResistanceDistance",
    "ResistanceKernel",
    "SquaredExponential",
    "kernel_from_arrays",
    "kernel_to_arrays",
    "make_kernel",
]
