"""Where a model has data: the distance from a state to the nearest state seen.

A planner must not believe a model where the task has never been (MOReL, Kidambi et
al. 2020, halts its roll-outs there). A GP's own variance does not say it: an output
that ignores an input (an ARD length-scale at its bound) is as sure far along that
input as on the data, and an output whose budget cannot cover its data is unsure on
it. :class:`StateSupport` measures it directly: the distance from a state to the
nearest state seen, in units of the states' standard deviations, divided by the data's
own spacing (the 99th percentile of the seen states' nearest-neighbour distances, set
at :meth:`StateSupport.reset`). 1 or less: among the data. Along trajectories a
state's nearest neighbour is its own next step, so that spacing measures a step; given
the newest states apart, the spacing is instead the 99th percentile of their
distances to the older ones: how far new experience lands from the old
(``ModelSettings.support_holdout``).

The states live in a k-d tree (:class:`scipy.spatial.cKDTree`) and, once added, in a
short list searched by brute force until ``REBUILD`` of them wait; the tree is then
rebuilt. The nearest distance does not depend on where a state is kept.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from geoq._typing import FloatArray

__all__ = ["REBUILD", "StateSupport"]

#: States waiting outside the tree before it is rebuilt with them.
REBUILD = 64
#: Seen states the spacing is computed from (a random subsample beyond).
_SPACING_POINTS = 1000


class StateSupport:
    """Seen states ``[N, d]`` (scaled by ``scale`` [d]) and the distance to them."""

    def __init__(
        self, states: FloatArray, scale: FloatArray, rng: np.random.Generator,
        newest: FloatArray | None = None,
    ) -> None:  # fmt: skip
        self.reset(states, scale, rng, newest)

    def reset(
        self, states: FloatArray, scale: FloatArray, rng: np.random.Generator,
        newest: FloatArray | None = None,
    ) -> None:  # fmt: skip
        """Start again from ``states`` [N, d]: the scale and the spacing follow them. With
        ``newest`` [n, d] (states that came after all of ``states``), the spacing is the
        99th percentile of their distances to ``states``, and they join the seen states."""
        self.scale = np.asarray(scale, dtype=np.float64)
        old = np.asarray(states, dtype=np.float64) / self.scale
        Z = np.unique(old if newest is None else np.vstack([old, newest / self.scale]), axis=0)
        self._tree_points, self._pending = Z, np.zeros((0, Z.shape[1]))
        self._tree = cKDTree(Z)
        if newest is not None and len(newest):
            probe = newest / self.scale
            probe = probe if len(probe) <= _SPACING_POINTS else probe[
                rng.choice(len(probe), _SPACING_POINTS, False)]  # fmt: skip
            nearest = cKDTree(np.unique(old, axis=0)).query(probe)[0]
        else:
            probe = (
                Z if len(Z) <= _SPACING_POINTS else Z[rng.choice(len(Z), _SPACING_POINTS, False)]
            )
            nearest = self._tree.query(probe, k=2)[0][:, 1] if len(Z) > 1 else np.zeros(1)
        self.spacing = max(float(np.quantile(nearest, 0.99)), 1e-12)

    def add(self, state: FloatArray) -> None:
        """One more seen state ``[d]``."""
        self._pending = np.vstack([self._pending, np.asarray(state, dtype=np.float64) / self.scale])
        if len(self._pending) >= REBUILD:
            self._tree_points = np.vstack([self._tree_points, self._pending])
            self._pending = self._pending[:0]
            self._tree = cKDTree(self._tree_points)

    def distance(self, states: FloatArray) -> FloatArray:
        """Distance ``[P]`` of ``states`` [P, d] to the nearest seen state, in spacings."""
        Z = states / self.scale
        d = self._tree.query(Z)[0]
        if len(self._pending):
            diff = Z[:, None, :] - self._pending[None, :, :]
            d = np.minimum(d, np.sqrt(np.min(np.einsum("pkd,pkd->pk", diff, diff), axis=1)))
        return d / self.spacing

    def distance_gradient(self, states: FloatArray) -> tuple[FloatArray, FloatArray]:
        """:meth:`distance` ``[P]`` and its gradient ``[P, d]`` with respect to ``states``
        (the nearest seen state held fixed; 0 on a seen state)."""
        Z = states / self.scale
        dist, index = self._tree.query(Z)
        nearest = self._tree_points[index]
        if len(self._pending):
            diff = Z[:, None, :] - self._pending[None, :, :]
            d2 = np.einsum("pkd,pkd->pk", diff, diff)
            k = np.argmin(d2, axis=1)
            closer = np.sqrt(d2[np.arange(len(Z)), k]) < dist
            nearest[closer] = self._pending[k[closer]]
        away = Z - nearest
        dist = np.sqrt(np.einsum("pd,pd->p", away, away))
        grad = away / (np.where(dist > 0, dist, 1.0)[:, None] * self.scale * self.spacing)
        return dist / self.spacing, grad

    def to_arrays(self) -> dict[str, Any]:
        """The scaled states (the tree's, then the waiting ones), where they split, the scale
        and the spacing."""
        return {
            "scaled_states": np.vstack([self._tree_points, self._pending]),
            "in_tree": np.array(len(self._tree_points)),
            "scale": self.scale,
            "spacing": np.array(self.spacing),
        }

    @classmethod
    def from_arrays(cls, a: dict[str, Any]) -> StateSupport:
        """Inverse of :meth:`to_arrays` (``ValueError`` on inconsistent arrays)."""
        support = cls.__new__(cls)
        support.scale = np.asarray(a["scale"], dtype=np.float64)
        Z = np.asarray(a["scaled_states"], dtype=np.float64)
        n, spacing = int(a["in_tree"]), float(a["spacing"])
        if Z.ndim != 2 or Z.shape[1] != support.scale.shape[0] or not 1 <= n <= len(Z):
            raise ValueError("support states do not match their scale or split")
        if not (np.all(np.isfinite(Z)) and np.isfinite(spacing) and spacing > 0):
            raise ValueError("support states and spacing must be finite (spacing positive)")
        support._tree_points, support._pending = Z[:n], Z[n:]
        support._tree, support.spacing = cKDTree(Z[:n]), spacing
        return support
