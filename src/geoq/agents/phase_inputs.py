"""What a fitted-Q phase reads of the agent (:class:`PhaseInputs`), one record per phase:
the phase (:mod:`geoq.agents.fitted_q`) and its replay strategy (:mod:`geoq.agents.replay`)
both read it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from geoq._typing import FloatArray
from geoq.agents.buffer import TransitionBuffer, Transitions
from geoq.agents.state import LearningState
from geoq.gp import SparseOnlineGP
from geoq.learners.scaling import InputScaling

__all__ = ["PhaseInputs", "phase_inputs_of"]


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


class _Agent(Protocol):
    """What :func:`phase_inputs_of` reads of a :class:`~geoq.agents.GPQAgent` (named by its
    members: the agent's module imports this one)."""

    gp: SparseOnlineGP
    buffer: TransitionBuffer
    scaling: InputScaling
    candidates: FloatArray
    obs_dim: int
    state: LearningState

    def value_bounds(self) -> tuple[float, float]: ...
    def _lengthscale(self) -> float | tuple[float, ...]: ...


def phase_inputs_of(
    agent: _Agent, stored: Transitions, obs_box: tuple[FloatArray | None, FloatArray | None]
) -> PhaseInputs:
    """What a phase on ``stored`` (``agent``'s window's transitions) reads of ``agent``, whose
    env's observation box is ``obs_box`` (``(None, None)``: not a Box)."""
    bounds = agent.value_bounds()
    lengthscale = np.asarray(agent._lengthscale(), dtype=np.float64)
    return PhaseInputs(
        gp=agent.gp, stored=stored, n_seen=len(agent.buffer), bounds=bounds,
        targets=np.clip(agent.buffer.targets(last=len(stored)), *bounds),  # warm start
        scaling=agent.scaling, candidates=agent.candidates, obs_dim=agent.obs_dim,
        lengthscale=np.broadcast_to(lengthscale, (agent.scaling.dim,)),
        obs_low=obs_box[0], obs_high=obs_box[1], y_mean=agent.state.y_mean,
        y_scale=agent.state.y_scale,
    )  # fmt: skip
