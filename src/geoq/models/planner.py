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
Hansen et al. 2022). Where the model has no data, a roll-out halts (MOReL's halt,
Kidambi et al. 2020): a predicted state farther from every state seen than the data's
own spacing (:class:`~geoq.models.support.StateSupport`) stops with probability
``min(distance / spacing - 1, 1)``, and a halted particle is paid the least reward
seen (``model.reward_range[0]``) for every model step left, then ``value_floor`` if a
value closes the plan: the worst the plan could score from there. (The least value
of a whole discounted return instead, tried first, made ``Reacher-v5``'s plans too
timid to move the arm.) The termination output, a GP regression of 0/1 flags, is
read as a classifier at 1/2 (least-squares classification, Rasmussen & Williams 2006,
§6.5): a predicted termination ends a particle's return after the step's reward.
Roll-outs follow the model's means, or with ``rng`` draws from its predictive
Gaussians, one per particle and step (trajectory sampling, PETS).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from geoq._typing import FloatArray
from geoq._validation import as_float_vector, check_int, check_real
from geoq.models.dynamics import GPDynamicsModel

__all__ = ["CEMPlanner", "PlannerSettings", "model_returns", "rollout_outcomes", "rollout_returns"]

#: The value of ``P`` states ``[P, d_s]`` and actions ``[P, d_a]`` after the horizon.
TerminalValue = Callable[[FloatArray, FloatArray], FloatArray]
#: The actions ``[N, d_a]`` at model step ``t`` of the particles ``rows`` [N] (indices
#: among all of them) from their states ``[N, d_s]``.
ActionRule = Callable[[int, FloatArray, np.ndarray], FloatArray]


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
    keep_elites: bool = True
    """Carry each iteration's elites into the next iteration's samples, and the last
    decision's, shifted by one step, into the next decision's (iCEM, Pinneri et al. 2020)."""
    act_best: bool = False
    """Take the first action of the best sequence scored (iCEM) instead of the mean's."""
    noise_beta: float = 0.0
    """Colour of the sampling noise along the horizon: power ``1 / f^beta`` (0: white;
    iCEM's 2: smooth sequences)."""

    def __post_init__(self) -> None:
        check_int(self.horizon, "horizon", minimum=0, maximum=1000)
        check_int(self.samples, "samples", minimum=2, maximum=100_000)
        check_int(self.iterations, "iterations", minimum=1, maximum=1000)
        check_int(self.elites, "elites", minimum=1, maximum=self.samples)
        check_real(self.init_std, "init_std", low=0.0, high=10.0)
        check_real(self.min_std, "min_std", low=0.0, high=10.0)
        check_real(self.noise_beta, "noise_beta", low=0.0, high=10.0)
        if self.keep_elites and self.elites >= self.samples:
            raise ValueError("keep_elites needs elites < samples (the kept ones replace samples)")


class CEMPlanner:
    """The cross-entropy method over ``horizon + 1`` actions in the box ``[low, high]``.

    ``mean`` [H + 1, d_a] (centred units) is the warm start of the next decision, and
    ``elites`` [E, H + 1, d_a] the last decision's best sequences, shifted (with
    ``keep_elites``); both None after :meth:`reset` (an episode's start), when the search
    starts at the box's centre.
    """

    def __init__(self, low: FloatArray, high: FloatArray, settings: PlannerSettings | None = None):
        self.low = as_float_vector(low, "low")
        self.high = as_float_vector(high, "high", self.low.shape[0])
        if np.any(self.high <= self.low):
            raise ValueError("the action box must have high > low in every dimension")
        self.settings = settings or PlannerSettings()
        self.mean: FloatArray | None = None
        self.elites: FloatArray | None = None

    def reset(self) -> None:
        """Forget the warm start (a new episode)."""
        self.mean = self.elites = None

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
        kept = self.elites if c.keep_elites else None
        best, best_value = mean, -np.inf
        for _ in range(c.iterations):
            noise = _noise(rng, (c.samples, *mean.shape), c.noise_beta)
            U = np.clip(mean + std * noise, -1.0, 1.0)
            U[0] = mean
            if kept is not None:
                U[1 : 1 + len(kept)] = kept
            values = np.asarray(score(self.actions(U)), dtype=np.float64)
            if values.shape != (c.samples,):
                raise ValueError(f"score returned shape {values.shape}; expected ({c.samples},)")
            values = np.where(np.isnan(values), -np.inf, values)
            order = np.argsort(-values, kind="stable")
            if values[order[0]] > best_value:
                best, best_value = U[order[0]], values[order[0]]
            elite = U[order[: c.elites]]
            mean, std = elite.mean(axis=0), np.maximum(elite.std(axis=0), c.min_std)
            kept = elite if c.keep_elites else None
        self.mean = np.vstack([mean[1:], mean[-1:]])
        if kept is not None:
            self.elites = np.concatenate([kept[:, 1:], kept[:, -1:]], axis=1)
        return self.actions(best[0] if c.act_best else mean[0])


