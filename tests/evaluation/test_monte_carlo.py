"""Monte-Carlo Q^pi: closed form on a chain MDP, a deterministic roll-out, determinism."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import geoq  # noqa: F401
from geoq.envs.chain import ChainMDP
from geoq.evaluation import mc_horizon, mc_q_values, sample_evaluation_pairs
from geoq.policies import GaussianPolicy, default_policy
from geoq.rollouts import collect_rollouts


@pytest.mark.parametrize("gamma", [0.0, 0.5, 0.9, 0.95, 0.99])
def test_horizon_is_the_first_power_below_the_tolerance(gamma: float) -> None:
    H = mc_horizon(gamma)
    assert gamma**H < 1e-4
    assert H == 1 or gamma ** (H - 1) >= 1e-4
    assert mc_horizon(0.95) == 180


def test_chain_mdp_closed_form() -> None:
    chain = ChainMDP()
    gamma = 0.9
    q_true = chain.q_values(gamma)  # [5, 2]
    states = np.repeat(np.arange(5.0), 2)[:, None]
    actions = np.tile([-1.0, 1.0], 5)
    est = mc_q_values(
        states, actions, chain.policy, np.random.default_rng(0), 4000, gamma, step=chain.step
    )
    assert est.horizon == mc_horizon(0.9)
    truncation = gamma**est.horizon * 1.0 / (1 - gamma)  # |r| <= 1
    z = np.abs(est.mean - q_true.ravel()) / (est.stderr + truncation)
    assert z.max() < 4.5
    assert np.all(est.stderr > 0) and est.stderr.max() < 0.05


def test_deterministic_policy_equals_a_direct_env_rollout() -> None:
    policy = GaussianPolicy(sigma=0.0)
    states = np.array([[-np.pi, 0.0], [0.3, -1.0], [2.0, 5.0]])
    actions = np.array([5.0, -2.0, 0.7])
    est = mc_q_values(states, actions, policy, np.random.default_rng(0), n_rollouts=3)
    np.testing.assert_array_equal(est.stderr, 0.0)
    env = gym.make("geoq/PendulumSwingUp-v0")
    for i in range(3):
        obs, _ = env.reset(options={"state": states[i]})
        total, discount, a = 0.0, 1.0, actions[i]
        for _ in range(est.horizon):
            obs, r, *_ = env.step(np.array([a]))
            total += discount * r
            discount *= 0.95
            a = policy.mean_action(obs)
        assert est.mean[i] == pytest.approx(total, abs=1e-10)


def test_first_action_matters_and_is_clipped() -> None:
    states = np.array([[0.3, 0.0]] * 3)
    est = mc_q_values(
        states, np.array([5.0, 50.0, -5.0]), GaussianPolicy(sigma=0.0), np.random.default_rng(0), 2
    )
    assert est.mean[0] == est.mean[1]  # the dynamics clip the torque
    assert est.mean[0] != est.mean[2]


def test_same_seed_same_estimates_bit_for_bit() -> None:
    policy = default_policy()
    states = np.array([[0.0, 0.5], [-3.0, 1.0]])
    actions = np.array([0.0, 2.0])
    a = mc_q_values(states, actions, policy, np.random.default_rng(5), 20)
    b = mc_q_values(states, actions, policy, np.random.default_rng(5), 20)
    c = mc_q_values(states, actions, policy, np.random.default_rng(6), 20)
    np.testing.assert_array_equal(a.mean, b.mean)
    np.testing.assert_array_equal(a.stderr, b.stderr)
    assert not np.array_equal(a.mean, c.mean)


def test_chunked_batches_are_reproducible_and_agree() -> None:
    policy = default_policy()
    states, actions = sample_evaluation_pairs(40, policy, np.random.default_rng(0), 2, 100)
    whole = mc_q_values(states, actions, policy, np.random.default_rng(1), 50)
    chunked = mc_q_values(states, actions, policy, np.random.default_rng(1), 50, max_batch=700)
    again = mc_q_values(states, actions, policy, np.random.default_rng(1), 50, max_batch=700)
    np.testing.assert_array_equal(chunked.mean, again.mean)
    z = (whole.mean - chunked.mean) / np.sqrt(whole.stderr**2 + chunked.stderr**2 + 1e-12)
    assert np.abs(z).max() < 4.5
    deterministic = GaussianPolicy(sigma=0.0)
    a = mc_q_values(states, actions, deterministic, np.random.default_rng(1), 2)
    b = mc_q_values(states, actions, deterministic, np.random.default_rng(1), 2, max_batch=20)
    np.testing.assert_array_equal(a.mean, b.mean)


def test_standard_error_shrinks_like_one_over_sqrt_n() -> None:
    chain = ChainMDP()
    states, actions = np.array([[1.0]]), np.array([1.0])
    rng = np.random.default_rng(0)
    small = mc_q_values(states, actions, chain.policy, rng, 400, 0.9, step=chain.step)
    large = mc_q_values(states, actions, chain.policy, rng, 6400, 0.9, step=chain.step)
    assert large.stderr[0] == pytest.approx(small.stderr[0] / 4, rel=0.25)


def test_bad_inputs() -> None:
    policy = default_policy()
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="expected"):
        mc_q_values(np.zeros(2), np.zeros(1), policy, rng)
    with pytest.raises(ValueError, match="entries"):
        mc_q_values(np.zeros((2, 2)), np.zeros(3), policy, rng)
    with pytest.raises(ValueError, match="non-finite"):
        mc_q_values(np.zeros((1, 2)), np.array([np.nan]), policy, rng)
    with pytest.raises(ValueError, match="n_rollouts"):
        mc_q_values(np.zeros((1, 2)), np.zeros(1), policy, rng, n_rollouts=1)
    with pytest.raises(ValueError, match="gamma"):
        mc_horizon(1.0)
    with pytest.raises(ValueError, match="empty"):
        mc_q_values(np.zeros((0, 2)), np.zeros(0), policy, rng)


def test_evaluation_pairs_come_from_held_out_rollouts() -> None:
    policy = default_policy()
    states, actions = sample_evaluation_pairs(300, policy, np.random.default_rng(9), 4, 250)
    assert states.shape == (300, 2) and actions.shape == (300,)
    # The same generator, replayed, gives the roll-outs the pairs were drawn from.
    pool = collect_rollouts(4, 250, policy, np.random.default_rng(9))
    pool_pairs = {tuple(x) for ro in pool for x in ro.inputs}
    assert all((s[0], s[1], a) in pool_pairs for s, a in zip(states, actions, strict=True))
    assert len({tuple(s) for s in states}) == 300  # without replacement
    again = sample_evaluation_pairs(300, policy, np.random.default_rng(9), 4, 250)
    np.testing.assert_array_equal(again[0], states)
    with pytest.raises(ValueError, match="n_pairs"):
        sample_evaluation_pairs(2000, policy, np.random.default_rng(0), 4, 250)
