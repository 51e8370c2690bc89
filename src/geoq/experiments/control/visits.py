"""Where an agent went: a visitation map of its training states and one greedy route.

For tasks whose observation has two dimensions (``geoq/TwoRooms-v0``, the swing-up,
``MountainCarContinuous-v0``); :func:`geoq.experiments.control.plotting.plot_visits` draws
them, ``geoq train`` writes the picture as ``visits.png``. The map's extent is the
observation space's bounds where they are finite, else the range of the states seen.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium
import numpy as np

from geoq._typing import FloatArray
from geoq.agents import GPQAgent

__all__ = ["VISIT_BINS", "VisitMap", "greedy_route", "map_extent", "visit_map"]

#: Cells of the visitation map per dimension.
VISIT_BINS = 40


@dataclass(frozen=True)
class VisitMap:
    """Training visits and one greedy route of a 2-D task.

    Attributes
    ----------
    counts : visits per cell ``[bins, bins]`` (first index: the first observation
        dimension), of every stored transition's state.
    extent : ``((lo_0, hi_0), (lo_1, hi_1))``: the map's range per dimension.
    route : the states of one greedy episode ``[T + 1, 2]`` from the env's default reset.
    names : the two observation dimensions' names.
    success : whether that episode reported success (NaN if the env reports none).
    """

    counts: np.ndarray
    extent: tuple[tuple[float, float], tuple[float, float]]
    route: FloatArray
    names: tuple[str, str]
    success: float


def map_extent(
    space: gymnasium.spaces.Box, states: FloatArray
) -> tuple[tuple[float, float], tuple[float, float]]:
    """Per dimension of a 2-D observation space: its bounds where finite, else the range of
    ``states`` ``[N, 2]`` widened by 5% (a unit range around a single value)."""
    out = []
    for j in range(2):
        lo, hi = float(space.low[j]), float(space.high[j])
        if not (np.isfinite(lo) and np.isfinite(hi)):
            col = states[:, j] if len(states) else np.zeros(1)
            lo, hi = float(col.min()), float(col.max())
            pad = 0.05 * (hi - lo) if hi > lo else 0.5
            lo, hi = lo - pad, hi + pad
        out.append((lo, hi))
    return out[0], out[1]


def greedy_route(agent: GPQAgent, env: gymnasium.Env, seed: int) -> tuple[FloatArray, float]:
    """The observations ``[T + 1, d_s]`` of one greedy episode from ``env.reset(seed=seed)``
    and its success (``info["is_success"]`` at the end, NaN if absent)."""
    obs, _ = env.reset(seed=seed)
    route = [np.asarray(obs, dtype=np.float64)]
    info: dict[str, object] = {}
    done = False
    while not done:
        action, _ = agent.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action.astype(env.action_space.dtype))
        route.append(np.asarray(obs, dtype=np.float64))
        done = bool(terminated or truncated)
    success = float(bool(info["is_success"])) if "is_success" in info else np.nan
    return np.array(route), success


def visit_map(
    agent: GPQAgent, env: gymnasium.Env, seed: int, bins: int = VISIT_BINS
) -> VisitMap | None:
    """The :class:`VisitMap` of ``agent`` on ``env`` (its greedy route from ``seed``); None
    unless the observation space is a 2-D Box."""
    space = env.observation_space
    if not isinstance(space, gymnasium.spaces.Box) or space.shape != (2,):
        return None
    stored = agent.buffer.transitions()
    extent = map_extent(space, stored.states)
    counts, _, _ = np.histogram2d(stored.states[:, 0], stored.states[:, 1], bins=bins, range=extent)
    route, success = greedy_route(agent, env, seed)
    names = tuple(agent.scaling.names[:2])
    return VisitMap(counts, extent, route, (str(names[0]), str(names[1])), success)
