"""A feedback policy searched through a model (PILCO's loop, with a sampling search).

PILCO (Deisenroth & Rasmussen 2011) learns a GP model of the steps, then a policy by
the model's predicted return over a long horizon from the task's start states, acts
with it for an episode and repeats. Here the policy is :class:`LinearFeedback`,
``a = mid + half * tanh(K [z, 1])`` with ``z`` the state standardised by the model's
data, and its gains ``K`` [d_a, d_s + 1] are searched by the cross-entropy method
(:func:`search_gains`) rather than PILCO's analytic gradients: each candidate's score is
the mean undiscounted return of ``particles`` sampled roll-outs
(:func:`~geoq.models.planner.rollout_returns`: trajectory sampling, halted where the
model has no data), from start states drawn among the episodes' first states, every
candidate seeing the same starts and the same normals (common random numbers, fixed
for the whole search: a comparison is not drowned by the draws' noise).

Where a short plan cannot see far, a policy can: ``InvertedPendulum-v5``'s plans drove
the cart into its stop beyond their horizon (docs/design-notes.md); a policy scored
over hundreds of model steps must keep the cart where the model has data, since a
roll-out that leaves it is halted at the least reward.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoq._typing import FloatArray
from geoq._validation import as_float_matrix, as_float_vector, check_int, check_real
from geoq.models.dynamics import GPDynamicsModel
from geoq.models.planner import rollout_returns

__all__ = [
    "HOLDOUT_SE",
    "LinearFeedback",
    "PolicySearchSettings",
    "policy_returns",
    "search_gains",
]

#: Standard errors by which a search's winner must beat the current gains on fresh draws.
HOLDOUT_SE = 2.0


@dataclass(frozen=True)
class PolicySearchSettings:
    """The gains' search (cross-entropy method over ``K``; gains in units of the
    standardised state per half-range of the action box)."""

    horizon: int = 300
    """Model steps of each roll-out (capped at the task's time limit by the caller)."""
    particles: int = 16
    """Sampled roll-outs per candidate."""
    candidates: int = 32
    """Gains scored per iteration."""
    iterations: int = 8
    """Refits of the sampling Gaussian per search."""
    elites: int = 4
    """Best candidates the Gaussian is refitted to."""
    init_std: float = 1.0
    """The Gaussian's first std around the current gains."""
    min_std: float = 0.05
    """Least std after a refit."""
    patience: int = 2
    """Stop after this many iterations in a row that found nothing better."""
    holdout: bool = True
    """Keep the current gains unless the search's best beats them on fresh draws too."""

    def __post_init__(self) -> None:
        check_int(self.horizon, "horizon", minimum=1, maximum=100_000)
        check_int(self.particles, "particles", minimum=1, maximum=100_000)
        check_int(self.candidates, "candidates", minimum=3, maximum=100_000)
        check_int(self.iterations, "iterations", minimum=1, maximum=1000)
        check_int(self.elites, "elites", minimum=1, maximum=self.candidates)
        check_int(self.patience, "patience", minimum=1, maximum=1000)
        check_real(self.init_std, "init_std", low=0.0, high=100.0)
        check_real(self.min_std, "min_std", low=0.0, high=100.0)


class FeedbackBase:
    """What a feedback policy acts in: the action box ``[low, high]`` (its ``mid`` and
    ``half`` [d_a]) and the states' standardisation ``z = (s - center) / scale`` [d_s]."""

    def __init__(self, low: FloatArray, high: FloatArray, center: FloatArray, scale: FloatArray):
        low = as_float_vector(low, "low")
        high = as_float_vector(high, "high", low.shape[0])
        if np.any(high <= low):
            raise ValueError("the action box must have high > low in every dimension")
        self.center = as_float_vector(center, "center")
        self.scale = as_float_vector(scale, "scale", self.center.shape[0])
        if np.any(self.scale <= 0.0):
            raise ValueError("scale must be positive in every dimension")
        self.mid, self.half = (high + low) / 2.0, (high - low) / 2.0


class LinearFeedback(FeedbackBase):
    """``a = mid + half * tanh(K [z, 1])``, ``z = (s - center) / scale``: actions inside
    the box ``[low, high]`` for any gains ``K`` [d_a, d_s + 1]."""

    @property
    def shape(self) -> tuple[int, int]:
        """The gains' shape ``(d_a, d_s + 1)``."""
        return self.mid.shape[0], self.center.shape[0] + 1

    def features(self, S: FloatArray) -> FloatArray:
        """``[z, 1]`` ``[P, d_s + 1]`` of states ``[P, d_s]``."""
        z = (S - self.center) / self.scale
        return np.hstack([z, np.ones((z.shape[0], 1))])

    def act(self, gains: FloatArray, S: FloatArray) -> FloatArray:
        """Actions ``[P, d_a]`` of one policy's gains ``[d_a, d_s + 1]`` at states ``[P, d_s]``."""
        return self.act_rows(np.broadcast_to(gains, (S.shape[0], *gains.shape)), S)

    def act_rows(self, gains: FloatArray, S: FloatArray) -> FloatArray:
        """Actions ``[N, d_a]`` of ``N`` states ``[N, d_s]``, each under its own gains
        ``[N, d_a, d_s + 1]``. Each action is its own sum over the features, so a state
        is acted on bit for bit alike whatever else is in the batch (what the search
        scored is what the agent does)."""
        y = np.sum(self.features(S)[:, None, :] * gains, axis=-1)  # [N, d_a]
        return self.mid + self.half * np.tanh(y)


def policy_returns(
    model: GPDynamicsModel,
    policy: LinearFeedback,
    gains: FloatArray,
    starts: FloatArray,
    normals: FloatArray,
) -> FloatArray:
    """Undiscounted model returns ``[C, P]`` of ``C`` gains ``[C, d_a, d_s + 1]``, each from
    every start ``[P, d_s]``, over ``T`` steps of sampled roll-outs whose state changes
    take the standard normals ``normals`` [T, P, d_s] (the same for every candidate)."""
    C, P = gains.shape[0], starts.shape[0]
    T = normals.shape[0]
    flat_starts = np.tile(starts, (C, 1))  # candidate c's particles: rows c P .. (c + 1) P - 1
    flat_normals = np.tile(normals, (1, C, 1))

    def act(t: int, S: FloatArray, rows: np.ndarray) -> FloatArray:
        return policy.act_rows(gains[rows // P], S)

    total = rollout_returns(model, flat_starts, act, T, gamma=1.0, noise=flat_normals)
    return total.reshape(C, P)


def search_gains(
    model: GPDynamicsModel,
    policy: LinearFeedback,
    gains: FloatArray,
    starts: FloatArray,
    rng: np.random.Generator,
    settings: PolicySearchSettings | None = None,
) -> tuple[FloatArray, float]:
    """The best gains ``[d_a, d_s + 1]`` found from ``gains`` by the cross-entropy method,
    and their score (the mean of :func:`policy_returns`). The search draws ``particles``
    starts from ``starts`` [N, d_s] and the roll-outs' normals once, and scores every candidate on
    those same draws (PEGASUS, Ng & Jordan 2000: a fixed sample of scenarios makes the
    scores comparable across iterations, so the best is not the luckiest draw). Each
    iteration scores the current mean, the best so far and ``candidates - 2`` draws
    around the mean, and refits the Gaussian to the ``elites``; the search stops early
    once ``patience`` iterations in a row found nothing better. Ties keep the earlier
    candidate: the current gains stay unless something scores higher. With
    ``settings.holdout`` the winner must then beat the current gains again on fresh
    draws (the best of many on one sample is flattered by it), by more than
    :data:`HOLDOUT_SE` standard errors of the particles' paired differences (a policy
    that works is not traded for one that differs on a single lucky particle), and the
    score returned is the kept gains' on those fresh draws."""
    c = settings or PolicySearchSettings()
    gains = as_float_matrix(gains, "gains", policy.shape[1])
    if gains.shape != policy.shape:
        raise ValueError(f"gains must have shape {policy.shape}, got {gains.shape}")
    starts = as_float_matrix(starts, "starts", model.obs_dim)
    mean, std = gains.copy(), np.full(policy.shape, c.init_std)
    best, best_value = gains.copy(), -np.inf
    picked = starts[rng.integers(len(starts), size=c.particles)]
    normals = rng.standard_normal((c.horizon, c.particles, model.obs_dim))
    stale = 0  # iterations in a row without a better best
    for _ in range(c.iterations):
        if stale >= c.patience:
            break
        candidates = mean + std * rng.standard_normal((c.candidates, *policy.shape))
        candidates[0], candidates[1] = mean, best
        values = policy_returns(model, policy, candidates, picked, normals).mean(axis=1)
        values = np.where(np.isnan(values), -np.inf, values)  # a diverged roll-out loses
        order = np.argsort(-values, kind="stable")
        stale += 1
        if values[order[0]] > best_value:
            best, best_value, stale = candidates[order[0]].copy(), float(values[order[0]]), 0
        elite = candidates[order[: c.elites]]
        mean, std = elite.mean(axis=0), np.maximum(elite.std(axis=0), c.min_std)
    if not c.holdout:
        return best, best_value
    picked = starts[rng.integers(len(starts), size=c.particles)]
    normals = rng.standard_normal((c.horizon, c.particles, model.obs_dim))
    fresh = policy_returns(model, policy, np.stack([gains, best]), picked, normals)
    gain = fresh[1] - fresh[0]  # paired: the same starts and draws [P]
    se = gain.std(ddof=1) / np.sqrt(len(gain)) if len(gain) > 1 else 0.0
    if gain.mean() > HOLDOUT_SE * se:
        return best, float(fresh[1].mean())
    return gains, float(fresh[0].mean())
