"""Roll-outs: record consistency, discounted returns vs brute force, determinism."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.signal import lfilter

import geoq  # noqa: F401
from geoq.envs import pendulum_step
from geoq.policies import GaussianPolicy, default_policy
from geoq.rollouts import (
    DEFAULT_GAMMA,
    Rollout,
    collect_rollouts,
    discounted_returns,
    initial_states,
    to_training_data,
)


def _brute_force_returns(rewards: np.ndarray, gamma: float) -> np.ndarray:
    H = len(rewards)
    return np.array([sum(gamma**i * rewards[t + i] for i in range(H - t)) for t in range(H)])


@settings(max_examples=100, deadline=None)
@given(
    rewards=arrays(np.float64, st.integers(1, 40), elements=st.floats(-10, 10)),
    gamma=st.floats(0.0, 1.0),
)
def test_discounted_returns_match_brute_force(rewards: np.ndarray, gamma: float) -> None:
    y = discounted_returns(rewards, gamma)
    np.testing.assert_allclose(y, _brute_force_returns(rewards, gamma), rtol=1e-10, atol=1e-9)


def test_discounted_returns_match_lfilter_along_last_axis() -> None:
    rewards = np.random.default_rng(0).normal(size=(3, 4, 250))
    y = discounted_returns(rewards, 0.95)
    ref = lfilter([1.0], [1.0, -0.95], rewards[..., ::-1], axis=-1)[..., ::-1]
    np.testing.assert_allclose(y, ref, rtol=1e-12, atol=1e-12)
    assert discounted_returns([1.0, 1.0, 1.0], 1.0).tolist() == [3.0, 2.0, 1.0]
    assert discounted_returns([1.0, 2.0], 0.0).tolist() == [1.0, 2.0]
    with pytest.raises(ValueError, match="gamma"):
        discounted_returns([1.0], 1.5)


def test_rollout_records_are_consistent() -> None:
    rollouts = collect_rollouts(5, 60, default_policy(), np.random.default_rng(0))
    assert len(rollouts) == 5
    for ro in rollouts:
        assert len(ro) == 60 and ro.gamma == DEFAULT_GAMMA == 0.95
        assert ro.states.shape == ro.next_states.shape == (60, 2)
        np.testing.assert_array_equal(ro.next_states[:-1], ro.states[1:])
        np.testing.assert_array_equal(ro.rewards, np.cos(ro.states[:, 0]))
        nxt, r = pendulum_step(ro.states, ro.actions)
        np.testing.assert_array_equal(nxt, ro.next_states)
        np.testing.assert_array_equal(r, ro.rewards)
        np.testing.assert_allclose(ro.returns, _brute_force_returns(ro.rewards, 0.95))
        assert np.all(np.abs(ro.actions) <= 5.0)
        assert ro.inputs.shape == (60, 3)
        with pytest.raises(ValueError):
            ro.states[0, 0] = 1.0  # read-only
    X, y = to_training_data(rollouts)
    assert X.shape == (300, 3) and y.shape == (300,)
    np.testing.assert_array_equal(X[60:120, :2], rollouts[1].states)
    np.testing.assert_array_equal(y[60:120], rollouts[1].returns)


def test_same_seed_same_rollouts_bit_for_bit() -> None:
    a = collect_rollouts(4, 100, default_policy(), np.random.default_rng(123))
    b = collect_rollouts(4, 100, default_policy(), np.random.default_rng(123))
    c = collect_rollouts(4, 100, default_policy(), np.random.default_rng(124))
    for ra, rb in zip(a, b, strict=True):
        for field in ("states", "actions", "rewards", "next_states", "returns"):
            np.testing.assert_array_equal(getattr(ra, field), getattr(rb, field))
    assert not np.array_equal(a[0].actions, c[0].actions)


def test_deterministic_rollout_equals_env_loop() -> None:
    policy = GaussianPolicy(sigma=0.0)
    (ro,) = collect_rollouts(1, 120, policy, np.random.default_rng(0), start=[-np.pi, 0.0])
    env = gym.make("geoq/PendulumSwingUp-v0")
    obs, _ = env.reset(options={"state": [-np.pi, 0.0]})
    for t in range(120):
        np.testing.assert_array_equal(obs, ro.states[t])
        obs, r, *_ = env.step(np.array([policy.mean_action(obs)]))
        assert r == ro.rewards[t]


def test_start_specs_and_custom_dynamics() -> None:
    rng = np.random.default_rng(0)
    np.testing.assert_array_equal(initial_states([0.1, 0.2], 3, rng), np.tile([0.1, 0.2], (3, 1)))
    starts = np.array([[0.0, 0.0], [1.0, 1.0]])
    np.testing.assert_array_equal(initial_states(starts, 2, rng), starts)
    sampled = initial_states(lambda g, n: g.uniform(size=(n, 2)), 4, rng)
    assert sampled.shape == (4, 2)
    with pytest.raises(ValueError, match="shape"):
        initial_states(np.zeros((3, 2)), 2, rng)
    with pytest.raises(ValueError, match="NaN"):
        initial_states([np.nan, 0.0], 2, rng)

    def drift(states: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return states + actions[:, None], -np.abs(states[:, 0])

    def unit_policy(states: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return np.ones(states.shape[0])

    (ro,) = collect_rollouts(1, 4, unit_policy, rng, gamma=0.5, start=[0.0], step=drift)
    np.testing.assert_array_equal(ro.states[:, 0], [0, 1, 2, 3])
    # rewards 0, -1, -2, -3: y3 = -3, y2 = -2 - 1.5, y1 = -1 - 1.75, y0 = 0 - 1.375
    np.testing.assert_allclose(ro.returns, [-1.375, -2.75, -3.5, -3.0])
    with pytest.raises(ValueError, match=">= 1"):
        collect_rollouts(0, 4, unit_policy, rng)
    with pytest.raises(ValueError, match="policy returned"):
        collect_rollouts(3, 4, lambda s, g: np.ones((3, 1, 1)), rng, start=[0.0], step=drift)
    with pytest.raises(ValueError, match="policy returned"):  # [n] is scalar actions, not d_a = n
        collect_rollouts(3, 4, lambda s, g: np.ones((2,)), rng, start=[0.0], step=drift)
    with pytest.raises(ValueError, match="no roll-outs"):
        to_training_data([])


def test_rollout_rejects_inconsistent_arrays() -> None:
    z = np.zeros
    with pytest.raises(ValueError, match="disagree"):
        Rollout(z((3, 2)), z(3), z(3), z((2, 2)), z(3), 0.9)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n": 0}, "n must be"),
        ({"n": 2.5}, "n must be"),
        ({"n": True}, "n must be"),
        ({"steps": "3"}, "steps must be"),
        ({"rng": 0}, "Generator"),
        ({"rng": np.random.RandomState(0)}, "Generator"),
        ({"gamma": 1.5}, "gamma"),
    ],
)
def test_bad_arguments_get_clear_errors(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {"n": 2, "steps": 3, "policy": default_policy(),
                               "rng": np.random.default_rng(0)}  # fmt: skip
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        collect_rollouts(**args)  # type: ignore[arg-type]


@pytest.mark.parametrize("bad", [np.nan, np.inf, 1j])
def test_a_policy_returning_non_finite_or_complex_actions_is_refused(bad: complex) -> None:
    def policy(states: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        out = np.zeros(len(states), dtype=type(bad))
        out[-1] = bad
        return out

    with pytest.raises(ValueError, match=r"non-finite|real numbers"):
        collect_rollouts(2, 4, policy, np.random.default_rng(0))


def test_recorded_torques_are_the_applied_ones() -> None:
    """The default physics clips at 5 N m: the record holds the clipped torque."""
    ro = collect_rollouts(1, 5, lambda s, rng: np.full(len(s), 50.0), np.random.default_rng(0))[0]
    np.testing.assert_array_equal(ro.actions, 5.0)
    same = collect_rollouts(1, 5, lambda s, rng: np.full(len(s), 5.0), np.random.default_rng(0))[0]
    np.testing.assert_array_equal(ro.next_states, same.next_states)
