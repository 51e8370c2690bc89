"""What an agent reads of its env: its spaces, its observations, the input scaling."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from geoq._typing import FloatArray
from geoq.learners.scaling import InputScaling
from geoq.tasks import TaskInfo, box_scaling, check_box_spaces, data_scaling, has_finite_bounds

__all__ = [
    "agent_spaces",
    "as_env",
    "as_observations",
    "initial_scaling",
    "matching_env",
    "observation_box",
    "scaling_from_states",
]


def as_env(env: gymnasium.Env | str) -> gymnasium.Env:
    """``env``, or the registered env of that id."""
    if isinstance(env, str):
        return gymnasium.make(env)
    if not isinstance(env, gymnasium.Env):
        raise ValueError(
            f"env must be a gymnasium.Env or a registered id, got {type(env).__name__}"
        )
    return env


def agent_spaces(env: gymnasium.Env) -> tuple[spaces.Box, spaces.Box]:
    """The env's 1-D Box observation and action spaces (finite action bounds), or an error."""
    return check_box_spaces(env, "GPQAgent", finite_actions=True)


def as_observations(obs: Any, obs_dim: int) -> tuple[FloatArray, bool]:
    """``obs`` ``[d]`` or ``[n, d]`` as finite float64 ``[n, d]``, and whether it was one."""
    raw = np.asarray(obs)
    if np.iscomplexobj(raw) or raw.dtype.kind not in "fiub":
        raise ValueError(f"observation must hold real numbers, got dtype {raw.dtype}")
    o = raw.astype(np.float64)
    if o.ndim not in (1, 2) or o.shape[-1] != obs_dim:
        raise ValueError(
            f"observation has shape {o.shape}; expected ({obs_dim},) or (n, {obs_dim})"
        )
    if not np.all(np.isfinite(o)):
        raise ValueError("observation contains NaN or inf")
    return np.atleast_2d(o), o.ndim == 1


def observation_box(env: gymnasium.Env | None) -> tuple[FloatArray | None, FloatArray | None]:
    """The observation space's bounds ``[d_s]`` as float64 (None, None: not a Box)."""
    space = env.observation_space if env is not None else None
    if not isinstance(space, spaces.Box):
        return None, None
    low = np.where(np.isfinite(space.low), space.low, -np.inf).astype(np.float64)
    high = np.where(np.isfinite(space.high), space.high, np.inf).astype(np.float64)
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


def scaling_from_states(
    env: gymnasium.Env | None, states: FloatArray, current: InputScaling
) -> InputScaling:
    """The input scaling of the ``states`` ``[n, d_s]`` seen (:func:`geoq.tasks.data_scaling`),
    with ``current``'s periods and names."""
    if env is None:
        raise RuntimeError("a data-driven scaling needs the env's spaces")
    obs_space, act_space = agent_spaces(env)
    d_s = states.shape[1]
    info = TaskInfo(periods=current.periods[:d_s], names=current.names[:d_s])
    return data_scaling(states, obs_space, act_space, info)


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
