"""What a fitted-Q phase reads of the agent (:class:`PhaseInputs`), one record per phase:
the phase (:mod:`geoq.agents.fitted_q`) and its replay strategy (:mod:`geoq.agents.replay`)
both read it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoq._typing import FloatArray
from geoq.agents.buffer import Transitions
from geoq.gp import SparseOnlineGP
from geoq.learners.scaling import InputScaling

__all__ = ["PhaseInputs"]


@dataclass(frozen=True)
class PhaseInputs:
    """What a fitted-Q phase reads of the agent (one record per phase).

    Attributes
    ----------
    gp : the agent's GP (the phase refits it).
    stored : the window's transitions (``N``), oldest first.
    targets : their last targets ``[N]``, clipped to ``bounds`` (the warm start).
    n_seen : transitions stored in all (the window's first is number ``n_seen - N``).
    scaling, candidates, obs_dim : the agent's input scaling, candidate actions
        ``[K, d_a]`` and observation size.
    lengthscale : the squared exponential's length-scale per input ``[d]`` (graph units).
    obs_low, obs_high : the observation space's bounds ``[d_s]`` (None: not a Box).
    y_mean, y_scale, bounds : the standardisation in use and the value bounds.
    """

    gp: SparseOnlineGP
    stored: Transitions
    targets: FloatArray
    n_seen: int
    scaling: InputScaling
    candidates: FloatArray
    obs_dim: int
    lengthscale: FloatArray
    obs_low: FloatArray | None
    obs_high: FloatArray | None
    y_mean: float
    y_scale: float
    bounds: tuple[float, float]

    def inputs(self, data: Transitions) -> FloatArray:
        """Scaled GP inputs ``[n, d]`` of ``data``'s state-action pairs."""
        return self.scaling.transform(np.hstack([data.states, data.actions]))
