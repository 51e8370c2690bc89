"""The feedback policy's search against LQR (scipy's Riccati equation) and brute force."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoq.models import (
    LinearFeedback,
    PolicySearchSettings,
    policy_returns,
    rollout_returns,
    search_gains,
)

from ._lqr import A_SYS, B_SYS, Everywhere, learned_model, true_return
from ._lqr import lqr as _lqr
from ._lqr import reward as _reward

STARTS = np.array([[1.0, 0.0], [-0.5, 1.0], [0.3, -1.0], [-1.0, -0.5]])


def _true_return(policy: LinearFeedback, gains: np.ndarray, starts: np.ndarray, T: int) -> float:
    """The policy's mean return on the true system, by a plain loop."""
    return true_return(lambda S: policy.act(gains, S), starts, T)


class _KnownModel:
    """The double integrator as a model, with a made-up std ``0.01`` on each state change."""

    obs_dim = 2
    support = Everywhere()
    reward_range = np.array([-1e6, 0.0])

    def predict_mean(self, S: np.ndarray, A: np.ndarray) -> np.ndarray:
        change = S @ A_SYS.T + A @ B_SYS.T - S
        return np.column_stack([change, _reward(S, A), np.zeros(len(S))])

    def draw(self, S: np.ndarray, A: np.ndarray, normals: np.ndarray) -> tuple:
        mean = self.predict_mean(S, A)
        return mean, S + mean[:, :2] + 0.01 * normals


def _policy(box: float = 20.0) -> LinearFeedback:
    return LinearFeedback(np.array([-box]), np.array([box]), np.zeros(2), np.ones(2))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.1, 100.0))
