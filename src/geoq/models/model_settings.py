"""The settings of a :class:`~geoq.models.GPDynamicsModel`, and how an archive holds them."""

from __future__ import annotations

from dataclasses import dataclass

from geoq._validation import check_int, check_real

__all__ = ["ModelSettings", "settings_from"]


@dataclass(frozen=True)
class ModelSettings:
    """How each output's GP is made."""

    max_bv: int = 200
    """Basis-vector budget of each output's sparse online GP."""
    fit_points: int = 300
    """Transitions the evidence is computed on (``O(fit_points^3)`` per evaluation)."""
    restarts: int = 1
    """Further starts of each evidence fit."""
    tol: float = 1e-6
    """Relative novelty a transition needs to become a basis vector (0 with ``max_bv``
    at least the transitions' count: every one is kept, the exact GP)."""
    linear_mean: bool = False
    """Each output's prior mean a linear function of the inputs, fitted by least squares
    (the GP learns what it leaves); False: the data's mean."""
    outlier_mads: float = 0.0
    """A transition whose state change lies more than this many robust deviations (MADs)
    from the least-squares line is left out of the state changes' GPs (0: none is)."""
    standardised_support: bool = False
    """Measure the support in the states standardised by the data, every input counting
    alike; False: in the outputs' shortest length-scales, so that an input no output
    depends on counts for nothing (module docstring)."""
    support_holdout: float = 0.0
    """The newest fraction of the transitions calibrates the support's spacing: the 99th
    percentile of their states' distances to the older ones, never less than at the last
    fit (a settled policy's new states lie on its old path); 0: of the seen states' own
    nearest-neighbour distances, which along trajectories measure a step, not the data's
    reach."""
    residual_noise: bool = True
    """Where a streamed posterior's mean misses its own transitions by more than the
    evidence's noise (a mean squared residual above the noise variance), stream them again
    with that residual as the noise; False: the evidence's noise however the budget fits
    (as archives before the setting were fitted)."""

    def __post_init__(self) -> None:
        check_int(self.max_bv, "max_bv", minimum=1, maximum=5000)
        check_int(self.fit_points, "fit_points", minimum=2, maximum=5000)
        check_int(self.restarts, "restarts", minimum=0, maximum=100)
        check_real(self.tol, "tol", low=0.0, high=1.0)
        check_real(self.outlier_mads, "outlier_mads", low=0.0, high=1e6)
        check_real(self.support_holdout, "support_holdout", low=0.0, high=0.9)


def settings_from(stored: list[float]) -> ModelSettings:
    """:class:`ModelSettings` from an archive's numbers (4 before linear means, 5 before the
    outlier test, 6 before the standardised support, 7 before the support's holdout, 8
    before the residual noise)."""
    if len(stored) not in (4, 5, 6, 7, 8, 9):
        raise ValueError(f"settings must hold 4 to 9 numbers, got {len(stored)}")
    padded = (*stored, 0.0, 0.0, 0.0, 0.0, 0.0)[:9]  # what an older archive did not have: off
    max_bv, fit_points, restarts, tol, linear_mean, mads, standardised, holdout, residual = padded
    flags = (("linear_mean", linear_mean), ("standardised_support", standardised),
             ("residual_noise", residual))  # fmt: skip
    for name, flag in flags:
        if flag not in (0.0, 1.0):
            raise ValueError(f"settings' {name} must be 0 or 1, got {flag}")
    return ModelSettings(int(max_bv), int(fit_points), int(restarts), tol, linear_mean == 1.0,
                         mads, standardised == 1.0, holdout, residual == 1.0)  # fmt: skip