def _noise(rng: np.random.Generator, shape: tuple[int, ...], beta: float) -> FloatArray:
    """Standard normal noise ``shape`` = [P, T, d], coloured along ``T`` with power
    ``1 / f^beta`` (scaled to unit variance over the draw); white at 0."""
    if beta == 0.0 or shape[1] < 2:
        return rng.standard_normal(shape)
    T = shape[1]
    f = np.fft.rfftfreq(T)
    f[0] = f[1]  # the constant component gets the lowest frequency's power
    amp = f ** (-beta / 2.0)
    spectrum = rng.standard_normal((shape[0], len(f), shape[2])) + 1j * rng.standard_normal(
        (shape[0], len(f), shape[2])
    )
    x = np.fft.irfft(spectrum * amp[None, :, None], n=T, axis=1)  # circular: stationary
    return x / np.sqrt(np.mean(x**2))


def model_returns(
    model: GPDynamicsModel,
    state: FloatArray,
    actions: FloatArray,
    *,
    gamma: float,
    value: TerminalValue | None,
    value_floor: float = 0.0,
    rng: np.random.Generator | None,
) -> FloatArray:
    """Predicted returns ``[P]`` of action sequences ``[P, H + 1, d_a]`` from ``state``
    [d_s] (module docstring). ``rng``: draws of the state changes (None: their means);
    ``value``: the terminal value (None: 0) and ``value_floor`` its least."""
    P, H1, _ = actions.shape
    starts = np.repeat(state[None, :], P, axis=0)
    return rollout_returns(model, starts, lambda t, S, rows: actions[rows, t], H1 - 1, gamma=gamma,
                           value=value, value_floor=value_floor, noise=rng)  # fmt: skip


def rollout_returns(
    model: GPDynamicsModel,
    starts: FloatArray,
    act: ActionRule,
    horizon: int,
    *,
    gamma: float,
    value: TerminalValue | None = None,
    value_floor: float = 0.0,
    noise: np.random.Generator | FloatArray | None,
) -> FloatArray:
    """Predicted returns ``[P]`` of ``P`` particles from ``starts`` [P, d_s], each step's
    actions chosen by ``act(t, S, rows)`` from the states ``S`` of the particles ``rows``
    still running (open loop: a sequence's ``t``-th action; closed loop: a feedback
    policy), over ``horizon`` model steps, halted and ended as the module docstring says;
    a particle that has ended or halted for sure is not stepped further. ``noise``: None
    follows the model's means; a generator draws the state changes' standard normals
    ``[P, d_s]`` each step while any particle runs (every particle's, so the stream does
    not depend on which are running); an array ``[horizon, P, d_s]`` gives them (common
    random numbers).
    ``value`` (None: 0) is asked about the states after the horizon and the actions
    ``act(horizon, S, rows)``; ``value_floor`` is its least."""
    return rollout_outcomes(model, starts, act, horizon, gamma=gamma, value=value,
                            value_floor=value_floor, noise=noise)[0]  # fmt: skip


def rollout_outcomes(
    model: GPDynamicsModel,
    starts: FloatArray,
    act: ActionRule,
    horizon: int,
    *,
    gamma: float,
    value: TerminalValue | None = None,
    value_floor: float = 0.0,
    noise: np.random.Generator | FloatArray | None,
    trust_ends: bool = True,
) -> tuple[FloatArray, FloatArray]:
    """:func:`rollout_returns`'s returns ``[P]``, and the steps each particle's halts were
    paid the least reward for ``[P]`` (discounted, weighted by the halts' probabilities):
    the same roll-outs with a halt paid ``c`` a step return ``returns + steps * (c -
    model.reward_range[0])``, so the returns' range over what a halt could be worth is
    read off one roll-out. ``trust_ends`` False: an end predicted at a state beyond
    the data is no more believed than the state is, so the step's halt probability is
    paid as a halt whether it ends or not, and the end counts on the rest (True, as
    :func:`rollout_returns`: an end is believed wherever it is predicted)."""
    P, d = starts.shape
    S = starts.copy()
    alive, total, halted = np.ones(P), np.zeros(P), np.zeros(P)
    r_least = float(model.reward_range[0])
    after = gamma**horizon * value_floor if value is not None else 0.0
    rows = np.arange(P)
    for t in range(horizon):
        rows = rows[alive[rows] > 0.0]
        if rows.size == 0:
            return total, halted
        s, a = S[rows], act(t, S[rows], rows)
        if noise is None:
            mean = model.predict_mean(s, a)
            s = s + mean[:, :d]
        else:
            normals = (
                noise.standard_normal((P, d))
                if isinstance(noise, np.random.Generator)
                else noise[t]
            )
            mean, s = model.draw(s, a, normals[rows])
        S[rows] = s
        ends = mean[:, d + 1] > 0.5
        unknown = np.clip(model.support.distance(s) - 1.0, 0.0, 1.0)
        if trust_ends:  # an end is believed wherever it is predicted
            unknown = np.where(ends, 0.0, unknown)
        steps_left = sum(gamma**k for k in range(t + 1, horizon))
        rest = steps_left * r_least + after  # halted after t
        total[rows] += alive[rows] * (gamma**t * mean[:, d] + unknown * rest)
        halted[rows] += alive[rows] * unknown * steps_left
        alive[rows] = alive[rows] * ~ends * (1.0 - unknown)
    rows = rows[alive[rows] > 0.0]
    if value is not None and rows.size:
        total[rows] += gamma**horizon * alive[rows] * value(S[rows], act(horizon, S[rows], rows))
    return total, halted
