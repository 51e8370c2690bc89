"""What an agent reads of its env: its spaces, its observations, its steps, the input scaling.

Everything an env returns is checked here before the agent takes it in
(:func:`env_reset`, :func:`env_step`): an observation of the declared shape, real,
finite and of magnitude at most ``MAX_MAGNITUDE`` (also once divided by the input
scale), a reward that is one real number, ``terminated`` / ``truncated`` booleans,
``info`` a dict. A refusal is a ``ValueError`` naming the env and what it returned.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from numbers import Real
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from geoq._typing import FloatArray
from geoq._validation import MAX_MAGNITUDE, check_real
from geoq.agents.buffer import Transitions
from geoq.learners.scaling import InputScaling
from geoq.tasks import (
    TaskInfo,
    bounded_dims,
    box_scaling,
    check_box_spaces,
    data_scaling,
    env_action,
    has_finite_bounds,
)

__all__ = [
    "EnvStep",
    "agent_spaces",
    "as_env",
    "as_observations",
    "env_reset",
    "env_step",
    "initial_scaling",
    "is_registered",
    "make_progress_bar",
    "matching_env",
    "observation_box",
    "outgrew",
    "scaling_from_states",
    "warmup_actions",
]


def is_registered(env_id: str) -> bool:
    """Whether ``gymnasium.make(env_id)`` finds ``env_id`` in Gymnasium's registry. As there,
    an id ``"module:Id"`` imports ``module`` first (its import registers ``Id``); a module
    that cannot be found is ``False``, any other error of its import (a module it imports
    in turn missing, say) is raised."""
    module, _, name = env_id.rpartition(":")
    if module:
        try:
            importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if exc.name is None or not (module + ".").startswith(exc.name + "."):
                raise
            return False
    return name in gymnasium.registry


def as_env(env: gymnasium.Env | str) -> gymnasium.Env:
    """``env``, or the registered env of that id (``"module:Id"``: :func:`is_registered`)."""
    if isinstance(env, str):
        if not is_registered(env):
            raise ValueError(
                f"env {env!r} is not a registered Gymnasium id; see `geoq info` for geoq's, "
                "pass a gymnasium.Env, or name the module that registers it as 'module:Id'"
            )
        return gymnasium.make(env)
    if not isinstance(env, gymnasium.Env):
        raise ValueError(
            f"env must be a gymnasium.Env or a registered id, got {type(env).__name__}"
        )
    return env


def time_limit(env: gymnasium.Env) -> int | None:
    """The env's registered ``max_episode_steps`` (None: none, or made directly)."""
    limit = env.spec.max_episode_steps if env.spec is not None else None
    return None if limit is None else int(limit)


def _name(env: gymnasium.Env) -> str:
    return env.spec.id if env.spec is not None else type(env.unwrapped).__name__


@dataclass(frozen=True)
class EnvStep:
    """One checked ``env.step``: the action as stored ``[1, d_a]`` (what the env executed,
    :func:`env_step`), the next state ``[1, d_s]``, the reward, the flags and
    ``info["is_success"]`` (1/0, NaN if the env reports none)."""

    action: FloatArray
    next_state: FloatArray
    reward: float
    terminated: bool
    truncated: bool
    success: float


def _checked_observation(
    env: gymnasium.Env, obs: Any, obs_dim: int, scale: FloatArray
) -> FloatArray:
    """The env's observation as ``[1, d_s]`` float64, or a ``ValueError`` naming the env."""
    try:
        raw = np.asarray(obs)
    except (TypeError, ValueError):  # ragged sequences
        raw = np.asarray(None)
    if raw.dtype.kind not in "fiub" or raw.shape != (obs_dim,):
        raise ValueError(
            f"{_name(env)} returned the observation {obs!r}; expected {obs_dim} real "
            f"number(s) of shape ({obs_dim},), as its observation space declares"
        )
    o = raw.astype(np.float64)
    if not np.all(np.isfinite(o)):
        raise ValueError(f"{_name(env)} returned an observation with NaN or inf: {o}")
    big = float(np.max(np.abs(o / scale), initial=0.0))
    if float(np.max(np.abs(o))) > MAX_MAGNITUDE or not big <= MAX_MAGNITUDE:
        raise ValueError(
            f"{_name(env)} returned the observation {o}: beyond {MAX_MAGNITUDE:g} in magnitude "
            "(divided by the input scale), the agent's squared distances overflow; rescale "
            "the observations (gymnasium.wrappers.TransformObservation) or pass scaling="
        )
    return o[None, :]


def env_reset(env: gymnasium.Env, seed: int | None, obs_dim: int, scale: FloatArray) -> FloatArray:
    """``env.reset(seed=seed)``'s observation ``[1, d_s]``, checked; ``scale``: the input
    scale of the observation dimensions ``[d_s]``."""
    out = env.reset(seed=seed)
    if not (isinstance(out, tuple) and len(out) == 2):
        raise ValueError(
            f"{_name(env)}.reset returned {type(out).__name__}; expected (observation, info) "
            "(Gymnasium's API)"
        )
    return _checked_observation(env, out[0], obs_dim, scale)