def test_feedback_actions_stay_in_the_box_and_each_state_acts_as_alone(seed, spread) -> None:
    rng = np.random.default_rng(seed)
    policy = LinearFeedback(np.array([-1.0, 0.0]), np.array([2.0, 0.5]), rng.normal(size=3),
                            rng.uniform(0.1, 2.0, 3))  # fmt: skip
    gains = spread * rng.standard_normal((20, *policy.shape))
    S = spread * rng.standard_normal((20, 3))
    A = policy.act_rows(gains, S)
    assert np.all(A >= [-1.0, 0.0]) and np.all(A <= [2.0, 0.5])
    for i in range(20):  # a brute-force loop, one state and one policy at a time
        z = np.append((S[i] - policy.center) / policy.scale, 1.0)
        expected = policy.mid + policy.half * np.tanh([sum(z * g) for g in gains[i]])
        np.testing.assert_allclose(A[i], expected, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(A[i], policy.act(gains[i], S[i : i + 1])[0])
        np.testing.assert_array_equal(A[i], policy.act_rows(gains[i : i + 1], S[i : i + 1])[0])


def test_policy_returns_are_each_candidates_own_roll_outs_on_the_same_draws() -> None:
    rng = np.random.default_rng(0)
    policy, model = _policy(), _KnownModel()
    gains = rng.normal(size=(3, *policy.shape))
    normals = rng.standard_normal((25, len(STARTS), 2))
    got = policy_returns(model, policy, gains, STARTS, normals)  # type: ignore[arg-type]
    for c in range(3):
        alone = rollout_returns(model, STARTS, lambda t, S, rows, c=c: policy.act(gains[c], S), 25,  # type: ignore[arg-type]
                                gamma=1.0, noise=normals)  # fmt: skip
        np.testing.assert_allclose(got[c], alone, rtol=1e-12)
    # with no noise at all, the mean is the true system's return (a brute-force loop)
    quiet = policy_returns(model, policy, gains, STARTS, np.zeros_like(normals))  # type: ignore[arg-type]
    for c in range(3):
        assert quiet[c].mean() == pytest.approx(
            _true_return(policy, gains[c], STARTS, 25), rel=1e-12
        )


def _check_near_lqr(policy: LinearFeedback, gains: np.ndarray, T: int) -> None:
    P, K = _lqr()
    optimum = -np.mean(np.einsum("pi,ij,pj->p", STARTS, P, STARTS))
    got = _true_return(policy, gains, STARTS, T)
    assert got >= 1.02 * optimum, (got, optimum)  # returns are negative: within 2%
    for s in STARTS:
        lqr = -(K @ s)[0]
        assert abs(policy.act(gains, s[None])[0, 0] - lqr) < 0.2 * (1.0 + abs(lqr)), (s, lqr)


def test_the_search_through_the_exact_system_finds_the_lqr_policy() -> None:
    policy = _policy()
    search = PolicySearchSettings(horizon=100, particles=4, candidates=48, iterations=30, elites=6,
                                  patience=30)  # fmt: skip
    gains, value = search_gains(_KnownModel(), policy, np.zeros(policy.shape), STARTS,  # type: ignore[arg-type]
                                np.random.default_rng(1), search)  # fmt: skip
    assert np.isfinite(value)
    _check_near_lqr(policy, gains, 100)


def test_the_search_through_a_learned_model_finds_the_lqr_policy() -> None:
    rng = np.random.default_rng(2)
    model = learned_model(rng, 20.0)
    policy = _policy()
    search = PolicySearchSettings(horizon=100, particles=4, candidates=48, iterations=30, elites=6,
                                  patience=30)  # fmt: skip
    gains, _ = search_gains(model, policy, np.zeros(policy.shape), STARTS, rng, search)
    _check_near_lqr(policy, gains, 100)


def test_ties_keep_the_current_gains_and_the_same_seed_searches_alike() -> None:
    policy = _policy()

    class _Flat(_KnownModel):
        steps = 0

        def predict_mean(self, S: np.ndarray, A: np.ndarray) -> np.ndarray:
            self.steps += 1
            mean = super().predict_mean(S, A)
            mean[:, 2] = -1.0  # every policy scores the same
            return mean

    start, flat = np.full(policy.shape, 0.3), _Flat()
    gains, value = search_gains(flat, policy, start, STARTS, np.random.default_rng(3),  # type: ignore[arg-type]
                                PolicySearchSettings(horizon=5, patience=2))  # fmt: skip
    assert np.array_equal(gains, start) and value == -5.0
    assert flat.steps == 5 * (1 + 2) + 5  # the first best, two stale iterations; the holdout
    runs = [search_gains(_KnownModel(), policy, start, STARTS, np.random.default_rng(4),  # type: ignore[arg-type]
                         PolicySearchSettings(horizon=10)) for _ in range(2)]  # fmt: skip
    assert np.array_equal(runs[0][0], runs[1][0]) and runs[0][1] == runs[1][1]


def test_bad_settings_and_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="elites"):
        PolicySearchSettings(candidates=4, elites=5)
    with pytest.raises(ValueError, match="horizon"):
        PolicySearchSettings(horizon=0)
    with pytest.raises(ValueError, match="high > low"):
        LinearFeedback(np.array([1.0]), np.array([1.0]), np.zeros(2), np.ones(2))
    with pytest.raises(ValueError, match="scale"):
        LinearFeedback(np.array([0.0]), np.array([1.0]), np.zeros(2), np.array([1.0, 0.0]))
    policy = _policy()
    with pytest.raises(ValueError, match="gains"):
        search_gains(_KnownModel(), policy, np.zeros((2, 3)), STARTS, np.random.default_rng(0))  # type: ignore[arg-type]


class _Gamble:
    """``x' = x + a n`` (``n`` the draw's normal), paid ``x``: every policy's expected
    return is the same, and only luck tells them apart on a sample."""

    obs_dim = 1
    support = Everywhere()
    reward_range = np.array([-1e6, 1e6])

    def predict_mean(self, S: np.ndarray, A: np.ndarray) -> np.ndarray:
        return np.column_stack([np.zeros(len(S)), S[:, 0], np.zeros(len(S))])

    def draw(self, S: np.ndarray, A: np.ndarray, normals: np.ndarray) -> tuple:
        return self.predict_mean(S, A), S + A * normals


def test_the_holdout_keeps_the_current_gains_against_a_lucky_winner() -> None:
    policy = LinearFeedback(np.array([-1.0]), np.array([1.0]), np.zeros(1), np.ones(1))
    start, starts = np.zeros(policy.shape), np.zeros((1, 1))
    kept, flattered = 0, []
    for seed in range(10):
        for holdout in (True, False):
            search = PolicySearchSettings(horizon=20, particles=16, holdout=holdout)
            gains, value = search_gains(_Gamble(), policy, start, starts,  # type: ignore[arg-type]
                                        np.random.default_rng(seed), search)  # fmt: skip
            if holdout:
                kept += np.array_equal(gains, start)
            else:
                flattered.append(value)
    assert kept >= 8  # a lucky winner rarely passes the fresh, paired test
    assert min(flattered) > 0.0  # on its own sample the best always looks better than 0
