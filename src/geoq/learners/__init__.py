"""Q-function learners built on geoq.gp and geoq.kernels."""

from geoq.learners.q_gp import (
    KERNEL_NAMES,
    PAPER_KERNELS,
    GPQFunction,
    QGPConfig,
    make_kernel,
)
from geoq.learners.scaling import PENDULUM_SCALING, InputScaling

__all__ = [
    "KERNEL_NAMES",
    "PAPER_KERNELS",
    "PENDULUM_SCALING",
    "GPQFunction",
    "InputScaling",
    "QGPConfig",
    "make_kernel",
]
