"""Two-rooms navigation as a pure, vectorised function.

One function, :func:`two_rooms_step`, is the single source of truth for the
dynamics: the Gymnasium shell (:mod:`geoq.envs.two_rooms_env`) and any
Monte-Carlo ground truth call it. No state, no randomness, any leading batch
shape.

A point moves in the unit square. A wall stands on the line ``x = WALL_X``
with a door at ``DOOR[0] <= y <= DOOR[1]``; the goal is a disc around
``GOAL`` in the right room. States just left of the wall at low ``y`` are
close to the goal in Euclidean distance but far from it along the dynamics.

Dynamics::

    a  = clip(action, -1, 1)                                  # each component
    q  = clip(p + STEP_SIZE * a, 0, 1)                        # the clipped move p -> q
    p' = p  if the segment p -> q crosses the wall outside the door,  else q
    r  = -1                                                   # every step
    terminated = |p' - GOAL| <= GOAL_RADIUS                   # closed disc, Euclidean

**Rooms and crossing.** The left room is ``x < WALL_X`` and the right room is
``x >= WALL_X``: the wall line itself belongs to the right room. A move
*crosses* the wall exactly when its start ``p`` and its end ``q`` lie in
different rooms. Its crossing height is ``y_c = p_y + t (q_y - p_y)`` with
``t = (WALL_X - p_x) / (q_x - p_x)`` (linear interpolation along the clipped
move), except that an endpoint lying on the line gives its own ``y`` exactly
(and ``y_c`` is kept between ``p_y`` and ``q_y`` against rounding).
The move is blocked (``p' = p``) when it crosses with ``y_c`` outside the
closed door ``[DOOR[0], DOOR[1]]``. Consequences:

* a move from the left room that would end exactly on the wall line is a
  crossing (blocked unless its end is in the door);
* a move from the wall line into the left room is a crossing at the start's
  height (blocked unless the start is in the door);
* moves along the line, or from the right room onto it, do not cross.
"""

from __future__ import annotations

import numpy as np

from geoq._typing import ArrayLike, FloatArray

__all__ = [
    "DOOR",
    "GOAL",
    "GOAL_RADIUS",
    "STEP_SIZE",
    "TWO_ROOMS_START",
    "TWO_ROOMS_START_NOISE",
    "WALL_X",
    "sample_two_rooms_starts",
    "two_rooms_blocked",
    "two_rooms_step",
]

#: The wall stands on the line ``x = WALL_X``; ``x < WALL_X`` is the left room.
WALL_X = 0.5
#: The door: a crossing at height ``DOOR[0] <= y <= DOOR[1]`` passes.
DOOR: tuple[float, float] = (0.8, 1.0)
#: Centre of the goal disc (in the right room).
GOAL: tuple[float, float] = (0.75, 0.2)
#: An episode terminates when the new position is at Euclidean distance ``<= GOAL_RADIUS``.
GOAL_RADIUS = 0.1
#: A unit action moves the point by ``STEP_SIZE`` per component.
STEP_SIZE = 0.05
#: Centre of the default start distribution (in the left room).
TWO_ROOMS_START: tuple[float, float] = (0.25, 0.2)
#: Half-width of the uniform noise on each coordinate of the default start.
TWO_ROOMS_START_NOISE = 0.05


def _as_pairs(x: ArrayLike, name: str) -> FloatArray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 0 or a.shape[-1] != 2:
        raise ValueError(f"{name} has shape {a.shape}; expected (..., 2) rows [x, y]")
    return a


def two_rooms_blocked(starts: ArrayLike, ends: ArrayLike) -> np.ndarray:
    """Whether the wall blocks the moves ``starts -> ends``, boolean ``[...]``.

    ``starts`` and ``ends`` are ``[..., 2]`` positions (``ends`` already clipped
    to the square). See the module docstring for the crossing rule.
    """
    p, q = np.broadcast_arrays(_as_pairs(starts, "starts"), _as_pairs(ends, "ends"))
    px, py, qx, qy = p[..., 0], p[..., 1], q[..., 0], q[..., 1]
    crosses = (px < WALL_X) != (qx < WALL_X)
    dx = np.where(crosses, qx - px, 1.0)  # nonzero where it is used
    t = (WALL_X - px) / dx
    y_c = np.where(qx == WALL_X, qy, np.where(px == WALL_X, py, py + t * (qy - py)))
    y_c = np.clip(y_c, np.minimum(py, qy), np.maximum(py, qy))  # on the segment despite rounding
    through_door = (y_c >= DOOR[0]) & (y_c <= DOOR[1])
    return crosses & ~through_door


def two_rooms_step(
    states: ArrayLike, actions: ArrayLike
) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """Advance a batch of points by one step.

    Parameters
    ----------
    states : ``[..., 2]`` positions ``[x, y]`` in the unit square.
    actions : ``[..., 2]`` moves ``[dx, dy]``, broadcast against ``states``;
        each component is clipped to ``[-1, 1]``. Finite values are expected
        (the env validates its input; this function does not).

    Returns
    -------
    next_states : ``[..., 2]`` positions in the unit square.
    rewards : ``[...]``, ``-1`` everywhere.
    terminated : ``[...]`` bool, the next position is within ``GOAL_RADIUS``
        of ``GOAL`` (``<=``).
    """
    p = _as_pairs(states, "states")
    a = np.clip(_as_pairs(actions, "actions"), -1.0, 1.0)
    p, a = np.broadcast_arrays(p, a)
    q = np.clip(p + STEP_SIZE * a, 0.0, 1.0)  # [..., 2]
    blocked = two_rooms_blocked(p, q)  # [...]
    next_states = np.where(blocked[..., None], p, q)
    dist = np.hypot(next_states[..., 0] - GOAL[0], next_states[..., 1] - GOAL[1])
    terminated = dist <= GOAL_RADIUS
    rewards = np.full(terminated.shape, -1.0)
    return next_states, rewards, terminated


def sample_two_rooms_starts(
    rng: np.random.Generator, n: int, noise: float = TWO_ROOMS_START_NOISE
) -> FloatArray:
    """Draw ``n`` default start states, shape ``[n, 2]``.

    ``TWO_ROOMS_START + U(-noise, noise)`` per coordinate, drawn as one
    ``rng.uniform(-noise, noise, size=(n, 2))`` call. ``noise <= 0.2`` keeps
    every start inside the left room and the square, so nothing is clipped.
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    if not np.isfinite(noise) or not 0.0 <= noise <= 0.2:
        raise ValueError(f"noise must be in [0, 0.2] (starts stay in the left room), got {noise!r}")
    offsets = rng.uniform(-noise, noise, size=(n, 2))
    return np.asarray(TWO_ROOMS_START, dtype=np.float64) + offsets
