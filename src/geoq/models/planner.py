"""Planning through a model: the cross-entropy method over action sequences.

At each decision :class:`CEMPlanner` draws ``samples`` action sequences of
``horizon + 1`` actions from a Gaussian per step and action dimension, scores them
(``score``: the caller's, e.g. :func:`model_returns`), refits the Gaussian to the
``elites`` best and repeats ``iterations`` times (the cross-entropy method, as in
PETS: Chua et al. 2018); it takes the mean's first action. The mean is kept, shifted
by one step, as the next decision's start (warm start), and the previous mean is
always one of the samples. Sequences live in the action box's centred coordinates
``[-1, 1]`` and are clipped to it.

:func:`model_returns` scores sequences by a model's predicted return, closed by a
value: ``sum_{t<H} gamma^t r_t + gamma^H V(s_H, a_H)``, where the last action of a
sequence is the one the value is asked about (TD-MPC's terminal ``Q(z_H, pi(z_H))``,
Hansen et al. 2022). Where the model does not know, a roll-out halts: the
probability of stopping at a step is the largest fraction of its prior variance an
output's GP keeps there (0 on the data, 1 far from it, in the metric of that output's
length-scales: an input an output ignores does not make it unknown), and a halted
particle gets ``floor``, the least value any return can have (MOReL's halt, Kidambi
et al. 2020). A predicted termination ends a particle's return after the step's
reward. The state changes are sampled from the model's predictive Gaussian, one draw
per particle and step (trajectory sampling, PETS).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from geoq._typing import FloatArray
from geoq._validation import as_float_vector, check_int, check_real
from geoq.models.dynamics import GPDynamicsModel

__all__ = ["CEMPlanner", "PlannerSettings", "model_returns"]

#: The value of ``P`` states ``[P, d_s]`` and actions ``[P, d_a]`` after the horizon.
TerminalValue = Callable[[FloatArray, FloatArray], FloatArray]


@dataclass(frozen=True)
class PlannerSettings:
    """The cross-entropy method's settings (actions in centred units, ``[-1, 1]``)."""

    horizon: int = 10
    """Model steps before the terminal value."""
    samples: int = 64
    """Action sequences scored per iteration."""
    iterations: int = 3
    """Refits of the sampling Gaussian per decision."""
    elites: int = 8
    """Best sequences the Gaussian is refitted to."""
    init_std: float = 0.5
    """The Gaussian's first std, in half-ranges of the action box."""
    min_std: float = 0.05
    """Least std after a refit (keeps the search from collapsing onto one sequence)."""

    def __post_init__(self) -> None:
        check_int(self.horizon, "horizon", minimum=0, maximum=1000)
        check_int(self.samples, "samples", minimum=2, maximum=100_000)
        check_int(self.iterations, "iterations", minimum=1, maximum=1000)
        check_int(self.elites, "elites", minimum=1, maximum=self.samples)
        check_real(self.init_std, "init_std", low=0.0, high=10.0)
        check_real(self.min_std, "min_std", low=0.0, high=10.0)


class CEMPlanner:
    """The cross-entropy method over ``horizon + 1`` actions in the box ``[low, high]``.

    ``mean`` [H + 1, d_a] (centred units) is the warm start of the next decision; None
    after :meth:`reset` (an episode's start), when the search starts at the box's centre.
    """

    def __init__(self, low: FloatArray, high: FloatArray, settings: PlannerSettings | None = None):
        self.low = as_float_vector(low, "low")
        self.high = as_float_vector(high, "high", self.low.shape[0])
        if np.any(self.high <= self.low):
            raise ValueError("the action box must have high > low in every dimension")
        self.settings = settings or PlannerSettings()
        self.mean: FloatArray | None = None

    def reset(self) -> None:
        """Forget the warm start (a new episode)."""
        self.mean = None

    def actions(self, U: FloatArray) -> FloatArray:
        """Actions in the box from centred ones ``U`` [..., d_a]."""
        return self.low + (U + 1.0) * 0.5 * (self.high - self.low)

    def plan(
        self, score: Callable[[FloatArray], FloatArray], rng: np.random.Generator
    ) -> FloatArray:
        """The first action ``[d_a]`` of the best sequence found. ``score`` maps actions
        ``[P, H + 1, d_a]`` (in the box) to ``[P]`` values, higher better."""
        c, d = self.settings, self.low.shape[0]
        mean = np.zeros((c.horizon + 1, d)) if self.mean is None else self.mean
        std = np.full_like(mean, c.init_std)
        for _ in range(c.iterations):
            U = np.clip(mean + std * rng.standard_normal((c.samples, *mean.shape)), -1.0, 1.0)
            U[0] = mean
            values = np.asarray(score(self.actions(U)), dtype=np.float64)
            if values.shape != (c.samples,):
                raise ValueError(f"score returned shape {values.shape}; expected ({c.samples},)")
            values = np.where(np.isnan(values), -np.inf, values)
            elite = U[np.argsort(-values, kind="stable")[: c.elites]]
            mean, std = elite.mean(axis=0), np.maximum(elite.std(axis=0), c.min_std)
        self.mean = np.vstack([mean[1:], mean[-1:]])
        return self.actions(mean[0])


def model_returns(
    model: GPDynamicsModel,
    state: FloatArray,
    actions: FloatArray,
    *,
    gamma: float,
    value: TerminalValue | None,
    floor: float,
    rng: np.random.Generator | None,
) -> FloatArray:
    """Predicted returns ``[P]`` of action sequences ``[P, H + 1, d_a]`` from ``state``
    [d_s] (module docstring). ``rng``: draws of the state changes (None: their means);
    ``value``: the terminal value (None: 0); ``floor``: a halted particle's value."""
    P, H1, _ = actions.shape
    d = model.obs_dim
    S = np.repeat(state[None, :], P, axis=0)
    alive, total = np.ones(P), np.zeros(P)
    prior = np.where(model.prior_std > 0, model.prior_std, np.inf)  # [J]
    for t in range(H1 - 1):
        mean, std = model.predict(S, actions[:, t])
        p_end = np.clip(mean[:, d + 1], 0.0, 1.0)
        unknown = np.clip(np.max((std / prior) ** 2, axis=1), 0.0, 1.0)
        total += gamma**t * alive * (mean[:, d] + gamma * (1.0 - p_end) * unknown * floor)
        alive = alive * (1.0 - p_end) * (1.0 - unknown)
        step = (
            mean[:, :d] if rng is None else mean[:, :d] + std[:, :d] * rng.standard_normal((P, d))
        )
        S = S + step
    if value is not None:
        total += gamma ** (H1 - 1) * alive * value(S, actions[:, -1])
    return total
