"""GPQAgent's exploration map (``explore_map``): when it is built, what it leaves alone,
persistence and determinism with it."""

from __future__ import annotations

from pathlib import Path

import gymnasium
import numpy as np
import pytest
from tests.agents._tasks import PointToGoal

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent


def _point(seed: int = 0, **kw: object) -> GPQAgent:
    return GPQAgent(PointToGoal(), seed=seed, gamma=0.9, max_bv=40, **kw)  # type: ignore[arg-type]


def test_the_map_is_decided_on_after_two_steps_per_candidate() -> None:
    agent = _point()
    assert agent.explorer.decide_after == 2 * len(agent.candidates) == 42
    agent.learn(41)
    assert not agent.explorer.decided and agent.explorer.map is None
    agent.learn(1)
    assert agent.explorer.decided and agent.explorer.map is not None  # a point pushed around
    assert agent.explorer.map.n_transitions == 42
    agent.learn(10)
    assert agent.explorer.map.n_transitions == 52  # every later step goes in


def test_a_task_whose_state_integrates_a_velocity_gets_no_map_and_is_unchanged() -> None:
    """The swing-up's agent learns exactly as with ``explore_map="off"``, bit for bit."""
    auto = GPQAgent("geoq/PendulumSwingUp-v0", max_bv=40, seed=0, train_every=50).learn(120)
    off = GPQAgent("geoq/PendulumSwingUp-v0", max_bv=40, seed=0, train_every=50,
                   explore_map="off").learn(120)  # fmt: skip
    assert auto.explorer.decided and auto.explorer.map is None
    for a, b in zip(auto.buffer.arrays(), off.buffer.arrays(), strict=True):
        np.testing.assert_array_equal(a, b)
    on = GPQAgent("geoq/PendulumSwingUp-v0", max_bv=40, seed=0, train_every=50,
                  explore_map="on").learn(120)  # fmt: skip
    assert on.explorer.map is not None  # built whatever the test says
    assert not np.array_equal(on.buffer.arrays()[1], auto.buffer.arrays()[1])


class _HalfBoundedPoint(PointToGoal):
    """:class:`PointToGoal` whose observation space declares no upper bound."""

    def __init__(self) -> None:
        super().__init__()
        self.observation_space = gymnasium.spaces.Box(-1.0, np.inf, shape=(1,))


def test_only_a_box_the_space_bounds_everywhere_is_a_declared_one() -> None:
    """The map halves its cells only inside a box the space declares: with an infinite
    bound its box is partly the data's range, which says nothing of what lies beyond."""
    bounded = _point().learn(42).explorer.map
    assert bounded is not None and bounded.declared_box
    half = GPQAgent(_HalfBoundedPoint(), seed=0, gamma=0.9, max_bv=40).learn(200)  # type: ignore[arg-type]
    assert half.explorer.map is not None and not half.explorer.map.declared_box


def test_off_never_builds_a_map_and_bad_modes_are_refused() -> None:
    assert _point(explore_map="off").learn(100).explorer.map is None
    with pytest.raises(ValueError, match="explore_map must be one of"):
        _point(explore_map="sometimes")


def test_same_seed_same_run_and_predict_changes_nothing() -> None:
    a, b = _point(seed=3).learn(200), _point(seed=3).learn(200)
    for x, y in zip(a.buffer.arrays(), b.buffer.arrays(), strict=True):
        np.testing.assert_array_equal(x, y)
    assert a.explorer.map is not None
    before = {k: np.copy(v) for k, v in a.explorer.to_arrays().items()}
    obs = np.linspace(-1, 1, 9)[:, None]
    first = a.predict(obs)[0]
    np.testing.assert_array_equal(first, b.predict(obs)[0])
    np.testing.assert_array_equal(a.predict(obs)[0], first)
    for k, v in a.explorer.to_arrays().items():
        np.testing.assert_array_equal(v, before[k], err_msg=k)


def test_learn_leaves_the_plans_up_to_date_for_predict() -> None:
    agent = _point(seed=1).learn(150)
    m = agent.explorer.map
    assert m is not None and not m.changed
    Q = m.Q_exploit.copy()
    m.changed = True
    m.plan()  # planning again from the same data moves nothing
    np.testing.assert_allclose(m.Q_exploit, Q, atol=m.settings.tol / (1 - m.gamma))


def test_a_saved_agent_with_a_map_continues_identically(tmp_path: Path) -> None:
    agent = _point(seed=2).learn(120)
    assert agent.explorer.map is not None
    path = tmp_path / "agent.npz"
    agent.save(path)
    loaded = GPQAgent.load(path, env=PointToGoal())
    obs = np.linspace(-1, 1, 11)[:, None]
    np.testing.assert_array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])
    agent.learn(80)
    loaded.learn(80)
    for x, y in zip(agent.buffer.arrays(), loaded.buffer.arrays(), strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])


def test_a_file_from_before_the_map_keeps_exploring_without_one() -> None:
    agent = _point()
    agent.explorer.restore({})  # what a file without explorer/* arrays gives
    agent.learn(100)
    assert agent.explorer.decided and agent.explorer.map is None
