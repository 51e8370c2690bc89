"""geoq: action-value functions learned by sparse online GPs with geodesic kernels.

Importing geoq registers its Gymnasium environments (``geoq/PendulumSwingUp-v0``,
``geoq/TwoRooms-v0``).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("geoq")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

import geoq.envs  # noqa: F401  (registers the geoq/ envs)

__all__ = ["__version__"]
