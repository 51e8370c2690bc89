"""Replay strategies of the fitted-Q phases (``GPQConfig.replay``), one object per mode.

* :class:`NoReplay` (``"none"``): the targets stay those computed online when each step
  was taken; a phase only refits the posterior to them.
* :class:`UniformReplay` (``"uniform"``): every stored transition is re-bootstrapped.
* :class:`GraphReplay` (``"graph"``): ``uniform`` plus transitions imagined by the
  graph's dynamics model (:mod:`geoq.agents.graph_replay`) for the actions not taken at
  the stored states of largest TD error.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from geoq._typing import FloatArray
from geoq.agents.buffer import Transitions
from geoq.agents.graph_replay import GraphModel, imagine_transitions
from geoq.agents.phase_inputs import PhaseInputs

__all__ = [
    "GraphReplay", "NextQ", "NoReplay", "ReplayStrategy", "UniformReplay", "replay_strategy",
]  # fmt: skip


class NextQ(Protocol):
    """What a strategy asks of the phase (a :class:`~geoq.agents.fitted_q.FittedQPhase`)."""

    def stored_next_q(self, inp: PhaseInputs) -> FloatArray:
        """Posterior mean of ``Q`` ``[N, K]`` at the stored next states x candidates."""
        ...


class ReplayStrategy(Protocol):
    """What a phase replays: the transitions it sweeps over, and whether it sweeps."""

    sweeps: bool
    """Whether the phase re-bootstraps the targets (fitted-Q sweeps)."""

    def extend(self, phase: NextQ, inp: PhaseInputs) -> tuple[Transitions, FloatArray, int | None]:
        """The transitions of the phase and their starting targets (the stored ones first),
        and the number of imagined ones (None: this strategy imagines none)."""
        ...


class NoReplay:
    """``replay="none"``: refit the posterior to the online targets, no sweeps."""

    sweeps = False

    def extend(self, phase: NextQ, inp: PhaseInputs) -> tuple[Transitions, FloatArray, int | None]:
        return inp.stored, inp.targets, None


class UniformReplay(NoReplay):
    """``replay="uniform"``: re-bootstrap every stored transition alike."""

    sweeps = True


class GraphReplay:
    """``replay="graph"``: the stored transitions and up to ``budget`` imagined ones.

    Sources are ranked by the absolute TD error of their stored target under the
    current posterior, ``|r + gamma (1 - term) max_k Q(s', a_k) - y|``; the imagined
    transitions start from the posterior mean at their inputs.
    """

    sweeps = True

    def __init__(self, gamma: float, budget: int, eps: float) -> None:
        self.gamma, self.budget, self.eps = gamma, budget, eps

    def extend(self, phase: NextQ, inp: PhaseInputs) -> tuple[Transitions, FloatArray, int | None]:
        stored, y0 = inp.stored, inp.targets
        continues = 1.0 - stored.terminated
        td = stored.rewards + self.gamma * continues * phase.stored_next_q(inp).max(axis=1) - y0
        model = GraphModel(
            units=np.asarray(inp.scaling.scale) * inp.lengthscale,
            periods=np.asarray(inp.scaling.periods), eps=self.eps,
            obs_low=inp.obs_low, obs_high=inp.obs_high,
        )  # fmt: skip
        im = imagine_transitions(stored, model, inp.candidates, np.abs(td), self.budget)
        if len(im) == 0:
            return stored, y0, 0
        y_im = inp.y_mean + inp.y_scale * inp.gp.predict(inp.inputs(im))
        return stored.then(im), np.concatenate([y0, np.clip(y_im, *inp.bounds)]), len(im)


def replay_strategy(replay: str, gamma: float, budget: int, eps: float) -> ReplayStrategy:
    """The strategy of ``GPQConfig.replay`` (``budget``, ``eps``: graph replay's)."""
    if replay == "graph":
        return GraphReplay(gamma, budget, eps)
    return UniformReplay() if replay == "uniform" else NoReplay()
