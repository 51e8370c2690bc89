"""The planner against LQR (scipy's discrete algebraic Riccati equation) and its contracts."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from geoq.models import (
    CEMPlanner,
    GPDynamicsModel,
    PlannerSettings,
    model_returns,
    rollout_outcomes,
    rollout_returns,
)

from ._lqr import A_SYS, B_SYS, Everywhere, learned_model
from ._lqr import lqr as _lqr
from ._lqr import reward as _reward


def _exact_q(P: np.ndarray):
    """``Q(s, a) = r(s, a) - s'^T P s'``: the optimal value of acting ``a`` at ``s``."""

    def q(S: np.ndarray, A: np.ndarray) -> np.ndarray:
        S2 = S @ A_SYS.T + A @ B_SYS.T
        return _reward(S, A) - np.einsum("pi,ij,pj->p", S2, P, S2)

    return q


def _exact_returns(s0: np.ndarray, actions: np.ndarray, q) -> np.ndarray:
    S, total = np.repeat(s0[None], len(actions), axis=0), np.zeros(len(actions))
    for t in range(actions.shape[1] - 1):
        total += _reward(S, actions[:, t])
        S = S @ A_SYS.T + actions[:, t] @ B_SYS.T
    return total + q(S, actions[:, -1])


@pytest.mark.parametrize("horizon", [0, 3])
def test_the_first_action_approaches_the_lqr_action_on_the_exact_system(horizon: int) -> None:
    P, K = _lqr()
    low, high = np.array([-20.0]), np.array([20.0])
    settings = PlannerSettings(horizon=horizon, samples=300, iterations=12, elites=30,
                               min_std=1e-4)  # fmt: skip
    rng = np.random.default_rng(0)
    for s0 in (np.array([1.0, 0.0]), np.array([-0.5, 1.0]), np.array([0.3, -2.0])):
        planner = CEMPlanner(low, high, settings)
        a = planner.plan(lambda U, s0=s0: _exact_returns(s0, U, _exact_q(P)), rng)
        lqr = -(K @ s0)
        assert abs(a[0] - lqr[0]) < 0.02 * (1.0 + abs(lqr[0])), (a, lqr)


def test_through_a_learned_model_the_first_action_approaches_the_lqr_action() -> None:
    P, K = _lqr()
    rng = np.random.default_rng(1)
    model = learned_model(rng, 10.0)
    settings = PlannerSettings(horizon=3, samples=300, iterations=12, elites=30, min_std=1e-4)
    for s0 in (np.array([1.0, 0.0]), np.array([-0.5, 1.0])):
        planner = CEMPlanner(np.array([-10.0]), np.array([10.0]), settings)

        def score(U: np.ndarray, s0: np.ndarray = s0) -> np.ndarray:
            return model_returns(model, s0, U, gamma=1.0, value=_exact_q(P), value_floor=-1e3,
                                 rng=None)  # fmt: skip

        a, lqr = planner.plan(score, rng), -(K @ s0)
        assert abs(a[0] - lqr[0]) < 0.05 * (1.0 + abs(lqr[0])), (a, lqr)


class _LinearModel:
    """The double integrator as a model: exact means, no uncertainty (a known model)."""

    obs_dim = 2
    support = Everywhere()
    reward_range = np.array([-100.0, 0.0])

    def draw(self, S: np.ndarray, A: np.ndarray, normals: np.ndarray) -> tuple:
        mean = self.predict_mean(S, A)
        return mean, S + mean[:, :2] + 0.0 * normals

    def predict_mean(self, S: np.ndarray, A: np.ndarray) -> np.ndarray:
        change = S @ A_SYS.T + A @ B_SYS.T - S
        return np.column_stack([change, _reward(S, A), np.zeros(len(S))])


def test_model_returns_through_a_known_model_are_the_exact_returns() -> None:
    P, _ = _lqr()
    rng = np.random.default_rng(2)
    U = rng.uniform(-3.0, 3.0, size=(20, 5, 1))
    s0 = np.array([0.5, -0.5])
    got = model_returns(_LinearModel(), s0, U, gamma=1.0, value=_exact_q(P), value_floor=-9.0,
                        rng=rng)  # type: ignore[arg-type]  # fmt: skip
    np.testing.assert_allclose(got, _exact_returns(s0, U, _exact_q(P)), rtol=1e-12)
    discounted = model_returns(_LinearModel(), s0, U[:, :1], gamma=0.5, value=_exact_q(P),
                               value_floor=-9.0, rng=None)  # type: ignore[arg-type]  # fmt: skip
    np.testing.assert_allclose(discounted, _exact_q(P)(np.repeat(s0[None], 20, 0), U[:, 0]))


def test_a_predicted_termination_ends_the_return_and_far_from_the_data_it_halts() -> None:
    rng = np.random.default_rng(3)
    S = rng.uniform(-1.0, 1.0, size=(300, 1))
    A = rng.uniform(-1.0, 1.0, size=(300, 1))
    S2 = S + 0.1 * A
    T = (S2[:, 0] > 0.5).astype(float)  # stepping past 0.5 ends the episode
    model = GPDynamicsModel(1, 1).fit(S, A, np.ones(300), S2, T, rng)
    push = np.ones((2, 6, 1))
    push[1] = -1.0  # toward 0.5 and away from it
    got = model_returns(model, np.array([0.35]), push, gamma=1.0, value=None, rng=None)
    assert got[0] < 3.0 < got[1]  # ends after about 2 steps; -1 keeps to the data 5 steps

    # Driven far past the data the particle halts with the floor.
    def value(s: np.ndarray, a: np.ndarray) -> np.ndarray:
        return np.full(len(s), 100.0)

    away = np.full((1, 40, 1), -1.0)
    far = model_returns(model, np.array([0.0]), away, gamma=1.0, value=value, value_floor=-50.0,
                        rng=None)  # fmt: skip
    assert far[0] < 0.0


def test_the_planner_keeps_its_plan_as_the_next_start_and_the_same_seed_plans_alike() -> None:
    planner = CEMPlanner(np.array([-1.0, 0.0]), np.array([1.0, 2.0]), PlannerSettings(horizon=2))
    target = np.array([0.5, 1.5])

    def score(U: np.ndarray) -> np.ndarray:
        return -np.sum((U - target) ** 2, axis=(1, 2))

    a = planner.plan(score, np.random.default_rng(4))
    assert planner.mean is not None and planner.mean.shape == (3, 2)
    assert np.all(a >= [-1.0, 0.0]) and np.all(a <= [1.0, 2.0])
    again = CEMPlanner(np.array([-1.0, 0.0]), np.array([1.0, 2.0]), PlannerSettings(horizon=2))
    assert np.array_equal(again.plan(score, np.random.default_rng(4)), a)
    planner.reset()
    assert planner.mean is None


@pytest.mark.parametrize(
    ("field", "value"),
    [("horizon", -1), ("samples", 1), ("iterations", 0), ("elites", 65), ("init_std", -0.1),
     ("min_std", float("nan"))],
)  # fmt: skip
def test_bad_planner_settings_are_refused(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        PlannerSettings(**{field: value})


def test_a_score_of_the_wrong_shape_is_refused() -> None:
    planner = CEMPlanner(np.array([-1.0]), np.array([1.0]))
    with pytest.raises(ValueError, match="shape"):
        planner.plan(lambda U: np.zeros(3), np.random.default_rng(0))
    with pytest.raises(ValueError, match="high > low"):
        CEMPlanner(np.array([1.0]), np.array([1.0]))


def test_coloured_noise_has_unit_variance_and_is_smoother_than_white() -> None:
    from geoq.models.planner import _noise

    rng = np.random.default_rng(5)
    white, red = _noise(rng, (4000, 12, 2), 0.0), _noise(rng, (4000, 12, 2), 2.0)
    assert np.sqrt(np.mean(red**2)) == pytest.approx(1.0, rel=1e-9)
    lag1 = np.corrcoef(red[:, 3, 0], red[:, 4, 0])[0, 1]
    assert lag1 > 0.5 > abs(np.corrcoef(white[:, 3, 0], white[:, 4, 0])[0, 1])


def test_act_best_takes_the_best_scored_sequences_first_action() -> None:
    settings = PlannerSettings(horizon=1, samples=50, iterations=2, elites=5, act_best=True)
    planner = CEMPlanner(np.array([-1.0]), np.array([1.0]), settings)
    seen: list[np.ndarray] = []

    def score(U: np.ndarray) -> np.ndarray:
        seen.append(U.copy())
        return -np.abs(U[:, 0, 0] - 0.3)

    a = planner.plan(score, np.random.default_rng(6))
    every = np.concatenate(seen)
    assert a[0] == every[np.argmin(np.abs(every[:, 0, 0] - 0.3)), 0, 0]


def test_roll_outs_that_end_at_different_steps_are_each_particles_own() -> None:
    """Particles that end, halt or run on: the batch (which stops stepping the ended ones)
    against each particle rolled out alone, and the generator's stream either way."""
    rng = np.random.default_rng(5)
    S = rng.uniform(-1.0, 1.0, size=(300, 1))
    A = rng.uniform(-1.0, 1.0, size=(300, 1))
    S2 = S + 0.1 * A
    model = GPDynamicsModel(1, 1).fit(S, A, np.ones(300), S2, (S2[:, 0] > 0.5).astype(float), rng)
    U = rng.uniform(-1.0, 1.0, size=(12, 15, 1))
    U[:4] = 1.0  # toward the end
    U[4:8] = -1.0  # off the data
    s0 = np.array([0.2])
    batch = model_returns(model, s0, U, gamma=0.9, value=None, rng=np.random.default_rng(6))
    normals = np.random.default_rng(6).standard_normal((14, 12, 1))
    for p in range(12):
        alone = rollout_returns(model, s0[None], lambda t, X, rows, p=p: U[p, t][None], 14,
                                gamma=0.9, noise=normals[:, p : p + 1])  # fmt: skip
        assert batch[p] == pytest.approx(alone[0], rel=1e-12, abs=1e-12)
    np.testing.assert_allclose(batch[:4], 1 + 0.9 + 0.81 + 0.729)  # ended at the 4th step


