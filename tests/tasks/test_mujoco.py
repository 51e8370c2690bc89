"""The agent on Gymnasium's MuJoCo tasks: runs, acts in the box, is reproducible.

Needs the optional extra ``mujoco`` (``make test-mujoco``); skipped without it. These are
smoke tests of the plumbing (unbounded observations scaled from the warm-up's data,
more than three inputs, two action dimensions), not of learning: the learning figures
are the benchmark's (``geoq bench-control --env InvertedPendulum-v5``).
"""

from __future__ import annotations

from pathlib import Path

import gymnasium
import numpy as np
import pytest

pytest.importorskip("mujoco", reason="the optional extra mujoco is not installed")
pytest.importorskip("imageio", reason="the optional extra mujoco is not installed")

from geoq.agents import GPQAgent

pytestmark = pytest.mark.mujoco

TASKS = {"InvertedPendulum-v5": (4, 1), "Reacher-v5": (10, 2)}


@pytest.mark.parametrize("env_id", sorted(TASKS))
def test_the_agent_learns_acts_and_reloads(env_id: str, tmp_path: Path) -> None:
    obs_dim, action_dim = TASKS[env_id]
    agent = GPQAgent(env_id, seed=0).learn(300)
    assert (agent.obs_dim, agent.action_dim) == (obs_dim, action_dim)
    assert agent.config.max_bv == 800  # more than three inputs
    assert not agent.state.scaling_pending  # unbounded observations: scaled after warm-up
    assert np.all(np.isfinite(agent.scaling.scale)) and np.all(np.asarray(agent.scaling.scale) > 0)
    env = gymnasium.make(env_id)
    obs, _ = env.reset(seed=1)
    action, _ = agent.predict(obs)
    assert action.shape == (action_dim,) and env.action_space.contains(
        action.astype(env.action_space.dtype)
    )
    again = GPQAgent(env_id, seed=0).learn(300)
    np.testing.assert_array_equal(
        again.buffer.transitions().actions, agent.buffer.transitions().actions
    )
    agent.save(tmp_path / "agent.npz")
    loaded = GPQAgent.load(tmp_path / "agent.npz")
    np.testing.assert_array_equal(loaded.predict(obs)[0], action)
