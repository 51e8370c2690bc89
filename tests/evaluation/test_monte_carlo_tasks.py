"""Monte-Carlo Q^pi on a terminating task with vector actions, against brute force."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.envs import two_rooms_step
from geoq.evaluation.monte_carlo import mc_q_values, sample_evaluation_pairs
from geoq.policies import TwoRoomsWaypointPolicy

GAMMA = 0.95


def _steps_to_goal(state: list[float], first: list[float], policy: TwoRoomsWaypointPolicy) -> int:
    """Brute force, one state at a time: steps until the step that terminates (inclusive)."""
    s, a = np.array([state]), np.array([first])
    for n in range(1, 1000):
        s, _, done = two_rooms_step(s, a)
        if done[0]:
            return n
        a = policy.mean_action(s)
    raise AssertionError("the deterministic policy never reached the goal")


@pytest.mark.parametrize(
    ("state", "first"),
    [
        ([0.75, 0.5], [0.0, -1.0]),  # straight down to the goal
        ([0.45, 0.3], [1.0, 0.0]),  # into the wall (blocked), then round through the door
        ([0.55, 0.3], [-1.0, 0.0]),  # right of the wall, first move away from the goal
        ([0.2, 0.9], [0.0, 0.0]),  # far corner of the left room, first action "stay"
    ],
)
def test_deterministic_q_is_the_closed_form_of_the_path_length(
    state: list[float], first: list[float]
) -> None:
    policy = TwoRoomsWaypointPolicy(sigma=0.0)
    n = _steps_to_goal(state, first, policy)
    est = mc_q_values(
        np.array([state]),
        np.array([first]),
        policy,
        np.random.default_rng(0),
        n_rollouts=3,
        gamma=GAMMA,
        step=two_rooms_step,
    )
    # -1 per step up to and including the terminating one, nothing after it.
    assert est.mean[0] == pytest.approx(-(1 - GAMMA**n) / (1 - GAMMA), rel=1e-12)
    assert est.stderr[0] < 1e-12  # every roll-out the same


def test_the_wall_makes_q_jump_between_neighbours() -> None:
    policy = TwoRoomsWaypointPolicy(sigma=0.0)
    states = np.array([[0.49, 0.3], [0.51, 0.3]])  # 0.02 apart, on both sides of the wall
    actions = policy.mean_action(states)
    q = mc_q_values(
        states,
        actions,
        policy,
        np.random.default_rng(0),
        n_rollouts=2,
        gamma=GAMMA,
        step=two_rooms_step,
    ).mean
    assert q[1] > -4.0 and q[0] < -11.0


def test_noisy_policy_estimates_are_reproducible_and_bounded() -> None:
    policy = TwoRoomsWaypointPolicy()
    states, actions = sample_evaluation_pairs(
        30,
        policy,
        np.random.default_rng(1),
        n_rollouts=3,
        steps=200,
        start=lambda g, n: g.uniform(0.0, 0.45, size=(n, 2)),
        step=two_rooms_step,
    )
    assert actions.shape == (30, 2)
    runs = [
        mc_q_values(
            states,
            actions,
            policy,
            np.random.default_rng(2),
            n_rollouts=8,
            gamma=GAMMA,
            step=two_rooms_step,
        )
        for _ in range(2)
    ]
    np.testing.assert_array_equal(runs[0].mean, runs[1].mean)
    assert np.all(runs[0].mean <= -1.0) and np.all(runs[0].mean > -1 / (1 - GAMMA))
    chunked = mc_q_values(
        states,
        actions,
        policy,
        np.random.default_rng(2),
        n_rollouts=8,
        gamma=GAMMA,
        step=two_rooms_step,
        max_batch=40,
    )
    assert np.all(chunked.mean <= -1.0)


def test_too_few_visited_pairs_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="terminating roll-outs"):
        sample_evaluation_pairs(
            500,
            TwoRoomsWaypointPolicy(),
            np.random.default_rng(0),
            n_rollouts=3,
            steps=200,
            start=lambda g, n: np.tile([0.75, 0.35], (n, 1)),
            step=two_rooms_step,
        )