@pytest.mark.parametrize("gamma", [1.0, 0.9])
def test_the_halted_steps_reprice_every_halt_as_a_roll_out_paid_otherwise(gamma: float) -> None:
    """Oracle: the same roll-outs through a copy of the model whose least reward is
    ``c`` (every reward is 1, so only the halts' price changes) return ``returns +
    halted * (c - 1)``; a particle that ends or keeps to the data has no halted step,
    and :func:`rollout_returns` is the first output, bit for bit."""
    rng = np.random.default_rng(5)
    S = rng.uniform(-1.0, 1.0, size=(300, 1))
    A = rng.uniform(-1.0, 1.0, size=(300, 1))
    S2 = S + 0.1 * A
    model = GPDynamicsModel(1, 1).fit(S, A, np.ones(300), S2, (S2[:, 0] > 0.5).astype(float), rng)
    U = np.zeros((9, 20, 1))
    U[:3], U[3:6, :, 0] = 1.0, [[-1.0], [-0.1], [-0.03]]  # toward the end, off the data, still
    s0 = np.full((9, 1), 0.2)
    s0[3:6] = -0.97  # the data end at -1.09: halted in part, over several steps

    def outcomes(m: GPDynamicsModel) -> tuple[np.ndarray, np.ndarray]:
        return rollout_outcomes(m, s0, lambda t, X, rows: U[rows, min(t, 19)], 20, gamma=gamma,
                                value=lambda X, Aa: np.full(len(X), 7.0), value_floor=-4.0,
                                noise=None)  # fmt: skip

    returns, halted = outcomes(model)
    alone = rollout_returns(model, s0, lambda t, X, rows: U[rows, min(t, 19)], 20, gamma=gamma,
                            value=lambda X, Aa: np.full(len(X), 7.0), value_floor=-4.0,
                            noise=None)  # fmt: skip
    np.testing.assert_array_equal(returns, alone)
    assert np.all(halted[:3] == 0.0) and np.all(halted[6:] == 0.0) and np.all(halted[3:6] > 0.0)
    for c in (-3.0, 0.25):
        repriced = copy.deepcopy(model)
        repriced.reward_range = np.array([c, 1.0])
        np.testing.assert_allclose(outcomes(repriced)[0], returns + halted * (c - 1.0),
                                   rtol=1e-12, atol=1e-12)  # fmt: skip


