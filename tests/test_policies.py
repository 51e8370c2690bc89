"""The swing-up controller, the Gaussian policy, and the discontinuity of Q^pi they cause."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import geoq  # noqa: F401
from geoq.envs import PendulumParams, pendulum_energy, pendulum_step
from geoq.evaluation import mc_q_values
from geoq.policies import DEFAULT_POLICY_SIGMA, GaussianPolicy, SwingUpController, default_policy
from geoq.rollouts import collect_rollouts


def test_controller_shapes_and_torque_limit() -> None:
    f = SwingUpController()
    rng = np.random.default_rng(0)
    states = np.column_stack([rng.uniform(-np.pi, np.pi, 1000), rng.uniform(-8, 8, 1000)])
    u = f(states)
    assert u.shape == (1000,)
    assert np.all(np.abs(u) <= 5.0)
    assert f(states.reshape(10, 100, 2)).shape == (10, 100)
    np.testing.assert_array_equal(f(states[3]), u[3])
    with pytest.raises(ValueError, match="expected"):
        f(np.zeros((4, 3)))


def test_control_law_on_each_side_of_the_capture_boundary() -> None:
    f = SwingUpController()
    inside = np.array([0.1, -0.2])
    assert f.in_capture_region(inside)
    assert f(inside) == pytest.approx(-(20.0 * 0.1 + 5.0 * -0.2))  # PD feedback
    # Outside: energy pumping, sign of omega times the energy deficit, saturated.
    bottom = np.array([-np.pi + 0.1, 1.0])
    assert not f.in_capture_region(bottom)
    assert f(bottom) == 5.0  # E < 0 and omega > 0: push with the motion
    assert f(np.array([-np.pi + 0.1, -1.0])) == -5.0
    fast_top = np.array([0.0, 3.0])  # E > 0 outside the band: brake
    assert f(fast_top) == pytest.approx(max(-5.0, -2.0 * pendulum_energy(fast_top)))
    assert f(fast_top) < 0
    # The band follows the stable manifold omega = -sqrt(g) theta.
    slope = np.sqrt(9.81)
    assert f.in_capture_region(np.array([0.5, -0.5 * slope]))
    assert not f.in_capture_region(np.array([0.5, 0.5 * slope]))
    assert f.in_capture_region(np.array([0.0, 0.999])) and not f.in_capture_region([0.0, 1.001])


def test_gaussian_policy_noise_and_clipping() -> None:
    policy = GaussianPolicy(sigma=0.5)
    states = np.tile([0.01, 0.0], (20000, 1))  # f(s) = -0.2, far from the limits
    a = policy(states, np.random.default_rng(1))
    assert a.mean() == pytest.approx(-0.2, abs=4 * 0.5 / np.sqrt(20000))
    assert a.std() == pytest.approx(0.5, rel=0.03)
    far = np.tile([np.pi - 0.1, 1.0], (1000, 1))  # f(s) = +5 (saturated pumping)
    a = GaussianPolicy(sigma=3.0)(far, np.random.default_rng(2))
    assert np.all(np.abs(a) <= 5.0) and np.mean(a == 5.0) == pytest.approx(0.5, abs=0.06)


def test_policy_is_deterministic_given_the_generator() -> None:
    policy = default_policy()
    assert policy.sigma == DEFAULT_POLICY_SIGMA
    states = np.random.default_rng(0).uniform(-3, 3, (50, 2))
    a1 = policy(states, np.random.default_rng(7))
    a2 = policy(states, np.random.default_rng(7))
    np.testing.assert_array_equal(a1, a2)
    assert not np.array_equal(a1, policy(states, np.random.default_rng(8)))
    deterministic = GaussianPolicy(sigma=0.0)
    np.testing.assert_array_equal(
        deterministic(states, np.random.default_rng(1)), deterministic.mean_action(states)
    )


def test_bad_parameters() -> None:
    with pytest.raises(ValueError, match="sigma"):
        GaussianPolicy(sigma=-1.0)
    with pytest.raises(ValueError, match="capture_speed"):
        SwingUpController(capture_speed=0.0)


def test_controller_swings_up_from_hanging_down_and_balances() -> None:
    """Through the Gymnasium env: exact hanging-down start, deterministic controller."""
    f = SwingUpController()
    env = gym.make("geoq/PendulumSwingUp-v0")
    obs, _ = env.reset(options={"state": [-np.pi, 0.0]})
    thetas, captured_at = [], None
    for t in range(250):
        if captured_at is None and f.in_capture_region(obs):
            captured_at = t
        obs, *_ = env.step(np.array([f(obs)]))
        thetas.append(obs[0])
    assert captured_at is not None and 20 < captured_at <= 100  # needs pumping, but not forever
    balance = np.abs(np.array(thetas[captured_at + 40 :]))
    assert balance.max() < 0.01  # upright and staying there


def test_noisy_policy_swings_up_and_balances() -> None:
    rollouts = collect_rollouts(200, 250, default_policy(), np.random.default_rng(0))
    f = SwingUpController()
    inside = np.array([f.in_capture_region(ro.states) for ro in rollouts])  # [200, 250]
    assert inside[:, 150:].all()  # every roll-out is balanced by step 150
    assert inside[:, :40].sum() == 0  # nobody starts near the top
    thetas = np.array([ro.states[150:, 0] for ro in rollouts])
    assert np.abs(thetas).max() < 0.3


def test_controller_depends_on_params() -> None:
    weak = SwingUpController(params=PendulumParams(max_torque=2.0))
    assert np.all(np.abs(weak(np.random.default_rng(0).uniform(-3, 3, (100, 2)))) <= 2.0)


def test_q_jumps_across_the_capture_boundary() -> None:
    """Q^pi(s, f(s)) by Monte Carlo on both sides of the band edge omega + sqrt(g) theta = 1.

    On this part of the edge (theta >= 0: leaving the band means moving away
    from the top) the pendulum outside the band falls over; inside it is caught.
    """
    policy = default_policy()
    f = policy.controller
    slope = f.manifold_slope
    thetas = np.array([0.0, 0.2, 0.4])
    offsets = np.array([-0.04, -0.01, 0.01, 0.04])  # distance from the edge in omega
    theta_grid, off_grid = np.meshgrid(thetas, offsets, indexing="ij")
    omega = f.capture_speed - slope * theta_grid + off_grid
    states = np.column_stack([theta_grid.ravel(), omega.ravel()])
    inside = f.in_capture_region(states).reshape(theta_grid.shape)
    assert inside[:, :2].all() and not inside[:, 2:].any()
    est = mc_q_values(states, f(states), policy, np.random.default_rng(0), n_rollouts=200)
    q = est.mean.reshape(theta_grid.shape)
    se = est.stderr.reshape(theta_grid.shape)
    assert se.max() < 0.1  # the jump is not Monte-Carlo noise
    jump = q[:, 1] - q[:, 2]  # 0.02 apart across the edge
    smooth_in = np.abs(q[:, 0] - q[:, 1])  # 0.03 apart, both inside
    smooth_out = np.abs(q[:, 2] - q[:, 3])  # 0.03 apart, both outside
    assert np.all(jump > 5.0)
    assert np.all(smooth_in < 0.3) and np.all(smooth_out < 0.5)
    assert np.all(q[:, :2] > 19.0)  # caught: about 1 / (1 - gamma) = 20


def test_capture_band_lies_inside_the_feedbacks_basin() -> None:
    """Every state of the band is balanced by f without ever leaving the band."""
    f = SwingUpController()
    edge = 1 - 1e-12  # the closed band, up to rounding of omega + slope * theta
    theta = np.linspace(-f.capture_angle, f.capture_angle, 41)
    offset = np.linspace(-f.capture_speed, f.capture_speed, 41) * edge
    T, O = np.meshgrid(theta, offset, indexing="ij")
    s = np.column_stack([T.ravel(), (O - f.manifold_slope * T).ravel()])
    assert f.in_capture_region(s).all()
    for _ in range(200):
        s, _ = pendulum_step(s, f(s))
        assert f.in_capture_region(s).all()
    assert np.abs(s).max() < 1e-3


def test_about_four_in_five_noisy_swing_ups_are_caught_on_the_first_approach() -> None:
    f = SwingUpController()
    rollouts = collect_rollouts(400, 55, default_policy(), np.random.default_rng(11))
    caught = np.array([f.in_capture_region(ro.states).any() for ro in rollouts])
    assert 0.7 < caught.mean() < 0.9
