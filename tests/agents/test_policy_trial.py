"""``planner="policy-net"``'s test on the task itself (:mod:`geoq.agents.policy_planning`):
weights a search put in place run :data:`TEST_EPISODES` episodes, and give way to the
weights before them if their returns are worse by more than two standard errors."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.agents.policy_planning import SEARCH_EVERY, TEST_EPISODES, FeedbackPlanning
from geoq.models import GPDynamicsModel, PolicyGradientSettings

LOW, HIGH = np.array([-1.0]), np.array([1.0])


def _planning() -> tuple[FeedbackPlanning, GPDynamicsModel, np.random.Generator]:
    """A policy on a model of a double integrator paid ``-x^2``, searched with no Adam
    step (the search keeps the weights it starts from)."""
    rng = np.random.default_rng(0)
    S, A = rng.uniform(-1, 1, (200, 2)), rng.uniform(-1, 1, (200, 1))
    change = np.column_stack([0.1 * S[:, 1], 0.1 * A[:, 0]])
    model = GPDynamicsModel(2, 1).fit(S, A, -(S[:, 0] ** 2), S + change, np.zeros(200), rng)
    planning = FeedbackPlanning(2, LOW, HIGH, horizon=10, net=True, real_test=True)
    planning.gradient_settings = PolicyGradientSettings(horizon=10, steps=0)
    planning.starts = rng.uniform(-0.5, 0.5, (8, 2))
    planning.search(model, 0, rng)
    assert planning.policy is not None and planning.kept is None  # the first is on no trial
    return planning, model, rng


def test_an_episode_run_by_the_policy_adds_its_return() -> None:
    planning, _, _ = _planning()
    rewards = np.array([1.0, 2.0, 3.0, -1.0, 0.5])
    planning.open_episode(1)
    planning.close_episode(rewards[:3])
    planning.open_episode(3)
    planning.close_episode(rewards)
    planning.close_episode(rewards)  # closed already: nothing more
    assert planning.returns == [5.0, -0.5]
    unsearched = FeedbackPlanning(2, LOW, HIGH, horizon=10, real_test=True)
    unsearched.open_episode(0)  # no policy runs it
    unsearched.close_episode(rewards)
    assert unsearched.returns == [] and unsearched.due(0)


def test_a_search_waits_for_the_current_weights_episodes() -> None:
    planning, _, _ = _planning()
    planning.returns = [1.0] * (TEST_EPISODES - 1)
    assert not planning.due(SEARCH_EVERY)
    planning.returns.append(1.0)
    assert planning.due(SEARCH_EVERY) and not planning.due(SEARCH_EVERY - 1)
    planning.real_test = False
    planning.returns = []
    assert planning.due(SEARCH_EVERY)


@pytest.mark.parametrize(
    ("trial", "kept"),
    [([-5.0, -5.5], False), ([-1.1, -0.95], True), ([-1.4, -1.5, -1.45, -1.5], False),
     ([-1.4, -0.6], True)],
)  # fmt: skip
def test_weights_worse_on_the_task_give_way_to_those_before(trial: list, kept: bool) -> None:
    """Oracle: Welch's difference of the means against two of its standard errors, by
    hand (before: -1.0, -1.2, -0.9)."""
    planning, model, rng = _planning()
    before = planning.gains.copy()
    planning.kept = (before, -3.0, [-1.0, -1.2, -0.9])
    tried = before + 0.1
    planning.gains, planning.returns = tried, list(trial)
    old, new = np.array([-1.0, -1.2, -0.9]), np.array(trial)
    se = np.sqrt(old.var(ddof=1) / 3 + new.var(ddof=1) / len(new))
    assert (new.mean() >= old.mean() - 2.0 * se) == kept
    planning.search(model, 200, rng)  # no Adam step: the search keeps what it starts from
    assert planning.kept is None
    np.testing.assert_array_equal(planning.gains, tried if kept else before)
    assert planning.returns == (trial if kept else [-1.0, -1.2, -0.9])


def test_weights_a_search_replaces_go_on_trial() -> None:
    planning, model, rng = _planning()  # the network's first weights: no force anywhere
    planning.gradient_settings = PolicyGradientSettings(horizon=30, steps=30, learning_rate=0.05)
    planning.returns = [-2.0, -2.5]
    before = planning.gains.copy()
    planning.search(model, 200, rng)
    assert not np.array_equal(planning.gains, before)  # the search moved them
    assert planning.kept is not None and planning.returns == []
    np.testing.assert_array_equal(planning.kept[0], before)
    assert planning.kept[2] == [-2.0, -2.5]
