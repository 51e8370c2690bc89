"""Task facts and input scaling: from the space bounds, or from data where they are infinite."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

from geoq.tasks import TaskInfo, box_scaling, data_scaling, has_finite_bounds, task_info


def test_data_scaling_uses_bounds_where_finite_and_robust_spread_elsewhere() -> None:
    obs = gymnasium.spaces.Box(
        np.array([-2.0, -np.inf, -np.inf]), np.array([2.0, np.inf, np.inf]), dtype=np.float64
    )
    act = gymnasium.spaces.Box(-3.0, 3.0, shape=(1,), dtype=np.float64)
    info = TaskInfo(periods=(0.0, 0.0, 2 * np.pi), names=("a", "b", "angle"))
    rng = np.random.default_rng(0)
    S = np.column_stack([rng.uniform(-2, 2, 500), rng.normal(5.0, 10.0, 500), rng.normal(size=500)])
    S[0, 1] = 1e9  # one far state does not set the scale
    sc = data_scaling(S, obs, act, info)
    q05, q95 = np.quantile(S[:, 1], [0.05, 0.95])
    assert sc.scale == (2.0, pytest.approx(0.5 * (q95 - q05)), pytest.approx(np.pi), 3.0)
    assert sc.periods == (0.0, 0.0, 2 * np.pi, 0.0)
    assert sc.names == ("a", "b", "angle", "a0")
    assert not has_finite_bounds(obs) and has_finite_bounds(act)
    # A dimension that never moved gets 1; finite bounds agree with box_scaling.
    still = data_scaling(np.zeros((4, 3)), obs, act, info)
    assert still.scale[1] == 1.0
    finite = gymnasium.spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float64)
    assert data_scaling(np.zeros((2, 3)), finite, act, info) == box_scaling(finite, act, info)
    with pytest.raises(ValueError, match="collect some steps first"):
        data_scaling(np.zeros((0, 3)), obs, act, info)
    with pytest.raises(ValueError, match="NaN or inf"):
        data_scaling(np.full((2, 3), np.nan), obs, act, info)
    with pytest.raises(ValueError, match="infinite bounds"):
        box_scaling(obs, act, info)


def test_a_known_task_whose_observations_a_wrapper_reshaped_is_unknown() -> None:
    """TwoRooms observed with 3 more features: its names and periods are of 2 inputs."""
    box = gymnasium.spaces.Box(-1.0, 1.0, shape=(5,), dtype=np.float64)
    env = gymnasium.wrappers.TransformObservation(
        gymnasium.make("geoq/TwoRooms-v0"), lambda o: np.concatenate([o, np.zeros(3)]), box
    )
    info = task_info(env)
    assert info.periods == (0.0,) * 5 and info.names == ("s0", "s1", "s2", "s3", "s4")
    assert task_info(gymnasium.make("geoq/TwoRooms-v0")).names != info.names
