"""The exploration map's constants (:class:`MapSettings`), each range checked."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoq._validation import check_int, check_real

__all__ = ["MapSettings"]


@dataclass(frozen=True)
class MapSettings:
    """The map's constants (docs/exploration.md, prototype 4, where each was measured)."""

    side_scale: float = 3.0
    """Grid side, in 0.9-quantiles of the observed ``|s' - s|`` per dimension."""
    quantile: float = 0.9
    """The quantile of the moves that reads "a typical move" (cell side, blocked test)."""
    blocked_fraction: float = 0.25
    """A move shorter than this x its candidate's typical move is blocked."""
    min_split_fraction: float = 1 / 16
    """No leaf narrower than this x the grid side."""
    blocked_cos: float = 0.7
    """An untried move is predicted blocked where one at this cosine or more was."""
    max_macro: int = 50
    """Most steps a predicted move is repeated to leave its leaf."""
    route_margin: float = 0.05
    """The exploit plan knows a route from a leaf valued above the lower bound by this
    fraction of the value range."""
    nearest_tries: bool = True
    """The greedy policy judges a move at a state by the nearest try of a move like it
    (within one typical move) as well as by its leaf's plan (:meth:`StateMap.greedy`)."""
    tol: float = 1e-3
    """Value iteration stops when no value moves more than this."""
    max_sweeps: int = 2000
    """Most sweeps of one value iteration."""

    def __post_init__(self) -> None:
        """Each constant's range, checked here (``ValueError`` naming it)."""
        check_real(self.side_scale, "side_scale", low=0.0, low_open=True)
        check_real(self.quantile, "quantile", low=0.0, high=1.0, low_open=True)
        check_real(self.blocked_fraction, "blocked_fraction", low=0.0, high=1.0)
        check_real(self.min_split_fraction, "min_split_fraction", low=0.0, high=1.0,
                   low_open=True)  # fmt: skip
        check_real(self.blocked_cos, "blocked_cos", low=-1.0, high=1.0)
        check_int(self.max_macro, "max_macro", 1)
        check_real(self.route_margin, "route_margin", low=0.0, high=1.0, high_open=True)
        if not isinstance(self.nearest_tries, bool | np.bool_):
            raise ValueError(f"nearest_tries must be True or False, got {self.nearest_tries!r}")
        check_real(self.tol, "tol", low=0.0, low_open=True)
        check_int(self.max_sweeps, "max_sweeps", 1)
