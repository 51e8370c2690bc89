"""The frames of the envs' ``render_mode="rgb_array"``: pure functions of the state.

* :func:`pendulum_frame`: the swing-up's rod, success zone and torque.
* :func:`two_rooms_frame` / :class:`TwoRoomsPainter`: the two rooms, the goal and the
  path walked so far.
* :func:`check_render_mode` / :func:`warn_no_render_mode`: Gymnasium's render-mode
  conventions, shared by the shells.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import TypeVar

import gymnasium
import numpy as np

from geoq._typing import FloatArray
from geoq.envs._draw import Canvas
from geoq.envs.two_rooms import DOOR, GOAL, GOAL_RADIUS, WALL_X

__all__ = [
    "FRAME_SIZE",
    "TwoRoomsPainter",
    "check_render_mode",
    "pendulum_frame",
    "state_to_render",
    "two_rooms_frame",
]

_S = TypeVar("_S")

#: Width and height of every frame, in pixels.
FRAME_SIZE = 400

_ROD = (204, 77, 77)  # Gymnasium's Pendulum-v1 rod colour
_DARK = (40, 40, 40)
_ZONE = (205, 238, 205)
_TRACK = (225, 225, 225)
_BLUE = (45, 85, 200)
_PATH = (160, 180, 230)


def check_render_mode(render_mode: str | None, supported: Sequence[str]) -> None:
    """A ``ValueError`` naming the supported modes unless ``render_mode`` is one or None."""
    if render_mode is not None and render_mode not in supported:
        choices = ", ".join(repr(m) for m in supported)
        raise ValueError(f"render_mode {render_mode!r} is not supported; use None or {choices}")


def state_to_render(env: gymnasium.Env[FloatArray, FloatArray], state: _S | None) -> _S | None:
    """The ``state`` ``render()`` draws; None, with Gymnasium's warning, for an env made
    without a render mode; a ``RuntimeError`` before the first ``reset()`` (no ``state``)."""
    if env.render_mode is None:
        spec = env.spec.id if env.spec is not None else type(env).__name__
        gymnasium.logger.warn(
            "You are calling render method without specifying any render mode. "
            f'You can specify the render_mode at initialization, e.g. gym.make("{spec}", '
            'render_mode="rgb_array")'
        )
        return None
    if state is None:
        raise RuntimeError("call reset() before render()")
    return state


def pendulum_frame(
    theta: float, torque: float, max_torque: float, success_angle: float
) -> np.ndarray:
    """The swing-up at angle ``theta`` (rad, 0 up, positive clockwise on screen) after a
    torque ``torque``: an ``[FRAME_SIZE, FRAME_SIZE, 3]`` uint8 image.

    Light green: the success zone ``|theta| < success_angle``; red: the rod (1 m); the
    bar under the pivot: the torque, full width at ``max_torque``, right for positive.
    """
    n = FRAME_SIZE
    c, length = 0.5 * n, 0.36 * n
    bar_y, half = 0.92 * n, 0.4 * n
    canvas = _pendulum_background(success_angle).copy()
    tip = (c + length * np.sin(theta), c - length * np.cos(theta))
    canvas.segment((c, c), tip, 0.04 * n, _ROD)
    canvas.disc((c, c), 0.015 * n, _DARK)
    share = float(np.clip(torque / max_torque, -1.0, 1.0)) if max_torque > 0 else 0.0
    if share != 0.0:
        canvas.rectangle(c, bar_y - 0.01 * n, c + half * share, bar_y + 0.01 * n, _BLUE)
    canvas.segment((c, bar_y - 0.025 * n), (c, bar_y + 0.025 * n), 2.0, _DARK)
    return canvas.to_uint8()


@functools.lru_cache(maxsize=4)
def _pendulum_background(success_angle: float) -> Canvas:
    """What every swing-up frame shows: the success zone and the torque bar's track."""
    n = FRAME_SIZE
    c, length = 0.5 * n, 0.36 * n
    bar_y, half = 0.92 * n, 0.4 * n
    canvas = Canvas(n, n)
    canvas.sector((c, c), length + 0.05 * n, 0.0, success_angle, _ZONE)
    canvas.segment((c - half, bar_y), (c + half, bar_y), 0.02 * n, _TRACK)
    return canvas


_MARGIN = 0.05 * FRAME_SIZE
_SIDE = FRAME_SIZE - 2 * _MARGIN


def _rooms_px(xy: FloatArray) -> FloatArray:
    """Unit-square points ``[n, 2]`` (``y`` up) -> pixel coordinates ``[n, 2]`` (``y`` down)."""
    xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
    return np.stack([_MARGIN + _SIDE * xy[:, 0], _MARGIN + _SIDE * (1.0 - xy[:, 1])], axis=1)


@functools.lru_cache(maxsize=1)
def _rooms_background() -> Canvas:
    """What every two-rooms frame shows: the square, the goal and the wall with its door."""
    n = FRAME_SIZE
    canvas = Canvas(n, n, background=(235, 235, 235))
    canvas.rectangle(_MARGIN, _MARGIN, n - _MARGIN, n - _MARGIN, (255, 255, 255))
    canvas.disc(_rooms_px(np.array(GOAL))[0], GOAL_RADIUS * _SIDE, _ZONE)
    wall = _rooms_px(np.array([[WALL_X, 0.0], [WALL_X, DOOR[0]]]))
    canvas.segment(wall[0], wall[1], 0.015 * n, _DARK)
    return canvas


class TwoRoomsPainter:
    """Frames of one two-rooms episode.

    The path's layer grows by the new segments only, so a frame costs about the same
    at every step (one segment, one disc, the copies). Each segment is drawn on its
    own, in order, so a frame depends on the path alone, not on which earlier frames
    were asked for.
    """

    def __init__(self) -> None:
        self._layer: Canvas | None = None
        self._drawn = np.empty((0, 2))

    def frame(self, path: FloatArray) -> np.ndarray:
        """The rooms with the points ``path`` ``[n >= 1, 2]`` walked so far (the last is
        the current position): an ``[FRAME_SIZE, FRAME_SIZE, 3]`` uint8 image."""
        pts = _rooms_px(path)
        k = len(self._drawn)
        if (
            self._layer is None
            or k == 0
            or len(pts) < k
            or not np.array_equal(pts[:k], self._drawn)
        ):
            self._layer, k = _rooms_background().copy(), 1
        for i in range(k, len(pts)):
            self._layer.segment(pts[i - 1], pts[i], 0.006 * FRAME_SIZE, _PATH)
        self._drawn = pts
        canvas = self._layer.copy()
        canvas.disc(pts[-1], 0.018 * FRAME_SIZE, _BLUE)
        return canvas.to_uint8()


def two_rooms_frame(path: FloatArray) -> np.ndarray:
    """The two rooms with the points ``path`` ``[n >= 1, 2]`` walked so far (the last is the
    current position): an ``[FRAME_SIZE, FRAME_SIZE, 3]`` uint8 image, ``y`` up."""
    return TwoRoomsPainter().frame(path)
