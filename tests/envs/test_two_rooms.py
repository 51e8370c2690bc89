"""geoq/TwoRooms-v0: the pure step against an exact-arithmetic oracle, the Gymnasium
shell (env_checker, seeding, options, bad input, termination, success) and the
waypoint evaluation policy."""

from __future__ import annotations

import math
import warnings
from fractions import Fraction

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import geoq  # registers the envs
from geoq.agents import GPQAgent
from geoq.envs import (
    GOAL,
    TWO_ROOMS_ID,
    TWO_ROOMS_MAX_STEPS,
    TwoRoomsEnv,
    sample_two_rooms_starts,
    two_rooms_blocked,
    two_rooms_step,
)
from geoq.policies import TwoRoomsWaypointPolicy
from geoq.tasks import KNOWN_TASKS, task_info

# ----------------------------------------------------------------- the oracle


def _reference_step(
    x: float, y: float, dx: float, dy: float
) -> tuple[tuple[float, float], bool, bool, Fraction]:
    """One move written out with scalars; the wall test in exact rational arithmetic.

    Returns the next position, whether the wall blocked the move, whether the
    episode terminates, and the exact crossing height (-1 if no crossing).
    """
    dx, dy = min(max(dx, -1.0), 1.0), min(max(dy, -1.0), 1.0)
    qx, qy = min(max(x + 0.05 * dx, 0.0), 1.0), min(max(y + 0.05 * dy, 0.0), 1.0)
    wall = Fraction(0.5)
    px_, py_, qx_, qy_ = (Fraction(v) for v in (x, y, qx, qy))
    y_cross = Fraction(-1)
    blocked = False
    if (px_ < wall) != (qx_ < wall):  # start and end in different rooms (x = 0.5 is right)
        y_cross = py_ + (wall - px_) / (qx_ - px_) * (qy_ - py_)
        blocked = not (Fraction(0.8) <= y_cross <= Fraction(1.0))
    nx, ny = (x, y) if blocked else (qx, qy)
    d2 = (Fraction(nx) - Fraction(0.75)) ** 2 + (Fraction(ny) - Fraction(0.2)) ** 2
    return (nx, ny), blocked, d2 <= Fraction(0.1) ** 2, y_cross


_SPECIAL_XY = [0.0, 1.0, 0.5, 0.45, 0.55, 0.48, 0.52, 0.8, 0.9, 0.2, 0.75, 0.1]
_coord = st.one_of(
    st.floats(0.0, 1.0),
    st.floats(0.43, 0.57),  # near the wall
    st.sampled_from(_SPECIAL_XY),
    st.sampled_from([math.nextafter(0.5, 0.0), math.nextafter(0.5, 1.0)]),
)
_act = st.one_of(
    st.floats(-1.5, 1.5),
    st.sampled_from([-2.0, -1.0, -0.4, 0.0, 0.4, 1.0, 2.0]),
)


@settings(max_examples=1500, deadline=None)
@given(x=_coord, y=_coord, dx=_act, dy=_act)
def test_step_matches_the_exact_oracle(x: float, y: float, dx: float, dy: float) -> None:
    (nx, ny), blocked, terminated, y_cross = _reference_step(x, y, dx, dy)
    # Interpolated heights within rounding of a door edge may go either way;
    # endpoints on the line are exact and stay in (their height is not interpolated).
    on_line = x == 0.5 or min(max(x + 0.05 * min(max(dx, -1.0), 1.0), 0.0), 1.0) == 0.5
    assume(on_line or abs(y_cross - Fraction(0.8)) > Fraction(1, 10**9))
    d2 = (nx - 0.75) ** 2 + (ny - 0.2) ** 2
    assume(abs(d2 - 0.01) > 1e-12 or d2 == 0.01)
    nxt, rew, term = two_rooms_step(np.array([x, y]), np.array([dx, dy]))
    assert tuple(nxt.tolist()) == (nx, ny)
    assert bool(term) is terminated
    assert float(rew) == -1.0
    q = np.clip(np.array([x, y]) + 0.05 * np.clip([dx, dy], -1, 1), 0, 1)
    assert bool(two_rooms_blocked(np.array([x, y]), q)) is blocked


