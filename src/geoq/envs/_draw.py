"""A few anti-aliased shapes drawn with numpy: the frames of the envs' ``rgb_array`` render.

Every shape is a signed distance over the pixel grid, turned into a coverage in
``[0, 1]`` (one pixel of smooth edge) and blended into the canvas. No state, no
randomness: the same calls give the same bytes. Each shape touches only the
pixels of its bounding box.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence

import numpy as np

from geoq._typing import FloatArray

__all__ = ["Canvas"]

Color = tuple[int, int, int]


@functools.lru_cache(maxsize=4)
def _pixel_centres(height: int, width: int) -> tuple[FloatArray, FloatArray]:
    """Read-only ``y``, ``x`` of every pixel centre, ``[height, width]`` each."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float64) + 0.5
    y.flags.writeable = False
    x.flags.writeable = False
    return y, x


class Canvas:
    """An ``[height, width, 3]`` image in pixel coordinates (x right, y down).

    Parameters
    ----------
    width, height : size in pixels.
    background : RGB colour of the empty canvas.
    """

    def __init__(self, width: int, height: int, background: Color = (255, 255, 255)) -> None:
        self.image = np.empty((height, width, 3), dtype=np.float64)
        self.image[...] = background
        self._y, self._x = _pixel_centres(height, width)

    def copy(self) -> Canvas:
        """A canvas with a copy of this one's image (draw on it, this one stays)."""
        other = Canvas.__new__(Canvas)
        other.image = self.image.copy()
        other._y, other._x = self._y, self._x
        return other

    def _window(self, x0: float, y0: float, x1: float, y1: float) -> tuple[slice, slice]:
        """Rows and columns of the pixels within ``[x0, x1] x [y0, y1]`` (plus an edge pixel)."""
        h, w = self._x.shape
        cols = slice(max(int(np.floor(min(x0, x1))) - 1, 0), min(int(np.ceil(max(x0, x1))) + 2, w))
        rows = slice(max(int(np.floor(min(y0, y1))) - 1, 0), min(int(np.ceil(max(y0, y1))) + 2, h))
        return rows, cols

    def _blend(self, window: tuple[slice, slice], coverage: FloatArray, color: Color) -> None:
        a = np.clip(coverage, 0.0, 1.0)[..., None]
        region = self.image[window]
        region *= 1.0 - a
        region += a * np.asarray(color, dtype=np.float64)

    def disc(self, center: Sequence[float], radius: float, color: Color) -> None:
        """A filled disc."""
        cx, cy = center
        win = self._window(cx - radius, cy - radius, cx + radius, cy + radius)
        d = np.hypot(self._x[win] - cx, self._y[win] - cy) - radius
        self._blend(win, 0.5 - d, color)

    def _segment_distance(
        self, win: tuple[slice, slice], p: FloatArray, q: FloatArray
    ) -> FloatArray:
        """Distance of the window's pixel centres to the segment ``p -> q``."""
        v = q - p
        dx, dy = self._x[win] - p[0], self._y[win] - p[1]
        vv = float(v @ v)
        t = np.clip((dx * v[0] + dy * v[1]) / vv, 0.0, 1.0) if vv > 0 else 0.0
        return np.asarray(np.hypot(dx - t * v[0], dy - t * v[1]))

    def segment(
        self, start: Sequence[float], end: Sequence[float], width: float, color: Color
    ) -> None:
        """A line ``start -> end`` of ``width`` pixels with round caps."""
        self.polyline(np.array([start, end], dtype=np.float64), width, color)

    def polyline(self, points: FloatArray, width: float, color: Color) -> None:
        """Consecutive segments through ``points`` ``[n, 2]`` with round joints, drawn as
        one shape (no darker overlaps)."""
        pts = np.asarray(points, dtype=np.float64)
        if len(pts) < 2:
            return
        r = 0.5 * width
        lo, hi = pts.min(axis=0) - r, pts.max(axis=0) + r
        box = self._window(lo[0], lo[1], hi[0], hi[1])
        d = np.full(self._x[box].shape, np.inf)
        for p, q in itertools.pairwise(pts):
            win = self._window(min(p[0], q[0]) - r, min(p[1], q[1]) - r,
                               max(p[0], q[0]) + r, max(p[1], q[1]) + r)  # fmt: skip
            sub = (
                slice(win[0].start - box[0].start, win[0].stop - box[0].start),
                slice(win[1].start - box[1].start, win[1].stop - box[1].start),
            )
            np.minimum(d[sub], self._segment_distance(win, p, q), out=d[sub])
        self._blend(box, 0.5 - (d - r), color)

    def rectangle(self, x0: float, y0: float, x1: float, y1: float, color: Color) -> None:
        """A filled axis-aligned rectangle between the corners ``(x0, y0)`` and ``(x1, y1)``."""
        cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        hx, hy = 0.5 * abs(x1 - x0), 0.5 * abs(y1 - y0)
        win = self._window(cx - hx, cy - hy, cx + hx, cy + hy)
        d = np.maximum(np.abs(self._x[win] - cx) - hx, np.abs(self._y[win] - cy) - hy)
        self._blend(win, 0.5 - d, color)

    def sector(
        self,
        center: Sequence[float],
        radius: float,
        direction: float,
        half_angle: float,
        color: Color,
    ) -> None:
        """A filled circular sector: ``radius`` around ``center``, within ``half_angle`` rad
        of the screen direction ``direction`` (rad, 0 = up, clockwise positive)."""
        cx, cy = center
        win = self._window(cx - radius, cy - radius, cx + radius, cy + radius)
        dx, dy = self._x[win] - cx, self._y[win] - cy
        angle = np.arctan2(dx, -dy) - direction  # 0 = up, clockwise positive
        angle = (angle + np.pi) % (2.0 * np.pi) - np.pi
        inside = (np.abs(angle) <= half_angle) & (np.hypot(dx, dy) <= radius)
        self._blend(win, inside.astype(np.float64), color)

    def to_uint8(self) -> np.ndarray:
        """The image as ``[height, width, 3]`` uint8."""
        return np.rint(np.clip(self.image, 0.0, 255.0)).astype(np.uint8)
