"""Visitation maps and greedy routes of 2-D tasks (geoq.experiments.control.visits)."""

from __future__ import annotations

from pathlib import Path

import gymnasium
import numpy as np
from matplotlib.figure import Figure
from tests.agents._tasks import PointToGoal

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent
from geoq.experiments.control.plotting import plot_visits
from geoq.experiments.control.visits import greedy_route, map_extent, visit_map


def test_counts_are_the_training_states_cell_by_cell() -> None:
    agent = GPQAgent("geoq/TwoRooms-v0", seed=0, max_bv=30).learn(120)
    env = gymnasium.make("geoq/TwoRooms-v0")
    vm = visit_map(agent, env, seed=3, bins=8)
    assert vm is not None and vm.extent == ((0.0, 1.0), (0.0, 1.0))
    S = agent.buffer.transitions().states
    brute = np.zeros((8, 8))
    for x, y in S:  # the cell of each state; the upper edge belongs to the last cell
        brute[min(int(x * 8), 7), min(int(y * 8), 7)] += 1
    np.testing.assert_array_equal(vm.counts, brute)
    assert vm.names == ("x", "y") and vm.route.shape[1] == 2


def test_greedy_route_is_the_greedy_episode() -> None:
    agent = GPQAgent(PointToGoal(), seed=0, max_bv=40, gamma=0.9).learn(300)
    route, success = greedy_route(agent, PointToGoal(), seed=7)
    env = PointToGoal()
    obs, _ = env.reset(seed=7)
    np.testing.assert_array_equal(route[0], obs)
    for t in range(1, len(route)):  # each step is the greedy action's outcome
        obs, _, terminated, truncated, info = env.step(agent.predict(obs)[0])
        np.testing.assert_array_equal(route[t], obs)
    assert terminated or truncated
    assert success == float(bool(info["is_success"]))
    assert predict_unchanged(agent)


def predict_unchanged(agent: GPQAgent) -> bool:
    """A route does not change the agent (greedy predictions are pure)."""
    obs = np.linspace(-1, 1, 5)[:, None]
    before = agent.predict(obs)[0]
    greedy_route(agent, PointToGoal(), seed=1)
    return bool(np.array_equal(agent.predict(obs)[0], before))


def test_extent_comes_from_the_data_where_a_bound_is_infinite() -> None:
    space = gymnasium.spaces.Box(np.array([-1.0, -np.inf]), np.array([1.0, np.inf]))
    states = np.array([[0.0, 2.0], [0.5, 4.0]])
    assert map_extent(space, states) == ((-1.0, 1.0), (1.9, 4.1))
    assert map_extent(space, np.array([[0.0, 3.0]])) == ((-1.0, 1.0), (2.5, 3.5))


def test_only_two_dimensional_observations_get_a_map() -> None:
    agent = GPQAgent("Pendulum-v1", seed=0, max_bv=20).learn(30)
    assert visit_map(agent, gymnasium.make("Pendulum-v1"), seed=0) is None


def test_plot_shows_the_visits_and_the_route() -> None:
    agent = GPQAgent("geoq/PendulumSwingUp-v0", seed=0, max_bv=30).learn(50)
    vm = visit_map(agent, gymnasium.make("geoq/PendulumSwingUp-v0"), seed=0)
    assert vm is not None
    fig = plot_visits(vm, "swing-up")
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert len(ax.images) == 1 and ax.images[0].get_array().shape == vm.counts.T.shape
    np.testing.assert_array_equal(ax.lines[0].get_xydata(), vm.route)
    assert "where the agent went" in ax.get_title()


def test_train_writes_visits_only_for_two_dimensional_tasks(tmp_path: Path) -> None:
    from geoq.experiments.control.training import train

    train("geoq/TwoRooms-v0", tmp_path / "rooms", timesteps=60, eval_every=0, max_bv=20)
    assert (tmp_path / "rooms" / "visits.png").stat().st_size > 5_000
    train("Pendulum-v1", tmp_path / "pendulum", timesteps=30, eval_every=0, max_bv=20)
    assert not (tmp_path / "pendulum" / "visits.png").exists()
    assert (tmp_path / "pendulum" / "agent.npz").is_file()
