"""What an agent or learner needs to know about a task beyond its Gymnasium env.

One :class:`TaskInfo` record per known task: which observation dimensions are
angles (periodic, with their period in raw units), and a readable name per
dimension. Unknown tasks get no periodic dimension unless the caller declares
one; input scaling comes from the env's space bounds (:func:`box_scaling`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import gymnasium
import numpy as np

from geoq._typing import FloatArray
from geoq._validation import MAX_MAGNITUDE, check_real
from geoq.envs import PENDULUM_SWING_UP_ID, TWO_ROOMS_ID
from geoq.learners.scaling import InputScaling

__all__ = [
    "HUGE_BOUND",
    "KNOWN_TASKS",
    "TaskInfo",
    "bounded_dims",
    "box_scaling",
    "check_box_spaces",
    "data_scaling",
    "env_action",
    "has_finite_bounds",
    "task_info",
]

#: A space bound of this magnitude or more declares no bound (see the module docstring):
#: no task declares a real extent that large, and a half-range of 1e6 would make the
#: agent's length-scale rule (0.15 half-ranges) 150,000 units wide.
HUGE_BOUND = 1e6


@dataclass(frozen=True)
class TaskInfo:
    """Per-task facts that are not in the env's spaces.

    Attributes
    ----------
    periods : wrap-around period of each observation dimension in raw units
        (``0`` = not periodic), ``[d_s]``.
    names : readable names of the observation dimensions (for reports).
    success_return : for tasks whose env reports no ``info["is_success"]``: an
        evaluation succeeds when its mean return reaches this (None: the env's own).
    reward_range : ``(r_min, r_max)`` of one step's reward where the env documents it
        and its best reward comes late (the agent's optimistic prior starts from it);
        with ``terminal_reward_range``, of the steps that do not end the episode.
    terminal_reward_range : ``(r_min, r_max)`` of the reward of a step that ends the
        episode (``terminated``), where the env documents one apart: it is received
        once, so it bounds a return by itself, not divided by ``1 - gamma``.
    """

    periods: tuple[float, ...]
    names: tuple[str, ...]
    success_return: float | None = None
    reward_range: tuple[float, float] | None = None
    terminal_reward_range: tuple[float, float] | None = None


#: Tasks whose periodic dimensions are known. Gymnasium's ``Pendulum-v1``
#: observes ``[cos, sin, omega]``: nothing in it wraps. Success thresholds of the
#: Gymnasium tasks (mean evaluation return): MountainCarContinuous 90 (Gymnasium's
#: own "solved" threshold), Pendulum-v1 -160 (rl-baselines3-zoo's SAC reaches -157).
#: Reward ranges from Gymnasium's documentation: MountainCarContinuous
#: ``-0.1 a^2`` per step, plus 100 on the step that reaches the flag (and ends the
#: episode); Pendulum-v1
#: ``-(theta^2 + 0.1 omega^2 + 0.001 u^2)``, 0 upright at rest.
KNOWN_TASKS: Mapping[str, TaskInfo] = {
    PENDULUM_SWING_UP_ID: TaskInfo(periods=(2.0 * np.pi, 0.0), names=("theta", "omega")),
    TWO_ROOMS_ID: TaskInfo(periods=(0.0, 0.0), names=("x", "y")),
    "Pendulum-v1": TaskInfo(
        periods=(0.0, 0.0, 0.0),
        names=("cos", "sin", "omega"),
        success_return=-160.0,
        reward_range=(-(np.pi**2 + 0.1 * 8.0**2 + 0.001 * 2.0**2), 0.0),
    ),
    "MountainCarContinuous-v0": TaskInfo(
        periods=(0.0, 0.0),
        names=("position", "velocity"),
        success_return=90.0,
        reward_range=(-0.1, 0.0),
        terminal_reward_range=(99.9, 100.0),
    ),
}


def task_info(env: gymnasium.Env, periods: Sequence[float] | None = None) -> TaskInfo:
    """The :class:`TaskInfo` of ``env``: declared ``periods`` first, then the known tasks.

    ``periods`` (raw units, one per observation dimension, ``0`` = not
    periodic) overrides what is known. An unknown task without ``periods`` has
    none. A known task whose observations a wrapper reshaped is not known: what is known
    of it (periods, names, rewards) is of observations it no longer gives.
    """
    space = env.observation_space
    d = int(np.prod(space.shape)) if space.shape is not None else 0
    spec = env.spec
    known = KNOWN_TASKS.get(spec.id) if spec is not None else None
    if known is not None and len(known.names) != d:  # a wrapper changed the observations
        known = None
    names = known.names if known is not None else tuple(f"s{i}" for i in range(d))
    if periods is None:
        return known if known is not None else TaskInfo(periods=(0.0,) * d, names=names)
    success = known.success_return if known is not None else None
    rewards = known.reward_range if known is not None else None
    terminal = known.terminal_reward_range if known is not None else None
    try:
        p = tuple(check_real(v, "periods") for v in np.asarray(periods, dtype=object).ravel())
    except (ValueError, TypeError):
        p = ()
    if np.ndim(periods) != 1 or len(p) != d or not all(v >= 0 for v in p):
        raise ValueError(
            f"periods must give one finite period >= 0 per observation dimension ({d}) in raw "
            f"units (0: not periodic), got {periods!r}"
        )
    return TaskInfo(
        periods=p, names=names, success_return=success, reward_range=rewards,
        terminal_reward_range=terminal,
    )  # fmt: skip


def box_scaling(
    obs_space: gymnasium.spaces.Box, action_space: gymnasium.spaces.Box, info: TaskInfo
) -> InputScaling:
    """Input scaling of ``[s, a]`` from the spaces' bounds: each dimension's half-range.

    Every input then spans about ``[-1, 1]`` (an angle of period ``2 pi`` in
    ``[-pi, pi]`` spans ``[-1, 1]`` with period 2). Bounds must be finite.
    """
    lo = np.concatenate([obs_space.low.ravel(), action_space.low.ravel()]).astype(np.float64)
    hi = np.concatenate([obs_space.high.ravel(), action_space.high.ravel()]).astype(np.float64)
    if not (has_finite_bounds(obs_space) and has_finite_bounds(action_space)):
        raise ValueError(
            f"the observation or action space has infinite bounds (or bounds of {HUGE_BOUND:g} "
            "or more, which declare none); geoq scales inputs by the space bounds, so wrap "
            "the env in gymnasium.wrappers.ClipObservation or pass scaling= with a finite "
            "scale per dimension"
        )
    half = 0.5 * (hi - lo)
    half = np.where(half > 0, half, 1.0)
    d_a = int(np.prod(action_space.shape))
    periods = (*info.periods, *(0.0,) * d_a)
    names = (*info.names, *(f"a{i}" for i in range(d_a)))
    return InputScaling(tuple(float(h) for h in half), periods, names)


def check_box_spaces(
    env: gymnasium.Env, who: str = "the task suite", finite_actions: bool = False
) -> tuple[gymnasium.spaces.Box, gymnasium.spaces.Box]:
    """The env's observation and action spaces, if both are 1-D Boxes (and the action
    bounds finite, with ``finite_actions``); else a ``ValueError`` saying what ``who``
    supports."""
    obs, act = env.observation_space, env.action_space
    name = env.spec.id if env.spec is not None else type(env).__name__
    Box = gymnasium.spaces.Box
    if not isinstance(obs, Box) or len(obs.shape) != 1:
        raise ValueError(
            f"{name}: {who} needs a 1-D Box observation space; got {obs!r} "
            "(flatten Dict observations with gymnasium.wrappers.FlattenObservation)"
        )
    if not isinstance(act, Box) or len(act.shape) != 1:
        raise ValueError(
            f"{name}: {who} needs a 1-D Box action space (continuous actions); got {act!r}. "
            "Discrete action spaces are not supported."
        )
    if finite_actions and not has_finite_bounds(act):
        raise ValueError(
            f"{name}: {who} needs finite action bounds below {HUGE_BOUND:g} in magnitude (it "
            f"acts in the box); got {act!r}: wrap the env in gymnasium.wrappers.RescaleAction"
        )
    return obs, act


def bounded_dims(space: gymnasium.spaces.Box) -> np.ndarray:
    """``[d]`` bool: whether each dimension of ``space`` has two bounds that count, finite
    and below :data:`HUGE_BOUND` in magnitude (larger ones declare no bound)."""
    lo = np.asarray(space.low, dtype=np.float64).ravel()
    hi = np.asarray(space.high, dtype=np.float64).ravel()
    with np.errstate(invalid="ignore"):
        return (np.abs(lo) < HUGE_BOUND) & (np.abs(hi) < HUGE_BOUND)


def has_finite_bounds(space: gymnasium.spaces.Box) -> bool:
    """Whether every bound of ``space`` counts (:func:`bounded_dims`; then
    :func:`box_scaling` applies)."""
    return bool(np.all(bounded_dims(space)))


def env_action(action: FloatArray, space: gymnasium.spaces.Box) -> np.ndarray:
    """The action ``[d_a]`` (float64, inside the box) as the env receives it: cast to the
    space's dtype, integer (and bool) boxes rounded to the nearest value first (a cast
    alone would truncate towards zero) and clipped to the box."""
    a = np.asarray(action, dtype=np.float64)
    if space.dtype.kind in "iub":
        low = np.asarray(space.low, dtype=np.float64)
        high = np.asarray(space.high, dtype=np.float64)
        return np.clip(np.rint(a), low, high).astype(space.dtype)
    return a.astype(space.dtype)


def data_scaling(
    states: FloatArray,
    obs_space: gymnasium.spaces.Box,
    action_space: gymnasium.spaces.Box,
    info: TaskInfo,
    *,
    quantile: float = 0.05,
) -> InputScaling:
    """Input scaling of ``[s, a]`` from observed states where the bounds are infinite.

    Dimensions with finite bounds (every action dimension: the agent requires
    them) keep :func:`box_scaling`'s half-range. An observation dimension with an
    infinite bound gets half of the spread between the ``quantile`` and
    ``1 - quantile`` quantiles of ``states`` ``[N, d_s]`` (robust to the odd far
    state), or half its period if it is periodic; a dimension that never moved
    gets 1.

    Raises ``ValueError`` when ``states`` is empty or not finite: there is nothing
    to scale by yet.
    """
    S = np.asarray(states, dtype=np.float64)
    d_s = int(np.prod(obs_space.shape))
    if S.ndim != 2 or S.shape[1] != d_s or S.shape[0] == 0:
        raise ValueError(
            f"data_scaling needs observed states of shape (N >= 1, {d_s}), got {S.shape}: "
            "collect some steps first, or pass scaling= with a finite scale per dimension"
        )
    if not np.all(np.isfinite(S)):
        raise ValueError("observed states contain NaN or inf")
    lo = obs_space.low.ravel().astype(np.float64)
    hi = obs_space.high.ravel().astype(np.float64)
    finite = bounded_dims(obs_space)
    q_lo, q_hi = np.quantile(S, [quantile, 1.0 - quantile], axis=0)
    spread = 0.5 * (q_hi - q_lo)
    periods = np.asarray(info.periods, dtype=np.float64)
    data = np.where(periods > 0, 0.5 * periods, np.where(spread > 0, spread, 1.0))
    # Every state seen maps inside the GP's input range (a tiny spread beside a far state).
    data = np.maximum(data, np.max(np.abs(S), axis=0) / MAX_MAGNITUDE)
    with np.errstate(invalid="ignore", over="ignore"):
        half_box = np.where(finite, 0.5 * (hi - lo), 1.0)
    obs_scale = np.where(finite & (half_box > 0), half_box, np.where(finite, 1.0, data))
    clipped = gymnasium.spaces.Box(
        -np.ones(d_s), np.ones(d_s), dtype=np.float64
    )  # any finite box: only the action part of box_scaling is used below
    base = box_scaling(clipped, action_space, info)
    return InputScaling(
        tuple(float(v) for v in obs_scale) + base.scale[d_s:], base.periods, base.names
    )
