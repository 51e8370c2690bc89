"""Choosing a continuous action from a GP Q-function: candidates, acquisitions, maximisers.

Every function here is pure: it takes the posterior mean and standard deviation
of ``Q(s, a)`` at a batch of candidate actions (one batched GP call per step
gives them for every candidate at once) and returns scores or actions.

* :func:`candidate_actions`: a regular grid over a 1-D action interval; in more
  dimensions a scrambled Sobol' set over the box (random shooting), drawn from
  the caller's generator.
* Acquisitions: greedy (``mean``), upper confidence bound ``mean + beta * std``
  (GP-UCB, Srinivas et al. 2010) and Thompson-style sampling ``mean + std * xi``
  with ``xi ~ N(0, 1)`` drawn independently per candidate (the marginal
  posterior at each candidate; correlations between candidates are ignored).
* :func:`refine_on_grid`: on a 1-D grid, the vertex of the parabola through the
  best grid score and its two neighbours (successive parabolic interpolation,
  one step), so the chosen action is not limited to the grid and no second GP
  call is needed.
"""

from __future__ import annotations

from typing import Literal

import numba
import numpy as np
import scipy.stats

from geoq._typing import FloatArray

__all__ = [
    "EXPLORATION_MODES",
    "Exploration",
    "acquisition_scores",
    "candidate_actions",
    "choose_actions",
    "refine_on_grid",
]

Exploration = Literal["ucb", "thompson", "gaussian", "greedy"]
#: Exploration modes of the agent: two from the GP's own uncertainty, a plain
#: Gaussian-noise baseline on the greedy action, and none.
EXPLORATION_MODES: tuple[str, ...] = ("ucb", "thompson", "gaussian", "greedy")


def candidate_actions(
    low: FloatArray, high: FloatArray, n: int, rng: np.random.Generator | None = None
) -> FloatArray:
    """Candidate actions ``[n, d_a]`` inside the box ``[low, high]``.

    One action dimension: ``n`` evenly spaced points, both ends included (the
    same grid every call; ``rng`` is not used). More dimensions: a scrambled
    Sobol' set of ``n`` points (``n`` is rounded up to a power of two), seeded
    from ``rng``, which is then required.
    """
    lo = np.asarray(low, dtype=np.float64).reshape(-1)
    hi = np.asarray(high, dtype=np.float64).reshape(-1)
    if lo.shape != hi.shape or not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ValueError("the action box must have finite low and high bounds of the same shape")
    if np.any(hi < lo):
        raise ValueError(f"action box has high < low: low={lo}, high={hi}")
    if int(n) < 2:
        raise ValueError(f"need at least 2 candidate actions, got {n}")
    if lo.size == 1:
        return np.linspace(lo[0], hi[0], int(n))[:, None]
    if rng is None:
        raise ValueError("candidate actions in more than one dimension need rng=")
    m = int(np.ceil(np.log2(int(n))))
    sobol = scipy.stats.qmc.Sobol(d=lo.size, scramble=True, seed=rng)
    return lo + (hi - lo) * sobol.random_base2(m)


def acquisition_scores(
    mean: FloatArray,
    std: FloatArray,
    mode: Exploration,
    beta: float = 2.0,
    rng: np.random.Generator | None = None,
) -> FloatArray:
    """Scores ``[..., K]`` of the candidates: the action maximising them is taken.

    ``mean`` and ``std`` are the posterior of ``Q`` at the candidates, same shape.
    ``"gaussian"`` and ``"greedy"`` score by the mean (the Gaussian baseline adds
    its noise to the chosen action, not to the scores).
    """
    if mode == "ucb":
        return mean + beta * std
    if mode == "thompson":
        if rng is None:
            raise ValueError("thompson scores need rng=")
        return mean + std * rng.standard_normal(mean.shape)
    if mode in ("gaussian", "greedy"):
        return mean
    raise ValueError(f"exploration must be one of {EXPLORATION_MODES}, got {mode!r}")


def refine_on_grid(scores: FloatArray, grid: FloatArray) -> FloatArray:
    """Maximiser of ``scores`` [n, K] over an evenly spaced 1-D ``grid`` [K], refined.

    For each row, the best grid index ``i`` (the first, on ties) and, when it is
    interior and the parabola through ``(g_{i-1}, g_i, g_{i+1})`` is concave, that
    parabola's vertex (it lies within half a grid step of ``g_i``; its interpolated
    score is at least the grid maximum). Scores must be finite. Returns actions ``[n]``.
    """
    scores = np.ascontiguousarray(scores, dtype=np.float64)
    out = np.empty(scores.shape[0])
    _refine_rows(scores, np.ascontiguousarray(grid, dtype=np.float64), out)
    return out


@numba.njit(cache=True, nogil=True)
def _refine_rows(
    scores: FloatArray, grid: FloatArray, out: FloatArray
) -> None:  # pragma: no cover - compiled
    """:func:`refine_on_grid` row by row (one compiled call: an agent step asks for one
    row, and numpy's per-call overhead was most of its cost)."""
    n, K = scores.shape
    h = grid[1] - grid[0] if K > 1 else 0.0
    for r in range(n):
        row = scores[r]
        i = 0
        for k in range(1, K):
            if row[k] > row[i]:
                i = k
        if 0 < i < K - 1:
            left, mid, right = row[i - 1], row[i], row[i + 1]
            curvature = left - 2.0 * mid + right  # < 0 for a concave parabola
            offset = 0.0
            if curvature < 0.0:
                offset = min(max(0.5 * (left - right) / curvature, -0.5), 0.5)
            out[r] = grid[i] + offset * h
        else:
            out[r] = grid[i]


def choose_actions(
    mean: FloatArray,
    std: FloatArray,
    candidates: FloatArray,
    mode: Exploration,
    *,
    beta: float,
    noise_scale: FloatArray,
    low: FloatArray,
    high: FloatArray,
    rng: np.random.Generator,
) -> FloatArray:
    """One action ``[n, d_a]`` per state from the posterior at the candidates.

    ``mean``, ``std``: ``[n, K]`` at the candidates ``[K, d_a]``. 1-D actions on a
    grid are refined by :func:`refine_on_grid`; in more dimensions the best
    candidate is taken. ``"gaussian"`` adds ``N(0, noise_scale^2)`` to the greedy
    action. Actions are clipped to the box.
    """
    scores = acquisition_scores(mean, std, mode, beta, rng)
    if candidates.shape[1] == 1:
        actions = refine_on_grid(scores, candidates[:, 0])[:, None]
    else:
        actions = candidates[np.argmax(scores, axis=1)]
    if mode == "gaussian":
        actions = actions + noise_scale * rng.standard_normal(actions.shape)
    return np.clip(actions, low, high)
