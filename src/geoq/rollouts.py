"""Roll-outs of a policy, vectorised over many roll-outs, and discounted returns.

A roll-out of ``H`` steps records ``(s_t, a_t, r_t, s_{t+1})`` for
``t = 0 .. H-1`` and the Monte-Carlo targets of the paper (JC12 §3),

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

**Any task.** Actions are scalars ``[N]`` (the pendulum's torque) or vectors
``[N, d_a]``. A step function returns ``(next_states, rewards)`` or
``(next_states, rewards, terminated)``; a roll-out whose step terminates ends
there (its record is cut after the terminating step, so nothing after it is
recorded or counted in the returns) while the others go on in lock-step. The
policy is still called on every row, finished ones included, so the generator
is consumed the same way whatever terminates; the batch stops early when every
roll-out has terminated.
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
    "split_step",
    "to_training_data",
]

#: Default discount factor of geoq's experiments.
DEFAULT_GAMMA = 0.95

#: ``(states [N, d], actions [N] or [N, d_a]) -> (next_states [N, d], rewards [N])`` or
#: ``-> (next_states, rewards, terminated [N] bool)``, pure and vectorised.
StepFn = Callable[
    [FloatArray, FloatArray],
    tuple[FloatArray, FloatArray] | tuple[FloatArray, FloatArray, np.ndarray],
]

#: Start states: ``None`` (hanging down, seeded noise), one state ``[d]``, one per
#: roll-out ``[n, d]``, or a sampler ``(rng, n) -> [n, d]``.
StartSpec = ArrayLike | Callable[[np.random.Generator, int], FloatArray] | None


@dataclass(frozen=True)
class Rollout:
    """One roll-out of ``H`` steps (arrays are read-only).

    Attributes
    ----------
    states : ``[H, d]`` states ``s_t``.
    actions : ``[H]`` (scalar actions) or ``[H, d_a]`` actions ``a_t`` as taken (after the
        policy's clipping).
    rewards : ``[H]`` rewards ``r_t = r(s_t, a_t)``.
    next_states : ``[H, d]`` states ``s_{t+1}``.
    returns : ``[H]`` truncated discounted returns ``y_t`` (module docstring).
    gamma : the discount used for ``returns``.
    terminated : whether the last step terminated the episode (then ``H`` may be shorter
        than the roll-out length asked for, and ``returns`` are exact, not truncated).
    """

    states: FloatArray
    actions: FloatArray
    rewards: FloatArray
    next_states: FloatArray
    returns: FloatArray
    gamma: float
    terminated: bool = False

    def __post_init__(self) -> None:
        h = self.actions.shape[0]
        shapes_ok = (
            self.states.ndim == 2
            and self.states.shape[0] == h
            and self.next_states.shape == self.states.shape
            and self.actions.ndim in (1, 2)
            and self.rewards.shape == self.returns.shape == (h,)
        )
        if not shapes_ok:
            raise ValueError(
                "Rollout arrays disagree: states and next_states must be [H, d], actions "
                f"[H] or [H, d_a] and rewards, returns [H]; got {self.states.shape}, "
                f"{self.next_states.shape}, {self.actions.shape}, {self.rewards.shape}, "
                f"{self.returns.shape}"
            )
        for arr in (self.states, self.actions, self.rewards, self.next_states, self.returns):
            arr.flags.writeable = False

    def __len__(self) -> int:
        return int(self.actions.shape[0])

    @property
    def inputs(self) -> FloatArray:
        """State-action pairs ``x_t = [s_t, a_t]``, shape ``[H, d + d_a]`` (the GP inputs)."""
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
    policy : ``actions [n] or [n, d_a] = policy(states [n, d], rng)``; finite real numbers
        of the same shape at every step, else ``ValueError``.
        With the default pendulum physics, actions are clipped to the torque range
        before they are applied and recorded (as the env does); a custom ``step``
        gets and records them as returned.
    rng : the only source of randomness (start noise, then policy noise).
    gamma : discount of the ``returns`` targets, default 0.95.
    start : start states, see :data:`StartSpec`; default hanging down with noise.
    step : pure vectorised dynamics, see :data:`StepFn`; default the pendulum. When it
        returns ``terminated``, a roll-out ends at its terminating step (module docstring).

    Returns
    -------
    ``n`` :class:`Rollout` records of length ``steps`` (shorter when terminated).
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
    actions: FloatArray | None = None  # [n, steps] or [n, steps, d_a], once d_a is known
    rewards = np.empty((n, steps))
    lengths = np.full(n, steps)
    alive = np.ones(n, dtype=bool)
    for t in range(steps):
        a = _checked_actions(policy(s, rng), n, t, None if actions is None else actions.shape[2:])
        if max_torque is not None:  # the default physics clips: record what is applied
            a = np.clip(a, -max_torque, max_torque)
        if actions is None:
            actions = np.empty((n, steps, *a.shape[1:]))
        states[:, t] = s
        actions[:, t] = a
        s, r, terminated = split_step(step_fn(s, a), n)
        rewards[:, t] = r
        next_states[:, t] = s
        if terminated is not None:
            ended = alive & terminated
            lengths[ended] = t + 1
            alive &= ~terminated
            if not alive.any():
                break
    assert actions is not None
    # Steps after a roll-out's end are cut: zero rewards there leave y_t, t < end, exact.
    after_end = np.arange(steps)[None, :] >= lengths[:, None]  # [n, steps]
    rewards[after_end] = 0.0
    returns = discounted_returns(rewards, gamma)
    return [
        Rollout(
            states[i, :h],
            actions[i, :h],
            rewards[i, :h],
            next_states[i, :h],
            returns[i, :h],
            float(gamma),
            terminated=bool(not alive[i]),
        )
        for i, h in enumerate(lengths.tolist())
    ]


def _checked_actions(
    raw_actions: object, n: int, t: int, action_shape: tuple[int, ...] | None
) -> FloatArray:
    """The policy's actions as float64 ``[n]`` or ``[n, d_a]``, or a ``ValueError``."""
    raw = np.asarray(raw_actions)
    if np.iscomplexobj(raw) or raw.dtype.kind not in "fiub":
        raise ValueError(f"policy returned actions of dtype {raw.dtype}; expected real numbers")
    a = raw.astype(np.float64)
    expected = f"({n},) or ({n}, d_a)" if action_shape is None else str((n, *action_shape))
    if (
        a.ndim not in (1, 2)
        or a.shape[0] != n
        or (action_shape is not None and a.shape[1:] != action_shape)
    ):
        raise ValueError(f"policy returned actions of shape {a.shape}; expected {expected}")
    if not np.all(np.isfinite(a)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(a.reshape(n, -1)), axis=1))[0])
        raise ValueError(
            f"policy returned a non-finite action at step {t} of roll-out {bad}; "
            "a policy must return finite actions"
        )
    return a


