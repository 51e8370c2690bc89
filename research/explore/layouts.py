"""Other bottleneck layouts of TwoRooms' kind, for the exploration prototypes only.

``WallsEnv`` copies ``geoq/TwoRooms-v0``'s dynamics (a point in the unit square,
moves of ``0.05 * clip(a, -1, 1)`` per component, clipped to the square, ``-1``
per step, a goal disc) with any number of vertical and horizontal walls, each with
its own door, optionally observed in a box other than the unit square, and the same
crossing rule as :func:`geoq.envs.two_rooms_blocked` (a move that
crosses a wall outside its door leaves the state exactly unchanged). The
explorers never read these parameters: they are here to check that nothing in
a prototype was written for TwoRooms' geometry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

__all__ = ["LAYOUTS", "Layout", "WallsEnv", "make_env"]


@dataclass(frozen=True)
class Layout:
    """Walls, the start centre, the goal disc, the time limit, the observed box.

    ``walls`` are vertical ``(x, door_low, door_high)``, ``floors`` horizontal
    ``(y, door_low, door_high)``, all in the unit square where the dynamics run;
    the agent observes ``box[0] + (box[1] - box[0]) * state``.
    """

    walls: tuple[tuple[float, float, float], ...]
    start: tuple[float, float]
    goal: tuple[float, float]
    goal_radius: float = 0.1
    start_noise: float = 0.05
    horizon: int = 200
    step_size: float = 0.05
    floors: tuple[tuple[float, float, float], ...] = ()
    box: tuple[float, float] = (0.0, 1.0)


#: Layouts other than TwoRooms' (wall at x = 0.5, door at the top).
LAYOUTS: dict[str, Layout] = {
    # The door at the bottom, start and goal at the top: TwoRooms mirrored in y.
    "door-bottom": Layout(walls=((0.5, 0.0, 0.2),), start=(0.25, 0.8), goal=(0.75, 0.8)),
    # Two walls, doors at opposite ends: a route about twice TwoRooms' shortest one.
    "two-walls": Layout(
        walls=((1 / 3, 0.8, 1.0), (2 / 3, 0.0, 0.2)), start=(0.15, 0.2), goal=(0.85, 0.8)
    ),
    # Added after the design was fixed: a door half as wide, in the middle of the wall.
    "narrow-door": Layout(walls=((0.5, 0.45, 0.55),), start=(0.25, 0.2), goal=(0.75, 0.2)),
    # TwoRooms with moves half as long (twice the steps per route, time limit 400).
    "small-steps": Layout(
        walls=((0.5, 0.8, 1.0),), start=(0.25, 0.2), goal=(0.75, 0.2), step_size=0.025, horizon=400
    ),
    # Added after the map went into the agent (2026-12-03), none used to tune it:
    # a horizontal wall with its door on the left, start and goal on the right.
    "floor-door-left": Layout(
        walls=(), floors=((0.5, 0.0, 0.2),), start=(0.8, 0.2), goal=(0.8, 0.8)
    ),
    # Three walls, doors alternating top/bottom/top: a route about three times TwoRooms'.
    "three-walls": Layout(
        walls=((0.25, 0.8, 1.0), (0.5, 0.0, 0.2), (0.75, 0.8, 1.0)),
        start=(0.1, 0.2),
        goal=(0.9, 0.2),
    ),
    # TwoRooms observed in the box [-5, 5]^2 rather than the unit square.
    "big-box": Layout(
        walls=((0.5, 0.8, 1.0),), start=(0.25, 0.2), goal=(0.75, 0.2), box=(-5.0, 5.0)
    ),
    # A vertical and a horizontal wall: four rooms, the route through two doors
    # (bottom-left, bottom-right, top-right), the top-left room a dead end.
    "four-rooms": Layout(
        walls=((0.5, 0.0, 0.2),), floors=((0.5, 0.8, 1.0),), start=(0.25, 0.25), goal=(0.75, 0.75)
    ),
}


def _blocked(p: np.ndarray, q: np.ndarray, wall: tuple[float, float, float]) -> bool:
    """TwoRooms' crossing rule for one wall (geoq.envs.two_rooms.two_rooms_blocked)."""
    x, lo, hi = wall
    if (p[0] < x) == (q[0] < x):
        return False
    if q[0] == x:
        y_c = q[1]
    elif p[0] == x:
        y_c = p[1]
    else:
        y_c = p[1] + (x - p[0]) / (q[0] - p[0]) * (q[1] - p[1])
    y_c = min(max(y_c, min(p[1], q[1])), max(p[1], q[1]))
    return not lo <= y_c <= hi


class WallsEnv(gymnasium.Env):
    """TwoRooms' dynamics with the walls, start and goal of a :class:`Layout`."""

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        self.action_space = spaces.Box(low=-1.0, high=1.0, shape=(2,), dtype=np.float64)
        lo, hi = layout.box
        self.observation_space = spaces.Box(low=lo, high=hi, shape=(2,), dtype=np.float64)
        self.state = np.zeros(2)
        self._steps = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        noise = self.layout.start_noise
        self.state = np.asarray(self.layout.start) + self.np_random.uniform(-noise, noise, 2)
        self._steps = 0
        return self._observe(), {}

    def _observe(self) -> np.ndarray:
        lo, hi = self.layout.box
        return lo + (hi - lo) * self.state

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        p = self.state
        q = np.clip(p + self.layout.step_size * a, 0.0, 1.0)
        if not (
            any(_blocked(p, q, w) for w in self.layout.walls)
            or any(_blocked(p[::-1], q[::-1], f) for f in self.layout.floors)
        ):
            self.state = q
        self._steps += 1
        done = bool(np.hypot(*(self.state - self.layout.goal)) <= self.layout.goal_radius)
        truncated = not done and self._steps >= self.layout.horizon
        info: dict[str, Any] = {"is_success": done} if done or truncated else {}
        return self._observe(), -1.0, done, truncated, info


def make_env(name: str) -> gymnasium.Env:
    """``"two-rooms"``: ``gymnasium.make("geoq/TwoRooms-v0")``; else a :data:`LAYOUTS` entry."""
    if name == "two-rooms":
        import geoq  # noqa: F401  (registers the env)

        return gymnasium.make("geoq/TwoRooms-v0")
    if name not in LAYOUTS:
        raise ValueError(f"unknown layout {name!r}; expected two-rooms or one of {sorted(LAYOUTS)}")
    return WallsEnv(LAYOUTS[name])
