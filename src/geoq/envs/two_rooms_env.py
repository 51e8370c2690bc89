"""Gymnasium shell around :func:`geoq.envs.two_rooms.two_rooms_step`."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from geoq._typing import FloatArray
from geoq.envs._render import TwoRoomsPainter, check_render_mode, state_to_render
from geoq.envs._reset import episode_horizon, numeric_start_state, start_option
from geoq.envs.two_rooms import (
    TWO_ROOMS_START_NOISE,
    sample_two_rooms_starts,
    two_rooms_step,
)

__all__ = ["TwoRoomsEnv"]

#: Episode length used for the failure report when the env was made without a
#: time limit (``gymnasium.make`` sets 200, see ``geoq.envs``).
_DEFAULT_HORIZON = 200


class TwoRoomsEnv(gymnasium.Env[FloatArray, FloatArray]):
    """
    ## Description

    Move a point from the left room of the unit square, through a door in the
    wall `x = 0.5`, to a goal in the right room. States just left of the wall
    at low `y` are close to the goal in Euclidean distance and far from it
    along the dynamics. The dynamics is the pure function
    `geoq.envs.two_rooms.two_rooms_step`; this class is a thin, stateful shell
    around it.

    ## Action Space

    An `ndarray` of shape `(2,)`, the move `[dx, dy]`. Values outside the range
    are clipped; actions of another shape or with NaN/inf raise `ValueError`.

    | Num | Action | Min  | Max |
    |-----|--------|------|-----|
    | 0   | dx     | -1.0 | 1.0 |
    | 1   | dy     | -1.0 | 1.0 |

    ## Observation Space

    The position, an `ndarray` of shape `(2,)`, float64.

    | Num | Observation | Min | Max |
    |-----|-------------|-----|-----|
    | 0   | x           | 0.0 | 1.0 |
    | 1   | y           | 0.0 | 1.0 |

    ## Transition

    *q = clip(p + 0.05 clip(a, -1, 1), 0, 1)*. The left room is `x < 0.5`, the
    right room `x >= 0.5` (the wall line belongs to it). A move whose start and
    end lie in different rooms crosses the wall, at the height interpolated
    linearly along `p -> q` (an endpoint on the line gives its own height); if
    that height is outside the door `0.8 <= y <= 1.0` the move is blocked and
    the point stays at `p`. Otherwise it moves to `q`.

    ## Rewards

    `-1` per step.

    ## Starting State

    `(0.25, 0.2) + U(-0.05, 0.05)` per coordinate, drawn from the env's seeded
    generator (`reset(seed=...)`): always in the left room. An exact start is
    given by `reset(options={"state": [x, y]})`: any finite point of the unit
    square, else `ValueError`.

    ## Episode End

    `terminated` is `True` when the new position is at Euclidean distance
    `<= 0.1` from the goal `(0.75, 0.2)`. Registered as `geoq/TwoRooms-v0` with a
    time limit of 200 steps, after which `truncated` is `True`.

    ## Success

    `info["is_success"]` (Stable-Baselines3's convention) is `True` on the
    terminating step and `False` on the time limit's last step (the spec's
    `max_episode_steps`, 200 when made directly) if the goal was not reached;
    it is absent from other steps.

    ## Rendering

    `render_mode="rgb_array"`: `render()` returns the unit square as a
    400 x 400 x 3 uint8 image (numpy drawing, no display needed): the wall
    (dark) with its door, the goal disc (light green), the episode's path so far
    (light blue) and the point (blue). `render_fps` is 20.

    ## Arguments

    - `render_mode`: `None` or `"rgb_array"`.
    - `start_noise`: half-width of the uniform start noise (default `0.05`, at
      most `0.2` so that every start is in the left room).

    ```python
    >>> import gymnasium as gym, numpy as np, geoq
    >>> env = gym.make("geoq/TwoRooms-v0")
    >>> obs, info = env.reset(seed=0)
    >>> obs, reward, terminated, truncated, info = env.step(np.array([1.0, 0.0]))

    ```

    ## Version History

    * v0: Initial version.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 20}  # noqa: RUF012

    def __init__(
        self, render_mode: str | None = None, start_noise: float = TWO_ROOMS_START_NOISE
    ) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        if not np.isfinite(start_noise) or not 0.0 <= start_noise <= 0.2:
            raise ValueError(
                f"start_noise must be in [0, 0.2] (starts stay in the left room), "
                f"got {start_noise!r}"
            )
        self.render_mode = render_mode
        self.start_noise = float(start_noise)
        self.action_space = spaces.Box(low=-1.0, high=1.0, shape=(2,), dtype=np.float64)
        self.observation_space = spaces.Box(low=0.0, high=1.0, shape=(2,), dtype=np.float64)
        self.state: FloatArray | None = None
        self._steps = 0
        self._path: list[FloatArray] = []  # this episode's states, shown by render()
        self._painter = TwoRoomsPainter()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[FloatArray, dict[str, Any]]:
        """Start an episode near ``(0.25, 0.2)`` (seeded noise) or at ``options["state"]``."""
        super().reset(seed=seed)
        start = start_option(options)
        if start is None:
            self.state = sample_two_rooms_starts(self.np_random, 1, self.start_noise)[0]
        else:
            self.state = self._check_state(start)
        self._steps = 0
        self._path = [self.state.copy()]
        return self.state.copy(), {}

    def step(self, action: Any) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        """Apply one move; return ``(obs, -1.0, terminated, False, info)``.

        ``info`` holds ``is_success`` at the episode's end only (see the class
        docstring); truncation itself is the time-limit wrapper's.
        """
        if self.state is None:
            raise RuntimeError("call reset() before step()")
        raw = np.asarray(action)
        if np.iscomplexobj(raw) or raw.dtype.kind not in "biuf":
            raise ValueError(f"action has dtype {raw.dtype}; expected a real move [dx, dy]")
        a = raw.astype(np.float64)
        if a.shape != (2,):
            raise ValueError(f"action has shape {a.shape}; expected (2,) (one move [dx, dy])")
        if not np.isfinite(a).all():
            raise ValueError(f"action {a!r} is not finite; pass a move in [-1, 1]^2")
        next_state, reward, terminated = two_rooms_step(self.state, a)
        self.state = next_state
        self._steps += 1
        if self.render_mode is not None:
            self._path.append(next_state.copy())
        done = bool(terminated)
        info: dict[str, Any] = {}
        if done or self._steps == self._horizon():
            info["is_success"] = done
        return next_state.copy(), float(reward), done, False, info

    def render(self) -> np.ndarray | None:
        """The current state as an ``[400, 400, 3]`` uint8 image (``render_mode="rgb_array"``).

        Without a render mode: a warning (Gymnasium's convention) and ``None``.
        """
        if state_to_render(self, self.state) is None:
            return None
        return self._painter.frame(np.array(self._path))

    def _horizon(self) -> int:
        return episode_horizon(self.spec, _DEFAULT_HORIZON)

    def _check_state(self, state: Any) -> FloatArray:
        s = numeric_start_state(state, ("x", "y"))
        if np.any(s < 0.0) or np.any(s > 1.0):
            raise ValueError(
                f"options['state'] = {s.tolist()} is outside the unit square; "
                "expected 0 <= x, y <= 1"
            )
        return s.copy()
