"""Roll-outs of a policy, vectorised over many roll-outs, and discounted returns.

A roll-out of ``H`` steps records ``(s_t, a_t, r_t, s_{t+1})`` for
``t = 0 .. H-1`` and the Monte-Carlo targets of the paper (§3),

    y_t = sum_{i=0}^{H-1-t} gamma^i r_{t+i},

the discounted return *truncated at the end of the roll-out* (the paper's
``y_t = sum_{i=0}^{H-t} gamma^i R_{t+i}`` with 1-based ``t``). Near the end of
a roll-out ``y_t`` therefore under-counts ``Q^pi(s_t, a_t)``, exactly as in the
paper; :mod:`geoq.evaluation` computes the untruncated ``Q^pi``.

The default discount is ``gamma = 0.95`` (:data:`DEFAULT_GAMMA`): an effective
horizon ``1 / (1 - gamma) = 20`` steps = 1 s, long enough for ``Q`` to see
whether the pendulum is about to be caught or to fall, short enough for the
paper's 250-step roll-outs to give mostly untruncated targets.

All randomness comes from the :class:`numpy.random.Generator` passed in, drawn
in a fixed order (start states, then one policy call per time step for all
roll-outs at once), so the same seed gives bit-identical roll-outs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np

from geoq._typing import ArrayLike, FloatArray
from geoq.envs.pendulum import PendulumParams, pendulum_step, sample_hanging_states
from geoq.policies import Policy

__all__ = [
    "DEFAULT_GAMMA",
    "Rollout",
    "StartSpec",
    "StepFn",
    "collect_rollouts",
    "discounted_returns",
    "initial_states",
    "resolve_step",
    "to_training_data",
]

#: Default discount factor of geoq's experiments.
DEFAULT_GAMMA = 0.95

#: ``(states [N, d], actions [N]) -> (next_states [N, d], rewards [N])``, pure and vectorised.
StepFn = Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]

#: Start states: ``None`` (hanging down, seeded noise), one state ``[d]``, one per
#: roll-out ``[n, d]``, or a sampler ``(rng, n) -> [n, d]``.
StartSpec = ArrayLike | Callable[[np.random.Generator, int], FloatArray] | None


@dataclass(frozen=True)
class Rollout:
    """One roll-out of ``H`` steps (arrays are read-only).

    Attributes
    ----------
    states : ``[H, d]`` states ``s_t``.
    actions : ``[H]`` actions ``a_t`` as taken (after the policy's clipping).
    rewards : ``[H]`` rewards ``r_t = r(s_t, a_t)``.
    next_states : ``[H, d]`` states ``s_{t+1}``.
    returns : ``[H]`` truncated discounted returns ``y_t`` (module docstring).
    gamma : the discount used for ``returns``.
    """

    states: FloatArray
    actions: FloatArray
    rewards: FloatArray
    next_states: FloatArray
    returns: FloatArray
    gamma: float

    def __post_init__(self) -> None:
        h = self.actions.shape[0]
        shapes_ok = (
            self.states.ndim == 2
            and self.states.shape[0] == h
            and self.next_states.shape == self.states.shape
            and self.actions.shape == self.rewards.shape == self.returns.shape == (h,)
        )
        if not shapes_ok:
            raise ValueError(
                "Rollout arrays disagree: states and next_states must be [H, d] and "
                f"actions, rewards, returns [H]; got {self.states.shape}, "
                f"{self.next_states.shape}, {self.actions.shape}, {self.rewards.shape}, "
                f"{self.returns.shape}"
            )
        for arr in (self.states, self.actions, self.rewards, self.next_states, self.returns):
            arr.flags.writeable = False

    def __len__(self) -> int:
        return int(self.actions.shape[0])

    @property
    def inputs(self) -> FloatArray:
        """State-action pairs ``x_t = [s_t, a_t]``, shape ``[H, d + 1]`` (the GP inputs)."""
        return np.column_stack([self.states, self.actions])


def discounted_returns(rewards: ArrayLike, gamma: float) -> FloatArray:
    """Truncated discounted returns along the last axis.

    ``y[..., t] = sum_{i=0}^{H-1-t} gamma^i rewards[..., t+i]`` for rewards of
    shape ``[..., H]``; computed by the backward recursion
    ``y_t = r_t + gamma y_{t+1}``, ``y_H = 0``.
    """
    r = np.asarray(rewards, dtype=np.float64)
    if r.ndim == 0:
        raise ValueError("rewards must have at least one axis (time is the last axis)")
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"gamma must be in [0, 1], got {gamma!r}")
    y = np.empty_like(r)
    acc = np.zeros(r.shape[:-1])
    for t in range(r.shape[-1] - 1, -1, -1):
        acc = r[..., t] + gamma * acc
        y[..., t] = acc
    return y


def resolve_step(step: StepFn | None) -> StepFn:
    """``step`` itself, or the default pendulum physics when ``None``."""
    if step is not None:
        return step
    return partial(pendulum_step, params=PendulumParams())


def initial_states(start: StartSpec, n: int, rng: np.random.Generator) -> FloatArray:
    """Resolve a :data:`StartSpec` to ``n`` start states ``[n, d]`` (a fresh array)."""
    if start is None:
        return sample_hanging_states(rng, n)
    if callable(start):
        states = np.asarray(start(rng, n), dtype=np.float64)
        if states.ndim != 2 or states.shape[0] != n:
            raise ValueError(f"start sampler returned shape {states.shape}; expected ({n}, d)")
    else:
        arr = np.asarray(start, dtype=np.float64)
        if arr.ndim == 1:
            states = np.tile(arr, (n, 1))
        elif arr.ndim == 2 and arr.shape[0] == n:
            states = arr.copy()
        else:
            raise ValueError(f"start has shape {arr.shape}; expected (d,) or ({n}, d)")
    if not np.isfinite(states).all():
        raise ValueError("start states contain NaN or inf")
    return states


def collect_rollouts(
    n: int,
    steps: int,
    policy: Policy,
    rng: np.random.Generator,
    gamma: float = DEFAULT_GAMMA,
    start: StartSpec = None,
    step: StepFn | None = None,
) -> list[Rollout]:
    """Run ``n`` roll-outs of ``steps`` steps in lock-step, vectorised over roll-outs.

    Parameters
    ----------
    n, steps : number of roll-outs and their length ``H`` (integers >= 1).
    policy : ``actions [n] = policy(states [n, d], rng)``; finite, else ``ValueError``.
        With the default pendulum physics, actions are clipped to the torque range
        before they are applied and recorded (as the env does); a custom ``step``
        gets and records them as returned.
    rng : the only source of randomness (start noise, then policy noise).
    gamma : discount of the ``returns`` targets, default 0.95.
    start : start states, see :data:`StartSpec`; default hanging down with noise.
    step : pure vectorised dynamics, see :data:`StepFn`; default the pendulum.

    Returns
    -------
    ``n`` :class:`Rollout` records of length ``steps``.
    """
    for name, value in (("n", n), ("steps", steps)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    if not isinstance(rng, np.random.Generator):
        raise ValueError(
            f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), "
            f"got {type(rng).__name__}"
        )
    if not (isinstance(gamma, int | float) and 0.0 <= gamma <= 1.0):
        raise ValueError(f"gamma must be a number in [0, 1], got {gamma!r}")
    max_torque = PendulumParams().max_torque if step is None else None
    step_fn = resolve_step(step)
    s = initial_states(start, n, rng)
    d = s.shape[1]
    states = np.empty((n, steps, d))
    next_states = np.empty((n, steps, d))
    actions = np.empty((n, steps))
    rewards = np.empty((n, steps))
    for t in range(steps):
        raw = np.asarray(policy(s, rng))
        if np.iscomplexobj(raw) or raw.dtype.kind not in "fiub":
            raise ValueError(f"policy returned actions of dtype {raw.dtype}; expected real numbers")
        a = raw.astype(np.float64)
        if a.shape != (n,):
            raise ValueError(f"policy returned actions of shape {a.shape}; expected ({n},)")
        if not np.all(np.isfinite(a)):
            bad = int(np.flatnonzero(~np.isfinite(a))[0])
            raise ValueError(
                f"policy returned a non-finite action at step {t} of roll-out {bad}; "
                "a policy must return finite torques"
            )
        if max_torque is not None:  # the default physics clips: record what is applied
            a = np.clip(a, -max_torque, max_torque)
        states[:, t] = s
        actions[:, t] = a
        s, r = step_fn(s, a)
        rewards[:, t] = r
        next_states[:, t] = s
    returns = discounted_returns(rewards, gamma)
    return [
        Rollout(states[i], actions[i], rewards[i], next_states[i], returns[i], float(gamma))
        for i in range(n)
    ]


def to_training_data(rollouts: Sequence[Rollout]) -> tuple[FloatArray, FloatArray]:
    """Stack roll-outs into GP training data ``X [N, d + 1]`` (``[s, a]``) and ``y [N]``.

    Rows are in roll-out order, then time order (the order the online GP streams them).
    """
    if len(rollouts) == 0:
        raise ValueError("no roll-outs given")
    X = np.concatenate([ro.inputs for ro in rollouts], axis=0)
    y = np.concatenate([ro.returns for ro in rollouts])
    return X, y
