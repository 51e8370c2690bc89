"""Gaussian processes: the sparse online GP (Csató & Opper 2002), the exact GP, numerics."""

from geoq.gp._resync import ProjectedSystem
from geoq.gp.exact import ExactGP
from geoq.gp.numerics import CONFIG, NotPSDError, NumericalWarning, NumericsConfig, safe_cholesky
from geoq.gp.sparse_online import OnlineDiagnostics, SparseOnlineGP

__all__ = [
    "CONFIG",
    "ExactGP",
    "NotPSDError",
    "NumericalWarning",
    "NumericsConfig",
    "OnlineDiagnostics",
    "ProjectedSystem",
    "SparseOnlineGP",
    "safe_cholesky",
]
