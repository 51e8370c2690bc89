"""``planner="policy"`` and ``"policy-net"``: a feedback policy searched through the model.

PILCO's loop (Deisenroth & Rasmussen 2011) on the agent's
:class:`~geoq.models.GPDynamicsModel`: at the start of an episode, once the warm-up is
over and at least :data:`SEARCH_EVERY` transitions have arrived since the last search
(or none was made), the policy is searched again from the current one, scored by the
model's return over ``config.policy_horizon`` steps from the episodes' first states.
``policy``: the model is refitted to the stored transitions first, and the gains of a
:class:`~geoq.models.LinearFeedback` policy are searched by the cross-entropy method
(:func:`~geoq.models.search_gains`). ``policy-net``: the weights of a
:class:`~geoq.models.MLPFeedback` are searched by gradients
(:func:`~geoq.models.search_policy`) through a model of :data:`NET_MODEL`'s settings,
fitted on :class:`~geoq.agents.model_planning.ModelPlanning`'s schedule. Training
actions are the policy's plus Gaussian noise of :data:`EXPLORATION` half-ranges
(clipped to the box); greedy actions are the policy's, with no roll-out.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from geoq._typing import FloatArray
from geoq.models import (
    GPDynamicsModel,
    LinearFeedback,
    MLPFeedback,
    ModelSettings,
    PolicyGradientSettings,
    PolicySearchSettings,
    search_gains,
    search_policy,
)

__all__ = ["EXPLORATION", "NET_MODEL", "SEARCH_EVERY", "FeedbackPlanning"]

#: Least number of new transitions between two searches.
SEARCH_EVERY = 100
#: Std of the training actions' noise, in half-ranges of the action box.
EXPLORATION = 0.1
#: The model a ``policy-net`` search reads: the support in standardised states,
#: calibrated by the newest fifth of the data (a new episode's states lie farther from
#: the old ones than a trajectory's steps from each other), and the rare jumps at a
#: joint's stop left out of the state changes' GPs (docs/design-notes.md, part four).
NET_MODEL = ModelSettings(standardised_support=True, support_holdout=0.2, outlier_mads=6.0)


class FeedbackPlanning:
    """The episodes' start states ``starts`` [N, d_s], the policy (None before the first
    search; ``net``: an :class:`~geoq.models.MLPFeedback`, else a
    :class:`~geoq.models.LinearFeedback`), its weights ``gains`` ([d_a, d_s + 1], or the
    network's ``[n_params]``) and score ``value`` (nan before), and ``searched_at``
    (transitions stored at the last search)."""

    def __init__(self, obs_dim: int, low: FloatArray, high: FloatArray, horizon: int,
                 net: bool = False):  # fmt: skip
        self.low, self.high, self.net = low, high, net
        self.settings = PolicySearchSettings(horizon=horizon)
        self.gradient_settings = PolicyGradientSettings(horizon=horizon)
        self.starts = np.zeros((0, obs_dim))
        self.policy: LinearFeedback | MLPFeedback | None = None
        self.gains = np.zeros((low.shape[0], obs_dim + 1))
        self.value, self.searched_at = float("nan"), 0

    def due(self, n: int) -> bool:
        """Whether a search is due with ``n`` transitions stored."""
        return self.policy is None or n - self.searched_at >= SEARCH_EVERY

    def _make(self, center: FloatArray, scale: FloatArray) -> LinearFeedback | MLPFeedback:
        kind = MLPFeedback if self.net else LinearFeedback
        return kind(self.low, self.high, center, scale)

    def search(self, model: GPDynamicsModel, n: int, rng: np.random.Generator) -> None:
        """Search the gains through ``model`` (fitted on ``n`` transitions), from the current."""
        if self.policy is None:  # the standardisation is fixed at the first search
            d = model.obs_dim
            self.policy = self._make(model.x_mean[:d], model.x_scale[:d])
            if isinstance(self.policy, MLPFeedback):
                self.gains = self.policy.initial(rng)
        if isinstance(self.policy, MLPFeedback):
            self.gains, self.value = search_policy(model, self.policy, self.gains, self.starts,
                                                   rng, self.gradient_settings)  # fmt: skip
        else:
            self.gains, self.value = search_gains(model, self.policy, self.gains, self.starts,
                                                  rng, self.settings)  # fmt: skip
        self.searched_at = n

    def action(self, s: FloatArray, rng: np.random.Generator | None) -> FloatArray:
        """The policy's action ``[1, d_a]`` at ``s`` [1, d_s]; with ``rng`` plus the noise."""
        assert self.policy is not None
        a = self.policy.act(self.gains, s)
        if rng is None:
            return a
        noise = EXPLORATION * self.policy.half * rng.standard_normal(a.shape)
        return np.clip(a + noise, self.low, self.high)

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> dict[str, Any]:
        """The starts, and once searched the policy, its gains and their score."""
        arrays: dict[str, Any] = {"policy_starts": self.starts}
        if self.policy is not None:
            arrays |= {
                "policy_center": self.policy.center, "policy_scale": self.policy.scale,
                "policy_gains": self.gains, "policy_value": np.array(self.value),
                "policy_searched_at": np.array(self.searched_at),
            }  # fmt: skip
        return arrays

    def restore(self, a: dict[str, Any]) -> None:
        """Inverse of :meth:`to_arrays` (``ValueError`` where it does not fit)."""
        starts = np.asarray(a.get("policy_starts", self.starts), dtype=np.float64)
        if starts.ndim != 2 or starts.shape[1] != self.starts.shape[1]:
            raise ValueError(f"policy_starts must be [N, {self.starts.shape[1]}]")
        if not np.all(np.isfinite(starts)):
            raise ValueError("policy_starts must be finite")
        self.starts = starts
        if "policy_gains" not in a:
            return
        policy = self._make(a["policy_center"], a["policy_scale"])
        gains = np.asarray(a["policy_gains"], dtype=np.float64)
        shape = (policy.n_params,) if isinstance(policy, MLPFeedback) else policy.shape
        if gains.shape != shape or not np.all(np.isfinite(gains)):
            raise ValueError(f"policy_gains must be finite of shape {shape}")
        self.policy, self.gains = policy, gains
        self.value, self.searched_at = float(a["policy_value"]), int(a["policy_searched_at"])