def split_step(
    out: tuple[FloatArray, ...], n: int
) -> tuple[FloatArray, FloatArray, np.ndarray | None]:
    """``(next_states, rewards, terminated or None)`` from a :data:`StepFn`'s result."""
    if not isinstance(out, tuple) or len(out) not in (2, 3):
        raise ValueError(
            "a step function must return (next_states, rewards) or "
            "(next_states, rewards, terminated)"
        )
    if len(out) == 2:
        return out[0], out[1], None
    terminated = np.asarray(out[2])
    if terminated.dtype != bool or terminated.shape != (n,):
        raise ValueError(
            f"a step function's terminated must be a bool array of shape ({n},), "
            f"got {terminated.dtype} {terminated.shape}"
        )
    return out[0], out[1], terminated


def to_training_data(rollouts: Sequence[Rollout]) -> tuple[FloatArray, FloatArray]:
    """Stack roll-outs into GP training data ``X [N, d + 1]`` (``[s, a]``) and ``y [N]``.

    Rows are in roll-out order, then time order (the order the online GP streams them).
    """
    if len(rollouts) == 0:
        raise ValueError("no roll-outs given")
    X = np.concatenate([ro.inputs for ro in rollouts], axis=0)
    y = np.concatenate([ro.returns for ro in rollouts])
    return X, y