def _flag(env: gymnasium.Env, value: Any, name: str) -> bool:
    if isinstance(value, bool | np.bool_) or (
        isinstance(value, np.ndarray) and value.shape == () and value.dtype == bool
    ):
        return bool(value)
    raise ValueError(f"{_name(env)}.step returned {name}={value!r}; expected True or False")


def env_step(env: gymnasium.Env, action: FloatArray, obs_dim: int, scale: FloatArray) -> EnvStep:
    """``env.step`` of ``action`` ``[1, d_a]``, every output checked before the agent takes it.

    The env receives :func:`geoq.tasks.env_action` (cast to the space's dtype; integer
    boxes rounded and clipped); the step's action is what it executed, as float64. A
    float32 box is the one exception: its cast moves an action by at most one part in
    1.7e7 (float32's resolution), and the agent keeps its own float64 action.
    """
    space = env.action_space
    sent = env_action(action[0], space)  # type: ignore[arg-type]
    out = env.step(sent)
    if not (isinstance(out, tuple) and len(out) == 5):
        size = len(out) if isinstance(out, tuple) else type(out).__name__
        raise ValueError(
            f"{_name(env)}.step returned {size} values; expected 5 (observation, reward, "
            "terminated, truncated, info: Gymnasium's API)"
        )
    obs, reward, terminated, truncated, info = out
    r = _reward(env, reward)
    if not isinstance(info, Mapping):
        raise ValueError(f"{_name(env)}.step returned info={info!r}; expected a dict")
    s2 = _checked_observation(env, obs, obs_dim, scale)
    flags = _flag(env, terminated, "terminated"), _flag(env, truncated, "truncated")
    success = np.nan
    if "is_success" in info:
        try:
            success = float(bool(info["is_success"]))
        except (TypeError, ValueError):  # an array of several values
            raise ValueError(
                f"{_name(env)}.step returned info['is_success']={info['is_success']!r}; "
                "expected True or False"
            ) from None
    kept = action if space.dtype in (np.float32, np.float64) else sent.astype(np.float64)[None]
    return EnvStep(kept, s2, r, *flags, success)


def _reward(env: gymnasium.Env, reward: Any) -> float:
    """The env's reward as a float, if it is one finite real number (not a bool)."""
    r = reward.item() if isinstance(reward, np.ndarray) and reward.shape == () else reward
    try:
        ok = not isinstance(r, bool | np.bool_) and isinstance(r, Real) and np.isfinite(float(r))
    except OverflowError:  # an int beyond float64
        ok = False
    if not ok:
        shape = f" of shape {np.shape(reward)}" if np.ndim(reward) else ""
        raise ValueError(
            f"{_name(env)}.step returned the reward {reward!r}{shape}; expected one finite "
            "real number (a float)"
        )
    return float(r)


def agent_spaces(env: gymnasium.Env) -> tuple[spaces.Box, spaces.Box]:
    """The env's 1-D Box observation and action spaces (finite action bounds), or an error."""
    return check_box_spaces(env, "GPQAgent", finite_actions=True)


def as_observations(
    obs: Any, obs_dim: int, scale: FloatArray | None = None
) -> tuple[FloatArray, bool]:
    """``obs`` ``[d]`` or ``[n >= 1, d]`` as finite float64 ``[n, d]``, and whether it was one;
    with the input ``scale`` ``[d]``, also of magnitude at most ``MAX_MAGNITUDE`` once
    divided by it."""
    try:
        raw = np.asarray(obs)
    except (TypeError, ValueError):  # ragged sequences
        raw = np.asarray(None)
    if np.iscomplexobj(raw) or raw.dtype.kind not in "fiub":
        raise ValueError(f"observation must hold real numbers, got dtype {raw.dtype}")
    o = raw.astype(np.float64)
    if o.ndim not in (1, 2) or o.shape[-1] != obs_dim:
        raise ValueError(
            f"observation has shape {o.shape}; expected ({obs_dim},) or (n, {obs_dim})"
        )
    if o.size == 0:
        raise ValueError(f"observation holds no rows (shape {o.shape}); pass at least one")
    if not np.all(np.isfinite(o)):
        raise ValueError("observation contains NaN or inf")
    if scale is not None and not float(np.max(np.abs(o / scale))) <= MAX_MAGNITUDE:
        raise ValueError(
            f"observation reaches {float(np.max(np.abs(o))):.3g}: beyond {MAX_MAGNITUDE:g} "
            "in magnitude once divided by the agent's input scale, it cannot be compared with "
            "the states learned (squared distances overflow); pass observations of the env's "
            "own range"
        )
    return np.atleast_2d(o), o.ndim == 1


