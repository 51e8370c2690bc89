"""Tabular TD: grid indexing, the chain MDP's closed form, and the paper's pendulum table."""

from __future__ import annotations

import math

import numpy as np
import pytest

from geoq.baselines import StateActionGrid, TabularQ, sarsa_evaluate, td_baseline
from geoq.envs import ChainMDP
from geoq.evaluation import mc_q_values, mse, sample_evaluation_pairs
from geoq.policies import default_policy

CHAIN_GRID = StateActionGrid((-0.5,), (4.5,), (5,), -2.0, 2.0, 2)


def test_pendulum_grid_is_the_papers() -> None:
    g = StateActionGrid.pendulum()
    assert g.n_cells == 3600 and g.n_actions == 80 and g.state_bins == (60, 60)
    assert g.state_low == (-np.pi, -8.0) and g.state_high == (np.pi, 8.0)
    assert (g.action_low, g.action_high) == (-5.0, 5.0)
    assert g.state_centres().shape == (3600, 2) and g.action_centres().shape == (80,)


def test_indices_match_a_brute_force_search() -> None:
    g = StateActionGrid.pendulum()
    rng = np.random.default_rng(0)
    states = np.column_stack([rng.uniform(-4, 4, 500), rng.uniform(-9, 9, 500)])
    actions = rng.uniform(-6, 6, 500)
    idx, aidx = g.state_index(states), g.action_index(actions)
    for k in range(500):
        ti = min(max(math.floor((states[k, 0] + np.pi) / (2 * np.pi / 60)), 0), 59)
        wi = min(max(math.floor((states[k, 1] + 8.0) / (16.0 / 60)), 0), 59)
        assert idx[k] == ti * 60 + wi
        assert aidx[k] == min(max(math.floor((actions[k] + 5.0) / 0.125), 0), 79)
    # Every cell centre maps to its own cell; bounds land in the edge cells.
    np.testing.assert_array_equal(g.state_index(g.state_centres()), np.arange(3600))
    np.testing.assert_array_equal(g.action_index(g.action_centres()), np.arange(80))
    assert g.action_index(np.array([-5.0, 5.0])).tolist() == [0, 79]
    assert g.state_index(np.array([[np.pi, 8.0]])).tolist() == [3599]


@pytest.mark.parametrize("method", ["sarsa", "td0"])
def test_chain_mdp_closed_form(method: str) -> None:
    chain = ChainMDP()
    q_true = chain.q_values(0.9)  # [5, 2]
    td = td_baseline(
        chain.policy,
        np.random.default_rng(0),
        grid=CHAIN_GRID,
        n_episodes=2000,
        steps=30,
        gamma=0.9,
        method=method,  # type: ignore[arg-type]
        step_size=0.02,
        start=chain.start,
        step=chain.step,
    )
    assert td.method == method
    np.testing.assert_allclose(td.table, q_true, atol=0.25)
    assert td.visits.sum() == 2000 * 30
    states = np.repeat(np.arange(5.0), 2)[:, None]
    actions = np.tile([-1.0, 1.0], 5)
    np.testing.assert_array_equal(td.q(states, actions), td.table.ravel())


def test_first_visit_overwrites_and_constant_step_follows() -> None:
    # One state, one action bin, rewards 1, 0, 0: alpha = 1, then 0.5, then 0.5; gamma = 0.
    grid = StateActionGrid((0.0,), (1.0,), (1,), -1.0, 1.0, 1)
    states = np.full((1, 4, 1), 0.5)
    td = sarsa_evaluate(states, np.zeros((1, 4)), [[1.0, 0.0, 0.0]], grid, 0.0, "sarsa", 0.5)
    assert td.table[0, 0] == pytest.approx(0.25) and td.visits[0, 0] == 3
    td = sarsa_evaluate(states, np.zeros((1, 4)), [[1.0, 0.0, 0.0]], grid, 0.0, "td0", 0.5)
    assert td.table[0, 0] == pytest.approx(1.0 / 3.0)  # read-out: mean of r + 0 * V


def test_pendulum_baseline_runs_the_papers_budget_and_is_deterministic() -> None:
    policy = default_policy()
    a = td_baseline(policy, np.random.default_rng(0))
    b = td_baseline(policy, np.random.default_rng(0))
    np.testing.assert_array_equal(a.table, b.table)
    np.testing.assert_array_equal(a.visits, b.visits)
    assert isinstance(a, TabularQ) and a.method == "td0"
    assert a.visits.sum() == 800 * 150  # 120,000 updates
    assert a.state_visits.shape == (60, 60) and a.state_visits.sum() == 120_000
    # The table covers the swing-up and the top, not the whole box.
    assert 0.1 < (a.state_visits > 0).mean() < 0.6
    assert a.state_visits[30, 30] > 0 and a.state_visits[0, 30] > 0  # top and bottom
    c = td_baseline(policy, np.random.default_rng(1))
    assert not np.array_equal(a.table, c.table)


def test_pendulum_tables_against_monte_carlo() -> None:
    policy = default_policy()
    states, actions = sample_evaluation_pairs(200, policy, np.random.default_rng(1))
    truth = mc_q_values(states, actions, policy, np.random.default_rng(2), 50)
    td0 = td_baseline(policy, np.random.default_rng(3), method="td0")
    sarsa = td_baseline(policy, np.random.default_rng(3), method="sarsa")
    spread = float(np.var(truth.mean))
    assert spread > 30  # the pairs span swing-up and balance
    assert mse(td0.q(states, actions), truth.mean) < 0.05 * spread
    assert mse(sarsa.q(states, actions), truth.mean) < 0.6 * spread
    np.testing.assert_array_equal(
        sarsa.n_visits(states, actions) > 0, sarsa.q(states, actions) != 0
    )


def test_bad_inputs() -> None:
    g = StateActionGrid.pendulum()
    with pytest.raises(ValueError, match="expected"):
        sarsa_evaluate(np.zeros((2, 5, 2)), np.zeros((2, 5)), np.zeros((2, 5)), g)
    with pytest.raises(ValueError, match="method"):
        sarsa_evaluate(np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 1)), g, method="q")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="step_size"):
        sarsa_evaluate(np.zeros((1, 2, 2)), np.zeros((1, 2)), np.zeros((1, 1)), g, step_size=0.0)
    with pytest.raises(ValueError, match="finite"):
        sarsa_evaluate(np.full((1, 2, 2), np.nan), np.zeros((1, 2)), np.zeros((1, 1)), g)
    with pytest.raises(ValueError, match="state bounds"):
        StateActionGrid((0.0,), (0.0,), (3,), -1.0, 1.0, 2)
    with pytest.raises(ValueError, match="expected"):
        TabularQ(g, np.zeros((3600, 80)), np.zeros((3600, 80), np.int64), 0.95).q(
            np.zeros((3, 3)), np.zeros(3)
        )