def test_batch_equals_row_by_row() -> None:
    rng = np.random.default_rng(0)
    n = 4000
    states = rng.uniform(0, 1, size=(n, 2))
    states[: n // 2, 0] = rng.uniform(0.45, 0.55, n // 2)  # half of them at the wall
    actions = rng.uniform(-1.5, 1.5, size=(n, 2))
    nxt, rew, term = two_rooms_step(states, actions)
    assert nxt.shape == (n, 2) and rew.shape == (n,) and term.shape == (n,)
    assert term.dtype == bool
    n_blocked = 0
    for i in range(n):
        (nx, ny), blocked, terminated, _ = _reference_step(*states[i], *actions[i])
        assert tuple(nxt[i].tolist()) == (nx, ny)
        assert bool(term[i]) is terminated
        n_blocked += blocked
    assert 200 < n_blocked < n // 2  # the wall is exercised, and not everywhere
    np.testing.assert_array_equal(rew, -1.0)
    assert np.all((nxt >= 0) & (nxt <= 1))


_BELOW_DOOR = math.nextafter(0.8, 0.0)


@pytest.mark.parametrize(
    ("start", "action", "expected", "why"),
    [
        ((0.48, 0.9), (1, 0), (0.53, 0.9), "through the door"),
        ((0.48, 0.5), (1, 0), (0.48, 0.5), "into the wall: blocked"),
        ((0.52, 0.5), (-1, 0), (0.52, 0.5), "into the wall from the right: blocked"),
        ((0.48, 0.8), (1, 0), (0.53, 0.8), "door's lower edge is open (<=)"),
        ((0.48, _BELOW_DOOR), (1, 0), (0.48, _BELOW_DOOR), "just below the door"),
        ((0.48, 1.0), (1, 1), (0.53, 1.0), "top corner of the door, y clipped"),
        ((0.48, 0.77), (1, 1), (0.48, 0.77), "crosses at 0.79 though it ends at 0.82"),
        ((0.48, 0.79), (1, 1), (0.53, 0.84), "crosses at 0.81"),
        ((0.52, 0.83), (-1, -1), (0.47, 0.78), "right to left, crosses at 0.81"),
        ((0.45, 0.3), (1, 0), (0.45, 0.3), "left room onto the line: crossing, blocked"),
        ((0.45, 0.9), (1, 0), (0.5, 0.9), "left room onto the line in the door"),
        ((0.5, 0.3), (-1, 0), (0.5, 0.3), "off the line into the left room: blocked"),
        ((0.5, 0.85), (-1, 0), (0.45, 0.85), "off the line into the left room via the door"),
        ((0.5, 0.3), (0, 1), (0.5, 0.35), "along the line: no crossing"),
        ((0.5, 0.3), (1, 0), (0.55, 0.3), "off the line into the right room"),
        ((0.55, 0.3), (-1, 0), (0.5, 0.3), "right room onto the line: no crossing"),
        ((0.48, 0.5), (5, 0), (0.48, 0.5), "action clipped, still blocked"),
        ((0.48, 0.9), (5, -7), (0.53, 0.85), "action clipped to [-1, 1]^2"),
        ((1.0, 1.0), (1, 1), (1.0, 1.0), "corner: clipped to the square"),
        ((0.0, 0.0), (-1, -1), (0.0, 0.0), "corner: clipped to the square"),
        ((0.0, 0.5), (-1, 1), (0.0, 0.55), "edge: x clipped, y moves"),
    ],
)
def test_wall_cases(
    start: tuple[float, float],
    action: tuple[float, float],
    expected: tuple[float, float],
    why: str,
) -> None:
    nxt, _, _ = two_rooms_step(np.array(start), np.array(action, dtype=float))
    np.testing.assert_allclose(nxt, expected, rtol=0, atol=1e-15, err_msg=why)
    ref, _, _, _ = _reference_step(*start, *map(float, action))
    assert tuple(nxt.tolist()) == ref


def test_goal_disc_is_closed() -> None:
    # (0.75, 0.1) is at distance exactly 0.1 in floating point.
    _, _, term = two_rooms_step(np.array([0.75, 0.05]), np.array([0.0, 1.0]))
    assert bool(term)
    _, _, term = two_rooms_step(np.array([0.75, math.nextafter(0.1, 0.0)]), np.zeros(2))
    assert not bool(term)
    _, _, term = two_rooms_step(np.array(GOAL), np.zeros(2))
    assert bool(term)


def test_step_rejects_bad_shapes() -> None:
    with pytest.raises(ValueError, match="states has shape"):
        two_rooms_step(np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match="actions has shape"):
        two_rooms_step(np.zeros(2), np.zeros((4, 1)))


def test_sample_starts() -> None:
    s = sample_two_rooms_starts(np.random.default_rng(0), 1000)
    assert s.shape == (1000, 2)
    assert np.all(np.abs(s - [0.25, 0.2]) <= 0.05)
    assert np.all(s[:, 0] < 0.5)
    with pytest.raises(ValueError, match="left room"):
        sample_two_rooms_starts(np.random.default_rng(0), 1, noise=0.3)
    with pytest.raises(ValueError, match="n must be"):
        sample_two_rooms_starts(np.random.default_rng(0), -1)


# ------------------------------------------------------------------ the shell


def test_registered_with_time_limit_and_known_task() -> None:
    assert TWO_ROOMS_ID == "geoq/TwoRooms-v0"
    assert gym.spec(TWO_ROOMS_ID).max_episode_steps == TWO_ROOMS_MAX_STEPS == 200
    env = gym.make(TWO_ROOMS_ID)
    assert isinstance(env.unwrapped, TwoRoomsEnv)
    info = task_info(env)
    assert info == KNOWN_TASKS[TWO_ROOMS_ID]
    assert info.periods == (0.0, 0.0) and info.names == ("x", "y")
    geoq.envs.register_envs()  # idempotent
    assert gym.spec(TWO_ROOMS_ID).max_episode_steps == 200


def test_passes_env_checker() -> None:
    env = gym.make(TWO_ROOMS_ID)
    for target in (env.unwrapped, env):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(target)
        unexpected = [
            w.message for w in caught if "different from the unwrapped" not in str(w.message)
        ]
        assert unexpected == []


def test_spaces() -> None:
    env = TwoRoomsEnv()
    np.testing.assert_array_equal(env.action_space.low, [-1.0, -1.0])
    np.testing.assert_array_equal(env.action_space.high, [1.0, 1.0])
    np.testing.assert_array_equal(env.observation_space.low, [0.0, 0.0])
    np.testing.assert_array_equal(env.observation_space.high, [1.0, 1.0])
    assert env.observation_space.dtype == np.float64


def test_seeded_reset_is_reproducible_and_in_the_left_room() -> None:
    env = gym.make(TWO_ROOMS_ID)
    obs1, _ = env.reset(seed=42)
    obs2, _ = env.reset(seed=42)
    np.testing.assert_array_equal(obs1, obs2)
    obs3, _ = env.reset(seed=43)
    assert not np.array_equal(obs1, obs3)
    for seed in range(50):
        obs, _ = env.reset(seed=seed)
        assert obs[0] < 0.5 and np.all(np.abs(obs - [0.25, 0.2]) <= 0.05)
        assert env.observation_space.contains(obs)


def test_env_is_the_pure_step() -> None:
    env = gym.make(TWO_ROOMS_ID)
    rng = np.random.default_rng(0)
    for start in ([0.45, 0.5], [0.5, 0.3], [0.5, 0.9], [0.9, 0.95]):
        obs, _ = env.reset(options={"state": start})
        np.testing.assert_array_equal(obs, start)
        for _ in range(60):
            a = rng.uniform(-1.3, 1.3, size=2)
            a[0] = a[0] * 0.3 + (0.7 if obs[0] < 0.5 else -0.7)  # press on the wall
            expected, r_expected, term_expected = two_rooms_step(obs, a)
            obs, r, terminated, truncated, _ = env.step(a)
            np.testing.assert_array_equal(obs, expected)
            assert r == float(r_expected) == -1.0
            assert terminated is bool(term_expected) and truncated is False
            if terminated:
                break


def test_goal_terminates_with_success() -> None:
    env = gym.make(TWO_ROOMS_ID)
    env.reset(options={"state": [0.75, 0.0]})
    obs, r, terminated, truncated, info = env.step(np.array([0.0, 1.0]))
    np.testing.assert_array_equal(obs, [0.75, 0.05])
    assert (terminated, truncated, info) == (False, False, {})
    obs, r, terminated, truncated, info = env.step(np.array([0.0, 1.0]))
    np.testing.assert_array_equal(obs, [0.75, 0.1])  # distance exactly 0.1: inside
    assert r == -1.0 and terminated is True and truncated is False
    assert info == {"is_success": True}


def test_truncation_at_200_without_success() -> None:
    env = gym.make(TWO_ROOMS_ID)
    env.reset(seed=0)
    infos = []
    for t in range(200):
        _, r, terminated, truncated, info = env.step(np.array([-1.0, 0.0]))  # away from the door
        infos.append(info)
        assert r == -1.0 and not terminated
        assert truncated == (t == 199)
    assert all(info == {} for info in infos[:-1])
    assert infos[-1] == {"is_success": False}


def test_unwrapped_env_reports_at_the_default_horizon() -> None:
    env = TwoRoomsEnv()
    env.reset(seed=0)
    for _ in range(199):
        assert env.step(np.zeros(2))[4] == {}
    assert env.step(np.zeros(2))[4] == {"is_success": False}


@pytest.mark.parametrize(
    ("state", "match"),
    [
        ([1.2, 0.5], "unit square"),
        ([0.5, -0.01], "unit square"),
        ([0.5, np.nan], "not finite"),
        ([np.inf, 0.5], "not finite"),
        ([0.1, 0.2, 0.3], "shape"),
        ([[0.1, 0.2]], "shape"),
        ("left", "numeric"),
    ],
)
def test_reset_rejects_bad_state(state: object, match: str) -> None:
    env = gym.make(TWO_ROOMS_ID)
    with pytest.raises(ValueError, match=match):
        env.reset(options={"state": state})


@pytest.mark.parametrize("state", [[0.0, 0.0], [1.0, 1.0], [0.5, 0.3], [0.8, 0.15]])
def test_reset_anywhere_in_the_square(state: list[float]) -> None:
    obs, _ = gym.make(TWO_ROOMS_ID).reset(options={"state": state})
    np.testing.assert_array_equal(obs, state)


def test_reset_rejects_unknown_option() -> None:
    with pytest.raises(ValueError, match="unknown reset option"):
        TwoRoomsEnv().reset(options={"start": [0.1, 0.1]})


@pytest.mark.parametrize(
    ("action", "match"),
    [
        (np.array([1.0]), "shape"),
        (np.array(1.0), "shape"),
        (np.array([[1.0, 0.0]]), "shape"),
        (np.array([np.nan, 0.0]), "not finite"),
        (np.array([0.0, -np.inf]), "not finite"),
        (np.array([1.0 + 1.0j, 0.0]), "real move"),
        (np.array(["1", "0"]), "real move"),
    ],
)
def test_step_rejects_bad_action(action: np.ndarray, match: str) -> None:
    env = TwoRoomsEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


def test_step_before_reset_and_bad_constructor_args() -> None:
    with pytest.raises(RuntimeError, match="reset"):
        TwoRoomsEnv().step(np.zeros(2))
    with pytest.raises(ValueError, match="render_mode"):
        TwoRoomsEnv(render_mode="human")
    with pytest.raises(ValueError, match="start_noise"):
        TwoRoomsEnv(start_noise=0.25)


# ------------------------------------------------------------- the policy


def _episode(policy: TwoRoomsWaypointPolicy, seed: int) -> tuple[bool, int]:
    env = gym.make(TWO_ROOMS_ID)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for t in range(1, 201):
        obs, _, terminated, truncated, info = env.step(policy(obs[None, :], rng)[0])
        if terminated or truncated:
            return bool(info["is_success"]), t
    raise AssertionError("the time limit did not end the episode")


def test_noiseless_policy_reaches_the_goal_quickly() -> None:
    policy = TwoRoomsWaypointPolicy(sigma=0.0)
    for seed in range(10):
        success, steps = _episode(policy, seed)
        assert success and steps < 60, (seed, steps)


def test_noisy_policy_reaches_the_goal_in_at_least_95_percent() -> None:
    results = [_episode(TwoRoomsWaypointPolicy(), seed) for seed in range(200)]
    assert np.mean([ok for ok, _ in results]) >= 0.95


def test_policy_heads_for_the_door_then_the_goal() -> None:
    policy = TwoRoomsWaypointPolicy(sigma=0.0)
    states = np.array([[0.25, 0.9], [0.5, 0.5], [0.75, 0.9], [0.75, 0.2], [0.5, 0.9]])
    mean = policy.mean_action(states)  # [5, 2]; (0.5, y) is in the right room: to the goal
    np.testing.assert_allclose(mean[0], [1.0, 0.0], atol=1e-15)  # left room: to (0.5, 0.9)
    np.testing.assert_allclose(mean[1], np.array([0.25, -0.3]) / math.hypot(0.25, 0.3))
    np.testing.assert_allclose(mean[2], [0.0, -1.0], atol=1e-15)
    np.testing.assert_array_equal(mean[3], [0.0, 0.0])  # at the goal: stay
    np.testing.assert_allclose(np.linalg.norm(mean[[0, 1, 2, 4]], axis=1), 1.0, atol=1e-15)
    np.testing.assert_array_equal(policy(states, np.random.default_rng(0)), mean)


def test_policy_sampling_is_seeded_batched_and_in_the_box() -> None:
    policy = TwoRoomsWaypointPolicy(sigma=0.8)
    states = np.random.default_rng(1).uniform(0, 1, size=(500, 2))
    a1 = policy(states, np.random.default_rng(7))
    a2 = policy(states, np.random.default_rng(7))
    assert a1.shape == (500, 2)
    np.testing.assert_array_equal(a1, a2)
    assert np.all(np.abs(a1) <= 1.0)
    expected = np.clip(
        policy.mean_action(states) + 0.8 * np.random.default_rng(7).standard_normal((500, 2)),
        -1,
        1,
    )
    np.testing.assert_array_equal(a1, expected)
    rng = np.random.default_rng(3)
    TwoRoomsWaypointPolicy(sigma=0.0)(states, rng)
    assert rng.bit_generator.state == np.random.default_rng(3).bit_generator.state
    with pytest.raises(ValueError, match="sigma"):
        TwoRoomsWaypointPolicy(sigma=-1.0)
    with pytest.raises(ValueError, match="states has shape"):
        policy.mean_action(np.zeros(3))


# ------------------------------------------------------------- the agent


def test_gpq_agent_runs_on_two_rooms() -> None:
    agent = GPQAgent(gym.make(TWO_ROOMS_ID), max_bv=50, seed=0).learn(300)
    assert agent.num_timesteps == 300
    assert len(agent.episodes) >= 1
    assert all(e.success in (0.0, 1.0) for e in agent.episodes)
    action, _ = agent.predict(np.array([0.25, 0.2]), deterministic=True)
    assert action.shape == (2,) and np.all(np.abs(action) <= 1.0)
