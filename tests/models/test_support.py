"""The data's support against brute-force nearest neighbours."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoq.models.support import REBUILD, StateSupport


def _brute(seen: np.ndarray, queries: np.ndarray, scale: np.ndarray) -> np.ndarray:
    diff = queries[:, None, :] / scale - seen[None, :, :] / scale
    return np.sqrt(np.min(np.sum(diff**2, axis=2), axis=1))


@settings(max_examples=25, deadline=None)
@given(n=st.integers(2, 60), added=st.integers(0, 2 * REBUILD + 3), seed=st.integers(0, 2**16))
def test_the_distance_is_the_nearest_seen_state_in_spacings(n: int, added: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    scale = rng.uniform(0.1, 3.0, size=3)
    seen = rng.normal(size=(n, 3))
    support = StateSupport(seen, scale, rng)
    more = rng.normal(size=(added, 3))
    for s in more:
        support.add(s)
    queries = rng.normal(scale=2.0, size=(17, 3))
    expected = _brute(np.vstack([seen, more]), queries, scale) / support.spacing
    np.testing.assert_allclose(support.distance(queries), expected, rtol=1e-10, atol=1e-12)


def test_the_spacing_is_the_99th_percentile_of_nearest_neighbour_distances() -> None:
    grid = np.array([[i, j] for i in range(10) for j in range(10)], dtype=float)
    support = StateSupport(grid, np.array([1.0, 2.0]), np.random.default_rng(0))
    assert support.spacing == pytest.approx(0.5)  # y / 2 puts each row 0.5 from the next
    assert support.distance(grid).max() == 0.0
    # (4.5, 30) scaled is (4.5, 15): 0.5 from x = 4 or 5, 10.5 above y = 9 / 2.
    far = support.distance(np.array([[4.5, 30.0]]))[0]
    assert far == pytest.approx(np.hypot(0.5, 10.5) / 0.5)


def test_arrays_round_trip_with_the_waiting_states() -> None:
    rng = np.random.default_rng(1)
    support = StateSupport(rng.normal(size=(30, 2)), np.ones(2), rng)
    for s in rng.normal(size=(REBUILD + 5, 2)):
        support.add(s)
    copy = StateSupport.from_arrays(support.to_arrays())
    q = rng.normal(size=(40, 2))
    assert np.array_equal(copy.distance(q), support.distance(q))
    bad = support.to_arrays() | {"in_tree": np.array(0)}
    with pytest.raises(ValueError, match="split"):
        StateSupport.from_arrays(bad)
