"""The pure pendulum physics against the formulas of its docstring, by a brute-force scalar loop."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoq.envs import (
    HANGING_DOWN,
    PendulumParams,
    pendulum_energy,
    pendulum_step,
    sample_hanging_states,
    wrap_angle,
)


def _reference_step(theta: float, omega: float, u: float) -> tuple[float, float, float]:
    """The physics written out with the math module, one pendulum at a time."""
    m, l, g, mu, dt = 1.0, 1.0, 9.81, 0.01, 0.05
    u = min(max(u, -5.0), 5.0)
    reward = math.cos(theta)
    omega_new = omega + dt * (g / l * math.sin(theta) - mu * omega / (m * l**2) + u / (m * l**2))
    omega_new = min(max(omega_new, -8.0), 8.0)
    theta_new = theta + dt * omega_new
    while theta_new >= math.pi:
        theta_new -= 2 * math.pi
    while theta_new < -math.pi:
        theta_new += 2 * math.pi
    return theta_new, omega_new, reward


def test_step_equals_scalar_reference_loop() -> None:
    rng = np.random.default_rng(0)
    n = 2000
    states = np.column_stack([rng.uniform(-np.pi, np.pi, n), rng.uniform(-8, 8, n)])
    torques = rng.uniform(-9, 9, n)  # a third of them get clipped
    states[:5] = [[0.0, 0.0], [-np.pi, 0.0], [3.14, 7.99], [-3.14, -7.99], [0.5, 8.0]]
    nxt, rew = pendulum_step(states, torques)
    for i in range(n):
        th, om, r = _reference_step(states[i, 0], states[i, 1], torques[i])
        assert nxt[i, 0] == pytest.approx(th, abs=1e-12)
        assert nxt[i, 1] == pytest.approx(om, abs=1e-12)
        assert rew[i] == pytest.approx(r, abs=1e-15)


def test_reward_is_cos_of_state_before_step_and_torque_is_clipped() -> None:
    s = np.array([[0.3, -1.0]])
    _, r = pendulum_step(s, np.array([2.0]))
    assert r[0] == np.cos(0.3)
    a, _ = pendulum_step(s, np.array([5.0]))
    b, _ = pendulum_step(s, np.array([50.0]))
    np.testing.assert_array_equal(a, b)


def test_gravity_pulls_away_from_upright() -> None:
    nxt, _ = pendulum_step(np.array([0.1, 0.0]), 0.0)
    assert nxt[1] > 0 and nxt[0] > 0.1  # theta = 0 is the unstable upright equilibrium
    nxt, _ = pendulum_step(np.array(HANGING_DOWN), 0.0)
    np.testing.assert_allclose(nxt, [-np.pi, 0.0], atol=1e-14)  # hanging down is at rest


@settings(max_examples=200, deadline=None)
@given(
    theta=st.floats(-50, 50),
    omega=st.floats(-20, 20),
    u=st.floats(-100, 100),
)
def test_next_state_is_within_bounds(theta: float, omega: float, u: float) -> None:
    nxt, r = pendulum_step(np.array([theta, omega]), u)
    assert -np.pi <= nxt[0] < np.pi
    assert -8.0 <= nxt[1] <= 8.0
    assert -1.0 <= r <= 1.0


def test_batch_shapes_broadcast() -> None:
    states = np.zeros((3, 4, 2))
    nxt, r = pendulum_step(states, np.ones((3, 4)))
    assert nxt.shape == (3, 4, 2) and r.shape == (3, 4)
    nxt, r = pendulum_step(states, 1.0)  # a scalar torque broadcasts
    assert nxt.shape == (3, 4, 2) and r.shape == (3, 4)
    single, r1 = pendulum_step(np.array([0.2, 0.1]), 1.0)
    assert single.shape == (2,) and r1.shape == ()
    np.testing.assert_array_equal(pendulum_step(np.array([[0.2, 0.1]]), [1.0])[0][0], single)


def test_step_rejects_wrong_state_shape() -> None:
    with pytest.raises(ValueError, match="expected"):
        pendulum_step(np.zeros((4, 3)), np.zeros(4))


def test_wrap_angle() -> None:
    x = np.array([np.pi, -np.pi, 0.0, 3 * np.pi, -1e-20, 2 * np.pi - 1e-17, 7.0])
    w = wrap_angle(x)
    assert np.all(w >= -np.pi) and np.all(w < np.pi)
    assert w[0] == -np.pi and w[1] == -np.pi and w[2] == 0.0
    inside = np.array([0.1, -np.pi, 3.0, -2.5])
    np.testing.assert_array_equal(wrap_angle(inside), inside)
    np.testing.assert_allclose(np.cos(w), np.cos(x), atol=1e-12)
    np.testing.assert_allclose(np.sin(w), np.sin(x), atol=1e-12)


def test_energy() -> None:
    np.testing.assert_allclose(
        pendulum_energy([[0.0, 0.0], [np.pi, 0.0], [0.0, 2.0]]), [0, -19.62, 2]
    )


def test_params_validation() -> None:
    with pytest.raises(ValueError, match="dt"):
        PendulumParams(dt=0.0)
    with pytest.raises(ValueError, match="friction"):
        PendulumParams(friction=-1.0)
    p = PendulumParams(max_torque=2.0)
    nxt, _ = pendulum_step(np.array([0.0, 0.0]), 5.0, p)
    assert nxt[1] == pytest.approx(0.05 * 2.0)


def test_hanging_start_states_are_seeded_and_near_the_bottom() -> None:
    a = sample_hanging_states(np.random.default_rng(3), 500)
    b = sample_hanging_states(np.random.default_rng(3), 500)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (500, 2)
    assert np.all(np.abs(wrap_angle(a[:, 0] - np.pi)) <= 0.05 + 1e-12)
    assert np.all(np.abs(a[:, 1]) <= 0.05)
    assert np.all(a[:, 0] >= -np.pi) and np.all(a[:, 0] < np.pi)
    assert not np.array_equal(a, sample_hanging_states(np.random.default_rng(4), 500))
