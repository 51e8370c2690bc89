"""The Gymnasium shell: registration, env_checker, seeding, options and bad input."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import geoq  # noqa: F401  (registers the env)
from geoq.envs import PENDULUM_SWING_UP_ID, PENDULUM_SWING_UP_MAX_STEPS, pendulum_step
from geoq.envs.swing_up import PendulumSwingUpEnv

# As in Gymnasium's own tests/envs/test_envs.py: torque in N m is the natural unit.
CHECK_ENV_IGNORE_WARNINGS = [
    f"\x1b[33mWARN: {message}\x1b[0m"
    for message in [
        "For Box action spaces, we recommend using a symmetric and normalized space "
        "(range=[-1, 1] or [0, 1]). See "
        "https://stable-baselines3.readthedocs.io/en/master/guide/rl_tips.html "
        "for more information.",
    ]
]


def test_registered_on_import_with_time_limit() -> None:
    assert PENDULUM_SWING_UP_ID == "geoq/PendulumSwingUp-v0"
    spec = gym.spec(PENDULUM_SWING_UP_ID)
    assert spec.max_episode_steps == PENDULUM_SWING_UP_MAX_STEPS == 250
    env = gym.make(PENDULUM_SWING_UP_ID)
    assert isinstance(env.unwrapped, PendulumSwingUpEnv)
    env.reset(seed=0)
    for t in range(250):
        _, _, terminated, truncated, _ = env.step(np.array([0.0]))
        assert not terminated
        assert truncated == (t == 249)


def test_passes_env_checker() -> None:
    env = gym.make(PENDULUM_SWING_UP_ID)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    unexpected = [w.message for w in caught if str(w.message) not in CHECK_ENV_IGNORE_WARNINGS]
    assert unexpected == []


def test_spaces() -> None:
    env = PendulumSwingUpEnv()
    assert env.action_space.shape == (1,)
    np.testing.assert_array_equal(env.action_space.low, [-5.0])
    np.testing.assert_array_equal(env.observation_space.high, [np.pi, 8.0])
    assert env.observation_space.dtype == np.float64


def test_seeded_reset_is_deterministic_and_hangs_down() -> None:
    env = gym.make(PENDULUM_SWING_UP_ID)
    obs1, _ = env.reset(seed=42)
    obs2, _ = env.reset(seed=42)
    np.testing.assert_array_equal(obs1, obs2)
    assert abs(abs(obs1[0]) - np.pi) <= 0.05 and abs(obs1[1]) <= 0.05
    obs3, _ = env.reset(seed=43)
    assert not np.array_equal(obs1, obs3)


def test_step_is_the_pure_physics() -> None:
    env = gym.make(PENDULUM_SWING_UP_ID)
    obs, _ = env.reset(options={"state": [0.1, -2.0]})
    np.testing.assert_array_equal(obs, [0.1, -2.0])
    rng = np.random.default_rng(0)
    for _ in range(50):
        u = rng.uniform(-7, 7, size=1)
        expected, r_expected = pendulum_step(obs, u[0])
        obs, r, *_ = env.step(u)
        np.testing.assert_array_equal(obs, expected)
        assert r == r_expected
    obs, r, *_ = env.step(np.float64(1.0))  # a 0-d array is one torque too
    assert obs.shape == (2,)


def test_reset_state_pi_is_wrapped() -> None:
    env = PendulumSwingUpEnv()
    obs, _ = env.reset(options={"state": [np.pi, 0.0]})
    np.testing.assert_array_equal(obs, [-np.pi, 0.0])


@pytest.mark.parametrize(
    ("state", "match"),
    [
        ([4.0, 0.0], "out of bounds"),
        ([0.0, 8.5], "out of bounds"),
        ([0.0, np.nan], "not finite"),
        ([0.0, 1.0, 2.0], "shape"),
        ("up", "numeric"),
    ],
)
def test_reset_rejects_bad_state(state: object, match: str) -> None:
    env = gym.make(PENDULUM_SWING_UP_ID)
    with pytest.raises(ValueError, match=match):
        env.reset(options={"state": state})


def test_reset_rejects_unknown_option() -> None:
    with pytest.raises(ValueError, match="unknown reset option"):
        PendulumSwingUpEnv().reset(options={"x_init": 1.0})


@pytest.mark.parametrize(
    ("action", "match"),
    [
        (np.array([1.0, 2.0]), "shape"),
        (np.array([[1.0]]), "shape"),
        (np.array([np.nan]), "not finite"),
        (np.array([np.inf]), "not finite"),
    ],
)
def test_step_rejects_bad_action(action: np.ndarray, match: str) -> None:
    env = PendulumSwingUpEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


def test_step_before_reset_and_bad_constructor_args() -> None:
    with pytest.raises(RuntimeError, match="reset"):
        PendulumSwingUpEnv().step(np.array([0.0]))
    with pytest.raises(ValueError, match="render_mode"):
        PendulumSwingUpEnv(render_mode="human")
    with pytest.raises(ValueError, match="start_noise"):
        PendulumSwingUpEnv(start_noise=-1.0)


def _episode_success(policy: object, seed: int) -> tuple[bool, list[dict[str, object]]]:
    env = gym.make(PENDULUM_SWING_UP_ID)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    infos = []
    truncated = False
    while not truncated:
        action = np.atleast_1d(policy(obs[None, :], rng))  # type: ignore[operator]
        obs, _, _, truncated, info = env.step(action)
        infos.append(info)
    return bool(infos[-1]["is_success"]), infos


def test_is_success_reported_only_at_truncation_and_matches_a_brute_force_check() -> None:
    from geoq.policies import default_policy

    policy = default_policy()
    for seed in range(3):
        ok, infos = _episode_success(policy, seed)
        assert all("is_success" not in info for info in infos[:-1])
        assert ok  # the hand-made controller swings up and balances

    # Brute force on a recorded trajectory: success iff |theta| < 0.3 in the last 50 states.
    env = PendulumSwingUpEnv()  # no time limit: reports at the default horizon of 250
    env.reset(options={"state": [0.0, 0.0]})
    thetas, info = [], {}
    for t in range(250):
        torque = 0.0 if t < 195 else 5.0  # upright, then pushed over near the end
        obs, _, _, _, info = env.step(np.array([torque]))
        thetas.append(obs[0])
    expected = bool(np.all(np.abs(np.array(thetas[-50:])) < 0.3))
    assert info["is_success"] is expected
    assert expected is False  # the push topples it within the window


def test_a_pendulum_left_hanging_fails() -> None:
    ok, _ = _episode_success(lambda s, rng: np.zeros(1), seed=0)
    assert not ok


def test_start_noise_beyond_the_speed_limit_is_refused() -> None:
    with pytest.raises(ValueError, match="observation space"):
        PendulumSwingUpEnv(start_noise=9.0)
    env = PendulumSwingUpEnv(start_noise=8.0)
    for seed in range(20):
        obs, _ = env.reset(seed=seed)
        assert env.observation_space.contains(obs)


@pytest.mark.parametrize("action", [np.array([1.0 + 2.0j]), np.array(["1.0"])])
def test_step_refuses_non_real_actions(action: np.ndarray) -> None:
    env = PendulumSwingUpEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="real torque"):
        env.step(action)