@pytest.mark.parametrize("trust_ends", [True, False])
def test_an_end_beyond_the_data_is_believed_or_paid_as_far_as_the_state_is_known(
    trust_ends: bool,
) -> None:
    """Oracle: a plain loop over the particles. A step's halt probability ``u`` (its next
    state's distance from the data) is paid as a halt where the step does not end, and, with
    ``trust_ends`` False, where it ends too, the end then counting on the other ``1 - u``."""
    rng = np.random.default_rng(5)
    S = rng.uniform(-1.0, 1.0, size=(300, 1))
    A = rng.uniform(-1.0, 1.0, size=(300, 1))
    S2 = S + 0.1 * A
    rewards = 1.0 + 0.5 * S[:, 0]
    model = GPDynamicsModel(1, 1).fit(S, A, rewards, S2, (S2[:, 0] > 0.5).astype(float), rng)
    s0 = np.array([[0.2], [0.3], [-0.97], [0.0], [1.05], [1.08]])
    U = np.array([1.0, 0.5, -0.5, 0.0, 1.0, 1.0])[:, None]  # ends, halts, stays, beyond
    gamma, horizon, r_least = 0.9, 12, float(model.reward_range[0])
    returns, halted = rollout_outcomes(model, s0, lambda t, X, rows: U[rows], horizon,
                                       gamma=gamma, noise=None, trust_ends=trust_ends)  # fmt: skip
    beyond = 0  # ends predicted at a state beyond the data
    for p in range(len(s0)):
        s, alive, total, steps = s0[p : p + 1], 1.0, 0.0, 0.0
        for t in range(horizon):
            mean = model.predict_mean(s, U[p : p + 1])[0]
            s = s + mean[:1]
            ends = mean[2] > 0.5
            u = min(max(model.support.distance(s)[0] - 1.0, 0.0), 1.0)
            beyond += bool(ends and u > 0.0)
            u = 0.0 if ends and trust_ends else u
            left = sum(gamma**k for k in range(t + 1, horizon))
            total += alive * (gamma**t * mean[1] + u * left * r_least)
            steps += alive * u * left
            alive *= (not ends) * (1.0 - u)
            if alive == 0.0:
                break
        assert returns[p] == pytest.approx(total, rel=1e-12, abs=1e-12)
        assert halted[p] == pytest.approx(steps, rel=1e-12, abs=1e-12)
    assert beyond >= 2 and np.any(halted[:4] > 0.0) and np.any(returns[:4] != 0.0)
    trusted = rollout_outcomes(model, s0, lambda t, X, rows: U[rows], horizon, gamma=gamma,
                               noise=None)  # fmt: skip
    assert trust_ends == np.array_equal(returns, trusted[0])
