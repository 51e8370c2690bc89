"""Candidate actions and acquisitions: exactness on parabolas, brute force over dense grids."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoq.agents.acquisition import (
    acquisition_scores,
    candidate_actions,
    choose_actions,
    refine_on_grid,
)


def test_grid_in_one_dimension_spans_the_box() -> None:
    c = candidate_actions(np.array([-5.0]), np.array([5.0]), 21)
    assert c.shape == (21, 1)
    np.testing.assert_allclose(c[:, 0], np.linspace(-5, 5, 21))


def test_sobol_candidates_fill_the_box_and_are_seeded() -> None:
    lo, hi = np.array([-1.0, 0.0, 2.0]), np.array([1.0, 0.5, 3.0])
    a = candidate_actions(lo, hi, 30, np.random.default_rng(1))
    b = candidate_actions(lo, hi, 30, np.random.default_rng(1))
    assert a.shape == (32, 3)  # rounded up to a power of two
    np.testing.assert_array_equal(a, b)
    assert np.all(a >= lo) and np.all(a <= hi)
    with pytest.raises(ValueError, match="rng"):
        candidate_actions(lo, hi, 30)


@pytest.mark.parametrize(
    ("low", "high", "n", "match"),
    [([0.0], [np.inf], 5, "finite"), ([1.0], [0.0], 5, "high < low"), ([0.0], [1.0], 1, "2")],
)
def test_bad_candidate_arguments(low: list[float], high: list[float], n: int, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        candidate_actions(np.array(low), np.array(high), n)


@settings(max_examples=60, deadline=None)
@given(
    vertex=st.floats(-4.2, 4.2),
    curvature=st.floats(0.05, 20.0),
    offset=st.floats(-100, 100),
)
def test_refinement_is_exact_on_a_concave_parabola(
    vertex: float, curvature: float, offset: float
) -> None:
    grid = np.linspace(-5.0, 5.0, 21)
    scores = offset - curvature * (grid - vertex) ** 2
    a = refine_on_grid(scores[None, :], grid)
    assert a[0] == pytest.approx(vertex, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    coeffs=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    freqs=st.lists(st.floats(0.2, 2.0), min_size=3, max_size=3),
    phases=st.lists(st.floats(0.0, 6.3), min_size=3, max_size=3),
)
def test_refined_maximiser_against_brute_force_on_a_dense_grid(
    coeffs: list[float], freqs: list[float], phases: list[float]
) -> None:
    """f(refined) >= max over a dense grid - (f'' bound) h^2 / 8 - (f''' bound) h^3."""
    c, w, p = np.array(coeffs), np.array(freqs), np.array(phases)

    def f(a: np.ndarray) -> np.ndarray:
        return np.sum(c * np.sin(np.multiply.outer(a, w) + p), axis=-1)

    grid = np.linspace(-5.0, 5.0, 41)
    h = grid[1] - grid[0]
    a = refine_on_grid(f(grid)[None, :], grid)[0]
    dense = np.linspace(-5.0, 5.0, 20_001)
    m2, m3 = np.sum(np.abs(c) * w**2), np.sum(np.abs(c) * w**3)
    assert -5.0 <= a <= 5.0
    assert f(np.array([a]))[0] >= f(dense).max() - m2 * h**2 / 8 - m3 * h**3 - 1e-12
    # Never worse than the grid's own best point, up to the interpolation error.
    assert f(np.array([a]))[0] >= f(grid).max() - m3 * h**3 - 1e-12


def _refine_reference(row: np.ndarray, grid: np.ndarray) -> float:
    """One row by hand: first argmax, parabola vertex only if interior and concave."""
    i = int(np.argmax(row))
    if not 0 < i < len(row) - 1:
        return float(grid[i])
    left, mid, right = row[i - 1], row[i], row[i + 1]
    curvature = left - 2.0 * mid + right
    offset = min(max(0.5 * (left - right) / curvature, -0.5), 0.5) if curvature < 0 else 0.0
    return float(grid[i] + offset * (grid[1] - grid[0]))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), K=st.integers(2, 25), n=st.integers(1, 6))
def test_refinement_of_each_row_matches_a_per_row_reference(seed: int, K: int, n: int) -> None:
    """Every row of a batch, bit for bit: ties (rounded scores), maxima at either end,
    flat and convex neighbourhoods."""
    rng = np.random.default_rng(seed)
    scores = np.round(rng.normal(size=(n, K)), 1)  # ties are common
    scores[0, rng.integers(K)] = scores[0].max() + 1.0  # a clear maximum anywhere
    grid = np.linspace(-2.0, 3.0, K)
    got = refine_on_grid(scores, grid)
    assert got.shape == (n,)
    assert got.tolist() == [_refine_reference(row, grid) for row in scores]


def test_scores() -> None:
    mean, std = np.array([[1.0, 2.0, 0.5]]), np.array([[1.0, 0.0, 3.0]])
    np.testing.assert_array_equal(acquisition_scores(mean, std, "greedy"), mean)
    np.testing.assert_array_equal(acquisition_scores(mean, std, "ucb", beta=1.0), [[2, 2, 3.5]])
    a = acquisition_scores(mean, std, "thompson", rng=np.random.default_rng(0))
    b = acquisition_scores(mean, std, "thompson", rng=np.random.default_rng(0))
    np.testing.assert_array_equal(a, b)
    assert a[0, 1] == 2.0  # zero std: the sample is the mean
    with pytest.raises(ValueError, match="exploration"):
        acquisition_scores(mean, std, "nope")  # type: ignore[arg-type]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), mode=st.sampled_from(["ucb", "thompson", "gaussian"]))
def test_chosen_actions_are_finite_and_inside_the_box(seed: int, mode: str) -> None:
    rng = np.random.default_rng(seed)
    for low, high in (([-5.0], [5.0]), ([-1.0, 0.0], [1.0, 2.0])):
        lo, hi = np.array(low), np.array(high)
        cand = candidate_actions(lo, hi, 16, rng)
        mean = rng.normal(size=(4, len(cand))) * 10
        std = np.abs(rng.normal(size=(4, len(cand))))
        a = choose_actions(
            mean, std, cand, mode, beta=2.0, noise_scale=5 * (hi - lo),  # type: ignore[arg-type]
            low=lo, high=hi, rng=rng,
        )  # fmt: skip
        assert a.shape == (4, len(lo))
        assert np.all(np.isfinite(a)) and np.all(a >= lo) and np.all(a <= hi)
