"""The vectorised Gymnasium twins against the real envs, step by step, bit for bit.

The twins follow Gymnasium 1.x's ``step`` code (checked with the versions in the lock file,
``requirements/``) under NumPy 2's promotion rules (NEP 50): a Python float times the
env's float32 scalar torque is float32 arithmetic. NumPy 1.x computed it in float64, so
there the bits differ (relative 1e-7) and the bit-for-bit tests are skipped.
"""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

from geoq.rollouts import collect_rollouts
from geoq.tasks.classic_control import (
    GymPendulumPolicy,
    MountainCarEnergyPolicy,
    gym_pendulum_observe,
    gym_pendulum_step,
    mountain_car_step,
    sample_gym_pendulum_starts,
    sample_mountain_car_starts,
)

NEP50 = pytest.mark.skipif(
    np.lib.NumpyVersion(np.__version__) < "2.0.0",
    reason="the twins follow NumPy 2's promotion of float32 scalars (NEP 50); NumPy "
    + np.__version__
    + " computes the env's float32 terms in float64",
)


@NEP50
@pytest.mark.parametrize("episode", range(12))
def test_mountain_car_step_equals_env_step_bit_for_bit(episode: int) -> None:
    rng = np.random.default_rng(episode)
    env = gymnasium.make("MountainCarContinuous-v0").unwrapped
    obs, _ = env.reset(seed=episode)
    env.state = np.asarray(obs, dtype=np.float32)  # the float32 state every later step has
    state = np.asarray(obs, dtype=np.float64)[None]
    policy = MountainCarEnergyPolicy(sigma=0.0)
    for t in range(400):
        # Clipped (|a| > 1) and unclipped forces, pumping most of the time, so the car
        # reaches the left wall, the speed limit and the goal in some episodes.
        push = policy.mean_action(state)[0, 0] if episode % 3 else 0.0
        action = np.array([push + rng.normal(0.0, 0.3 + 0.3 * (episode % 4))], np.float32)
        obs, reward, terminated, _, _ = env.step(action)
        state, r, done = mountain_car_step(state, action[None])
        np.testing.assert_array_equal(state[0], np.asarray(obs, dtype=np.float64), f"step {t}")
        assert r[0] == reward and bool(done[0]) == terminated, f"step {t}"
        if terminated:
            break


@NEP50
@pytest.mark.parametrize("episode", range(8))
def test_gym_pendulum_step_equals_env_step_bit_for_bit(episode: int) -> None:
    rng = np.random.default_rng(100 + episode)
    env = gymnasium.make("Pendulum-v1").unwrapped
    obs, _ = env.reset(seed=episode)
    state = np.array(env.state, dtype=np.float64)[None]
    np.testing.assert_array_equal(gym_pendulum_observe(state)[0], obs)
    for t in range(200):
        action = np.array([rng.normal(0.0, 2.5)], dtype=np.float32)  # often clipped to +-2
        obs, reward, terminated, _, _ = env.step(action)
        state, r, done = gym_pendulum_step(state, action[None])
        np.testing.assert_array_equal(state[0], env.state, f"step {t}")
        np.testing.assert_array_equal(gym_pendulum_observe(state)[0], obs, f"step {t}")
        assert r[0] == reward and not done[0] and not terminated, f"step {t}"


def test_start_samplers_draw_what_reset_draws() -> None:
    for seed in range(5):
        env = gymnasium.make("MountainCarContinuous-v0")
        obs, _ = env.reset(seed=seed)
        start = sample_mountain_car_starts(np.random.default_rng(seed), 1)[0]
        np.testing.assert_array_equal(start, np.asarray(obs, dtype=np.float64))
        env = gymnasium.make("Pendulum-v1")
        env.reset(seed=seed)
        start = sample_gym_pendulum_starts(np.random.default_rng(seed), 1)[0]
        np.testing.assert_array_equal(start, env.unwrapped.state)


def test_batches_equal_rows_and_scalar_actions_equal_vector_actions() -> None:
    rng = np.random.default_rng(0)
    states = np.column_stack([rng.uniform(-1.2, 0.6, 50), rng.uniform(-0.07, 0.07, 50)])
    actions = rng.normal(0.0, 1.0, (50, 1))
    batch = mountain_car_step(states, actions)
    scalar = mountain_car_step(states, actions[:, 0])
    for i in range(50):
        row = mountain_car_step(states[i], actions[i])
        for b, s, r in zip(batch, scalar, row, strict=True):
            assert np.array_equal(b[i], r) and np.array_equal(s[i], r)


def test_evaluation_policies_solve_their_tasks() -> None:
    rng = np.random.default_rng(0)
    car = collect_rollouts(
        20,
        999,
        MountainCarEnergyPolicy(),
        rng,
        gamma=0.99,
        start=sample_mountain_car_starts,
        step=mountain_car_step,
    )
    assert all(ro.terminated for ro in car)
    assert max(len(ro) for ro in car) < 200
    assert all(ro.actions.shape == (len(ro), 1) for ro in car)
    pend = collect_rollouts(
        10,
        200,
        GymPendulumPolicy(),
        rng,
        start=sample_gym_pendulum_starts,
        step=gym_pendulum_step,
    )
    upright = [np.cos(ro.states[-20:, 0]).min() for ro in pend]
    assert min(upright) > 0.95  # swung up and balanced from every start
    assert np.mean([ro.rewards.sum() for ro in pend]) > -300