def observation_box(env: gymnasium.Env | None) -> tuple[FloatArray | None, FloatArray | None]:
    """The observation space's bounds ``[d_s]`` as float64 (None, None: not a Box)."""
    space = env.observation_space if env is not None else None
    if not isinstance(space, spaces.Box):
        return None, None
    bounded = bounded_dims(space)
    low = np.where(bounded, space.low, -np.inf).astype(np.float64)
    high = np.where(bounded, space.high, np.inf).astype(np.float64)
    return low, high


def initial_scaling(
    env: gymnasium.Env, info: TaskInfo, scaling: InputScaling | None
) -> tuple[InputScaling, bool]:
    """The input scaling of ``[s, a]`` an agent starts with, and whether it waits for data.

    ``scaling`` if given; else the spaces' half-ranges (:func:`geoq.tasks.box_scaling`),
    or, for an observation space with an infinite bound, a placeholder that the
    warm-up's states replace (:func:`scaling_from_states`).
    """
    obs_space, act_space = agent_spaces(env)
    d = obs_space.shape[0] + act_space.shape[0]
    pending = scaling is None and not has_finite_bounds(obs_space)
    if scaling is not None:
        scaling = _as_scaling(scaling, d, box_scaling(spaces.Box(-1, 1, (d - act_space.shape[0],)),
                                                      act_space, info))  # fmt: skip
    if scaling is None:
        states = np.zeros((1, obs_space.shape[0]))
        scaling = (
            data_scaling(states, obs_space, act_space, info)
            if pending
            else box_scaling(obs_space, act_space, info)
        )
    if scaling.dim != d:
        raise ValueError(
            f"scaling has {scaling.dim} dimensions; expected {d} (observation + action)"
        )
    return scaling, pending


def _as_scaling(scaling: Any, d: int, names: InputScaling) -> InputScaling:
    """``scaling=`` as an :class:`InputScaling` of Python floats: one given, or one finite
    scale > 0 per input (``d``) with the task's periods and names (from ``names``)."""
    if isinstance(scaling, InputScaling):
        scale, periods, labels = scaling.scale, scaling.periods, scaling.names
    else:
        scale, periods, labels = scaling, names.periods, names.names
    try:
        values = np.asarray(scale, dtype=object).ravel()
        out = InputScaling(
            tuple(check_real(v, "scale", low=0.0, low_open=True) for v in values),
            tuple(check_real(v, "period", low=0.0) for v in periods),
            tuple(str(n) for n in labels),
        )
    except (ValueError, TypeError):
        out = None
    if out is None or out.dim != d or np.ndim(scale) != 1:
        raise ValueError(
            f"scaling must be a geoq.learners.scaling.InputScaling or {d} finite scale(s) > 0, "
            f"one per observation and action dimension (inputs are divided by them), "
            f"got {scaling!r}"
        )
    return out


def scaling_from_states(
    env: gymnasium.Env | None, stored: Transitions, current: InputScaling
) -> InputScaling:
    """The input scaling of the states and next states of ``stored``
    (:func:`geoq.tasks.data_scaling`), with ``current``'s periods and names."""
    states = np.vstack([stored.states, stored.next_states])
    if env is None:
        raise RuntimeError("a data-driven scaling needs the env's spaces")
    obs_space, act_space = agent_spaces(env)
    d_s = states.shape[1]
    info = TaskInfo(periods=current.periods[:d_s], names=current.names[:d_s])
    return data_scaling(states, obs_space, act_space, info)


def outgrew(new: InputScaling, current: InputScaling, factor: float) -> bool:
    """Whether a scale of ``new`` passes ``factor`` x ``current``'s (time to rescale)."""
    return bool(np.any(np.asarray(new.scale) > factor * np.asarray(current.scale)))


def warmup_actions(
    low: FloatArray, high: FloatArray, n: int, deterministic: bool, rng: np.random.Generator
) -> FloatArray:
    """``n`` actions ``[n, d_a]`` of the warm-up's policy: uniform over the box, or its mean
    (the box's centre) when ``deterministic``."""
    if deterministic:
        return np.tile(0.5 * (low + high), (n, 1))
    return rng.uniform(low, high, size=(n, low.shape[0]))


def make_progress_bar(total: int) -> Any:
    """A tqdm progress bar over ``total`` steps."""
    from tqdm.auto import tqdm

    return tqdm(total=int(total), unit="step")


def matching_env(
    env: gymnasium.Env | str, obs_dim: int, action_low: FloatArray, action_high: FloatArray
) -> gymnasium.Env:
    """``env`` (made if an id) if its spaces match an agent's; else a ``ValueError``."""
    e = as_env(env)
    obs_space, act_space = agent_spaces(e)
    action_dim = action_low.shape[0]
    if obs_space.shape != (obs_dim,) or act_space.shape != (action_dim,):
        raise ValueError(
            f"env spaces {obs_space.shape}/{act_space.shape} do not match the agent's "
            f"({obs_dim},)/({action_dim},)"
        )
    if not (np.allclose(act_space.low, action_low) and np.allclose(act_space.high, action_high)):
        raise ValueError("the env's action bounds differ from the agent's")
    return e
