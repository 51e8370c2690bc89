"""Roll-outs of terminating tasks with vector actions."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.envs import sample_two_rooms_starts, two_rooms_step
from geoq.learners import GPQFunction, QGPConfig
from geoq.learners.scaling import InputScaling
from geoq.policies import TwoRoomsWaypointPolicy
from geoq.rollouts import collect_rollouts, discounted_returns, to_training_data


def _ends_at_row_index(states: np.ndarray, actions: np.ndarray):  # type: ignore[no-untyped-def]
    """Row i terminates at its step i + 1 (the counter is state[:, 1]); reward 1 + counter."""
    nxt = states.copy()
    nxt[:, 1] += 1.0
    return nxt, 1.0 + states[:, 1], nxt[:, 1] >= states[:, 0] + 1.0


def test_terminated_rollouts_are_cut_and_their_returns_exact() -> None:
    calls: list[int] = []

    def policy(states: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        calls.append(states.shape[0])
        return rng.normal(size=(states.shape[0], 2))

    start = np.column_stack([np.arange(4.0), np.zeros(4)])  # row i ends after i + 1 steps
    rollouts = collect_rollouts(
        4, 10, policy, np.random.default_rng(0), gamma=0.5, start=start, step=_ends_at_row_index
    )
    assert [len(ro) for ro in rollouts] == [1, 2, 3, 4]
    assert all(ro.terminated for ro in rollouts)
    assert calls == [4, 4, 4, 4]  # every row each step; stops when all have ended
    for ro in rollouts:
        np.testing.assert_array_equal(ro.rewards, 1.0 + np.arange(len(ro)))
        np.testing.assert_array_equal(ro.returns, discounted_returns(ro.rewards, 0.5))
        assert ro.actions.shape == (len(ro), 2)
    X, y = to_training_data(rollouts)
    assert X.shape == (10, 4) and y.shape == (10,)


def test_the_generator_is_consumed_as_if_nothing_terminated() -> None:
    policy = TwoRoomsWaypointPolicy()
    a = collect_rollouts(
        5, 200, policy, np.random.default_rng(3), start=sample_two_rooms_starts, step=two_rooms_step
    )
    b = collect_rollouts(
        5, 200, policy, np.random.default_rng(3), start=sample_two_rooms_starts, step=two_rooms_step
    )
    for ra, rb in zip(a, b, strict=True):
        np.testing.assert_array_equal(ra.states, rb.states)
        assert ra.terminated and len(ra) < 60
        # The last step enters the goal disc, no earlier one does.
        end = np.hypot(*(ra.next_states[-1] - [0.75, 0.2]))
        assert end <= 0.1
        assert np.all(np.hypot(*(ra.next_states[:-1] - [0.75, 0.2]).T) > 0.1)


def test_unterminated_rollouts_keep_their_length_and_flag() -> None:
    never = lambda s, a: (s, np.zeros(len(s)), np.zeros(len(s), bool))  # noqa: E731
    (ro,) = collect_rollouts(
        1, 7, lambda s, g: np.zeros((1, 2)), np.random.default_rng(0), start=[0.1, 0.1], step=never
    )
    assert len(ro) == 7 and not ro.terminated


@pytest.mark.parametrize("bad", ["wrong", "shape"])
def test_bad_step_results_are_value_errors(bad: str) -> None:
    def step(s: np.ndarray, a: np.ndarray):  # type: ignore[no-untyped-def]
        if bad == "wrong":
            return (s,)
        return s, np.zeros(len(s)), np.zeros(len(s) + 1, bool)

    with pytest.raises(ValueError, match="step function"):
        collect_rollouts(
            2,
            3,
            lambda s, g: np.zeros((2, 2)),
            np.random.default_rng(0),
            start=[0.1, 0.1],
            step=step,
        )


def test_gp_learner_fits_vector_action_rollouts() -> None:
    rollouts = collect_rollouts(
        3,
        200,
        TwoRoomsWaypointPolicy(),
        np.random.default_rng(0),
        start=sample_two_rooms_starts,
        step=two_rooms_step,
    )
    scaling = InputScaling((0.5, 0.5, 1.0, 1.0), (0.0,) * 4, ("x", "y", "a0", "a1"))
    q = GPQFunction(QGPConfig(kernel="nearest", max_bv=20, scaling=scaling)).fit(rollouts)
    mean = q.predict(rollouts[0].states, rollouts[0].actions)
    assert mean.shape == (len(rollouts[0]),) and np.all(np.isfinite(mean))
