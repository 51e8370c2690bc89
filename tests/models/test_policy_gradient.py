"""The neural policy's gradient search: each derivative against finite differences, the
smooth return against the exact roll-outs, and the search against LQR."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoq.models import (
    GPDynamicsModel,
    MLPFeedback,
    ModelSettings,
    PolicyGradientSettings,
    policy_gradient,
    rollout_returns,
    search_policy,
    soft_return,
)

from ._lqr import learned_model, true_return
from ._lqr import lqr as _lqr

STARTS = np.array([[1.0, 0.0], [-0.5, 1.0], [0.3, -1.0], [-1.0, -0.5]])


def _central(f, x: np.ndarray, eps: float) -> np.ndarray:
    """Central finite differences of a scalar ``f`` at ``x`` [n]."""
    grad = np.zeros_like(x)
    for i in range(len(x)):
        step = np.zeros_like(x)
        step[i] = eps
        grad[i] = (f(x + step) - f(x - step)) / (2 * eps)
    return grad


def _ending_model(rng: np.random.Generator) -> GPDynamicsModel:
    """A nonlinear 3-state model whose episodes end beyond ``|s_0| > 1.5``."""
    S = rng.normal(size=(200, 3))
    A = rng.uniform(-1.0, 1.0, size=(200, 1))
    change = 0.1 * np.column_stack([S[:, 1], np.sin(S[:, 0]) + A[:, 0], -S[:, 2] * A[:, 0]])
    R = -np.sum(S**2, axis=1) - 0.1 * A[:, 0] ** 2
    ends = (np.abs(S[:, 0]) > 1.5).astype(float)
    return GPDynamicsModel(3, 1).fit(S, A, R, S + change, ends, rng)


def test_the_means_gradients_are_their_finite_differences() -> None:
    rng = np.random.default_rng(0)
    model = _ending_model(rng)
    S, A = rng.normal(size=(6, 3)), rng.uniform(-1.0, 1.0, size=(6, 1))
    mean, jac = model.mean_gradients(S, A)
    # the same sums, compiled apart: they may round apart (fastmath)
    np.testing.assert_allclose(mean, model.predict_mean(S, A), rtol=1e-7, atol=1e-12)
    for p in range(6):
        x = np.append(S[p], A[p])
        for j in range(model.n_outputs):

            def output(v: np.ndarray, j: int = j) -> float:
                return float(model.predict_mean(v[None, :3], v[None, 3:])[0, j])

            expected = _central(output, x, 1e-4)
            np.testing.assert_allclose(
                jac[p, j], expected, rtol=1e-5, atol=1e-6 * (1 + abs(expected).max())
            )
    clipped = mean[:, 3] == model.reward_range[1]
    assert clipped.any() and not jac[clipped, 3].any()  # a clipped reward does not move


def test_the_supports_gradient_is_its_finite_differences() -> None:
    rng = np.random.default_rng(1)
    model = _ending_model(rng)
    for _ in range(70):  # some in the tree, some waiting beside it
        model.support.add(rng.normal(size=3))
    S = 2.0 * rng.normal(size=(8, 3))
    dist, grad = model.support.distance_gradient(S)
    np.testing.assert_allclose(dist, model.support.distance(S), rtol=1e-12)
    for p in range(8):
        expected = _central(lambda s: float(model.support.distance(s[None])[0]), S[p], 1e-6)
        np.testing.assert_allclose(grad[p], expected, rtol=1e-5, atol=1e-8)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_the_networks_gradients_are_their_finite_differences(seed: int) -> None:
    rng = np.random.default_rng(seed)
    policy = MLPFeedback(np.array([-1.0, 0.0]), np.array([2.0, 0.5]), rng.normal(size=3),
                         rng.uniform(0.5, 2.0, 3), hidden=4)  # fmt: skip
    params, S = rng.normal(size=policy.n_params), rng.normal(size=(5, 3))
    weights = rng.normal(size=(5, 2))
    A, cache = policy.forward(params, S)
    assert np.all(A >= [-1.0, 0.0]) and np.all(A <= [2.0, 0.5])
    g_params, g_states = policy.backward(params, cache, weights)
    expected = _central(lambda v: float(np.sum(weights * policy.act(v, S))), params, 1e-6)
    np.testing.assert_allclose(g_params, expected, rtol=1e-6, atol=1e-8)
    flat = _central(lambda v: float(np.sum(weights * policy.act(params, v.reshape(5, 3)))),
                    S.ravel(), 1e-6)  # fmt: skip
    np.testing.assert_allclose(g_states, flat.reshape(5, 3), rtol=1e-6, atol=1e-8)
    assert np.array_equal(policy.act(policy.initial(rng), S), np.tile(policy.mid, (5, 1)))


def test_the_smooth_returns_gradient_is_its_finite_differences() -> None:
    rng = np.random.default_rng(2)
    model = _ending_model(rng)
    policy = MLPFeedback(np.array([-1.0]), np.array([1.0]), np.zeros(3), np.ones(3), hidden=5)
    params = policy.initial(rng) + 0.5 * rng.normal(size=policy.n_params)
    starts = rng.normal(size=(6, 3))
    normals = np.zeros((15, 6, 3))  # the means' roll-outs (with draws the stds are held
    _, grad = soft_return(model, policy, params, starts, normals)  # constant in the gradient)
    expected = _central(lambda v: soft_return(model, policy, v, starts, normals)[0], params, 1e-4)
    np.testing.assert_allclose(grad, expected, rtol=1e-4, atol=1e-4 * np.abs(expected).max())
    drawn = soft_return(model, policy, params, starts, rng.normal(size=(15, 6, 3)))[0]
    assert np.isfinite(drawn) and drawn != soft_return(model, policy, params, starts, normals)[0]
    ends, halts, running, w = [], [], [], np.ones(6)
    S = starts.copy()
    for _ in range(15):  # the roll-outs did meet the weights' both causes
        mean = model.predict_mean(S, policy.act(params, S))
        S = S + mean[:, :3]
        ends.append(mean[:, 4].max())
        dist = model.support.distance(S)
        halts.append(dist.max())
        w *= (1 - np.clip(mean[:, 4], 0, 1)) * (1 - np.clip(dist - 1, 0, 1))
        running.append(int((w > 0).sum()))
    assert max(ends) > 0.0 and max(halts) > 1.0
    assert len(set(running)) > 2  # roll-outs stop for sure at different steps (not stepped on)
    # the particles' model steps taken: each step counts the roll-outs alive at its start
    taken = policy_gradient._soft_return(model, policy, params, starts, normals)[2]
    assert taken == 6 + sum(running[:-1]) < 6 * 15


@pytest.mark.parametrize("close_halts", [True, False])
def test_a_closed_smooth_return_is_its_brute_force_sum_and_its_gradient_its_differences(
    close_halts: bool,
) -> None:
    """With ``tail`` steps more, a plain loop over the particles: each step's reward weighted
    by the chance the roll-out runs, a halt paid the least reward for the steps left (and
    the tail's, ``close_halts``), and after the last step ``tail_reward`` for each tail step
    weighted by the chance the roll-out runs (``close_halts``) or has not ended (else),
    halted roll-outs stopped where they halted."""
    rng = np.random.default_rng(2)
    model = _ending_model(rng)
    policy = MLPFeedback(np.array([-1.0]), np.array([1.0]), np.zeros(3), np.ones(3), hidden=5)
    params = policy.initial(rng) + 0.5 * rng.normal(size=policy.n_params)
    starts, normals, tail, tail_reward = rng.normal(size=(6, 3)), np.zeros((15, 6, 3)), 7, 0.8
    value, grad = soft_return(model, policy, params, starts, normals, tail, tail_reward,
                              close_halts)  # fmt: skip
    r_least, expected, halted = model.reward_range[0], 0.0, 0
    for p in range(6):
        s, w, alive = starts[p : p + 1], 1.0, 1.0
        for t in range(15):
            mean = model.predict_mean(s, policy.act(params, s))[0]
            s = s + mean[:3]
            end = min(max(mean[4], 0.0), 1.0)
            halt = min(max(model.support.distance(s)[0] - 1.0, 0.0), 1.0)
            rest = 14 - t + (tail if close_halts else 0)
            expected += w * (mean[3] + (1 - end) * halt * rest * r_least)
            w *= (1 - end) * (1 - halt)
            alive *= 1 - end
            halted += halt == 1.0 and w == 0.0
            if w == 0.0:
                break
        expected += (w if close_halts else alive) * tail * tail_reward
    assert halted >= 2  # halted roll-outs, whose closing value the two ways part
    assert value == pytest.approx(expected / 6, rel=1e-9)
    assert value != soft_return(model, policy, params, starts, normals)[0]
    differences = _central(
        lambda v: soft_return(model, policy, v, starts, normals, tail, tail_reward,
                              close_halts)[0],
        params, 1e-4,
    )  # fmt: skip
    np.testing.assert_allclose(grad, differences, rtol=1e-4,
                               atol=1e-4 * np.abs(differences).max())  # fmt: skip
    with pytest.raises(ValueError, match="tail"):
        soft_return(model, policy, params, starts, normals, -1)


def test_with_no_end_and_no_halt_the_smooth_return_is_the_exact_one() -> None:
    rng = np.random.default_rng(3)
    model = learned_model(rng, 20.0)
    model.support.spacing = 1e9  # every state among the data
    policy = MLPFeedback(np.array([-20.0]), np.array([20.0]), np.zeros(2), np.ones(2), hidden=6)
    params = rng.normal(size=policy.n_params)
    normals = np.zeros((30, len(STARTS), 2))
    value, _ = soft_return(model, policy, params, STARTS, normals)
    exact = rollout_returns(model, STARTS, lambda t, S, rows: policy.act(params, S), 30,
                            gamma=1.0, noise=None)  # fmt: skip
    assert value == pytest.approx(exact.mean(), rel=1e-9)


def _true_return(policy: MLPFeedback, params: np.ndarray, T: int) -> float:
    return true_return(lambda S: policy.act(params, S), STARTS, T)


def test_the_search_through_a_learned_model_nears_the_lqr_return() -> None:
    rng = np.random.default_rng(4)
    model = learned_model(rng, 20.0)
    policy = MLPFeedback(np.array([-20.0]), np.array([20.0]), np.zeros(2), np.ones(2), hidden=8)
    start = policy.initial(rng)
    search = PolicyGradientSettings(horizon=50, particles=16, steps=300, learning_rate=0.1)
    params, value = search_policy(model, policy, start, STARTS, rng, search)
    P, _ = _lqr()
    optimum = -np.mean(np.einsum("pi,ij,pj->p", STARTS, P, STARTS))
    got = _true_return(policy, params, 100)
    assert _true_return(policy, start, 100) < 3.0 * optimum  # far from it at the start
    assert got >= 1.15 * optimum, (got, optimum)  # within 15% (returns are negative)
    assert np.isfinite(value)


@pytest.mark.parametrize("branch", [20, 30])
def test_a_search_branched_from_stored_states_nears_the_lqr_return(branch: int) -> None:
    """Adam up the return of ``branch`` steps from states spread over the region (stored
    states, not the starts): the found weights, judged over the whole horizon from the
    starts, near the LQR return."""
    rng = np.random.default_rng(4)
    model = learned_model(rng, 20.0)
    policy = MLPFeedback(np.array([-20.0]), np.array([20.0]), np.zeros(2), np.ones(2), hidden=8)
    start = policy.initial(rng)
    stored = rng.uniform(-1.5, 1.5, size=(500, 2))
    search = PolicyGradientSettings(horizon=50, particles=16, steps=300, learning_rate=0.1,
                                    branch_horizon=branch)  # fmt: skip
    params, value = search_policy(model, policy, start, STARTS, rng, search, branch_from=stored)
    P, _ = _lqr()
    optimum = -np.mean(np.einsum("pi,ij,pj->p", STARTS, P, STARTS))
    assert not np.array_equal(params, start)
    assert _true_return(policy, params, 100) >= 1.15 * optimum
    assert np.isfinite(value)


def test_a_branch_horizon_without_stored_states_is_the_plain_search() -> None:
    rng = np.random.default_rng(5)
    model = learned_model(rng, 20.0)
    policy = MLPFeedback(np.array([-20.0]), np.array([20.0]), np.zeros(2), np.ones(2), hidden=4)
    start = policy.initial(rng)
    runs = [search_policy(model, policy, start, STARTS, np.random.default_rng(6),
                          PolicyGradientSettings(horizon=20, particles=4, steps=5,
                                                 branch_horizon=branch, whole_steps=whole))
            for branch, whole in ((0, 0), (5, 0), (5, 3))]  # fmt: skip
    for run in runs[1:]:
        assert np.array_equal(runs[0][0], run[0]) and runs[0][1] == run[1]


def test_a_whole_horizon_climb_beside_a_myopic_branched_one_is_kept() -> None:
    """One-step branches climb a myopic return (this LQR's one-step optimum is far from
    its optimum over the horizon: 450 times its cost here); the whole-horizon climb beside
    them comes within a small factor of it (300 plain steps come within 1.4-2.2 times,
    by the seed), and the holdout keeps it."""
    rng = np.random.default_rng(4)
    model = learned_model(rng, 20.0)
    policy = MLPFeedback(np.array([-20.0]), np.array([20.0]), np.zeros(2), np.ones(2), hidden=8)
    start = policy.initial(rng)
    stored = rng.uniform(-1.5, 1.5, size=(500, 2))
    P, _ = _lqr()
    optimum = -np.mean(np.einsum("pi,ij,pj->p", STARTS, P, STARTS))
    got = {}
    for whole_steps in (0, 300):
        search = PolicyGradientSettings(horizon=50, particles=16, steps=300, learning_rate=0.1,
                                        branch_horizon=1, whole_steps=whole_steps)  # fmt: skip
        params, _ = search_policy(model, policy, start, STARTS, np.random.default_rng(6),
                                  search, branch_from=stored)  # fmt: skip
        got[whole_steps] = _true_return(policy, params, 100)
    assert got[0] < 10.0 * optimum  # the branched climb alone (returns are negative)
    assert got[300] >= 2.5 * optimum, (got, optimum)


def _edge_task(S: np.ndarray, A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A cart on a line paid 1 a step alive and half its push to the right more, whose
    episode ends past ``s = 1``: the next states [N, 1], rewards [N] and ends [N] of states
    [N, 1] and actions [N, 1]."""
    S2 = S + 0.1 * A
    return S2, 1.0 + 0.5 * A[:, 0], (S2[:, 0] > 1.0).astype(float)


def test_a_closed_branch_climbs_away_from_the_end_a_short_branch_cannot_see() -> None:
    """Two-step branches see the push's pay and barely the end's cost (two steps' worth); the
    judge's 50 steps see the end's whole cost. Closed by the data's mean reward for the 48
    steps left, the branched climb learns to stop short of the edge; unclosed, it keeps
    pushing over it."""
    rng = np.random.default_rng(7)
    S, A = rng.uniform(-1.5, 1.2, size=(300, 1)), rng.uniform(-1.0, 1.0, size=(300, 1))
    S2, R, ends = _edge_task(S, A)
    model = GPDynamicsModel(1, 1, ModelSettings(max_bv=100)).fit(S, A, R, S2, ends, rng)
    policy = MLPFeedback(np.array([-1.0]), np.array([1.0]), np.zeros(1), np.ones(1), hidden=8)
    start = policy.initial(rng)
    start[-1] = 2.0  # the output's bias: push right nearly flat out everywhere
    starts = rng.uniform(-0.5, 0.5, size=(32, 1))

    def true_return(params: np.ndarray) -> float:
        s, alive, total = starts.copy(), np.ones(len(starts)), 0.0
        for _ in range(50):
            s, r, end = _edge_task(s, policy.act(params, s))
            total += float(np.sum(alive * r))
            alive *= 1.0 - end
        return total / len(starts)

    got = {}
    for closed in (False, True):
        search = PolicyGradientSettings(horizon=50, particles=32, steps=200, learning_rate=0.05,
                                        branch_horizon=2, close_branch=closed)  # fmt: skip
        params, _ = search_policy(model, policy, start, starts, np.random.default_rng(8), search,
                                  branch_from=S)  # fmt: skip
        got[closed] = true_return(params)
    assert true_return(start) < 20.0  # over the edge within about ten steps
    assert got[False] < 25.0 and got[True] > 45.0, got


@pytest.mark.parametrize("order", [(0, 1), (1, 0)])
def test_the_holdout_keeps_the_better_of_the_two_climbs(monkeypatch, order) -> None:
    """Whichever climb runs first, the weights the exact returns favour are returned."""
    rng = np.random.default_rng(4)
    model = learned_model(rng, 20.0)
    policy = MLPFeedback(np.array([-20.0]), np.array([20.0]), np.zeros(2), np.ones(2), hidden=8)
    start = policy.initial(rng)
    good, _ = search_policy(model, policy, start, STARTS, rng,
                            PolicyGradientSettings(horizon=50, particles=16, steps=300,
                                                   learning_rate=0.1))  # fmt: skip
    worse = start + 0.3 * (good - start)
    candidates = [[worse, good][i] for i in order]
    monkeypatch.setattr(policy_gradient, "_climb", lambda *args: candidates.pop(0))
    search = PolicyGradientSettings(horizon=50, branch_horizon=5, whole_steps=1)
    params, value = search_policy(model, policy, start, STARTS, rng, search,
                                  branch_from=STARTS)  # fmt: skip
    assert np.array_equal(params, good) and not candidates and np.isfinite(value)


def test_the_current_weights_stay_unless_beaten_and_the_same_seed_searches_alike() -> None:
    rng = np.random.default_rng(5)
    model = learned_model(rng, 20.0)
    policy = MLPFeedback(np.array([-20.0]), np.array([20.0]), np.zeros(2), np.ones(2), hidden=4)
    start = policy.initial(rng)
    kept, value = search_policy(model, policy, start, STARTS, rng, PolicyGradientSettings(steps=0))
    assert np.array_equal(kept, start) and np.isfinite(value)
    search = PolicyGradientSettings(horizon=20, particles=4, steps=5)
    runs = [search_policy(model, policy, start, STARTS, np.random.default_rng(6), search)
            for _ in range(2)]  # fmt: skip
    assert np.array_equal(runs[0][0], runs[1][0]) and runs[0][1] == runs[1][1]


def test_the_search_stops_where_the_gradients_square_overflows(monkeypatch) -> None:
    """A gradient of 1e200 (its square overflows) stops the Adam steps, with no warning,
    at the best weights before it."""
    rng = np.random.default_rng(5)
    model = learned_model(rng, 20.0)
    policy = MLPFeedback(np.array([-20.0]), np.array([20.0]), np.zeros(2), np.ones(2), hidden=4)
    start = policy.initial(rng)
    seen: list[np.ndarray] = []

    def huge_later(model, policy, theta, *rest):  # type: ignore[no-untyped-def]
        seen.append(theta.copy())
        grad = np.full(policy.n_params, 1.0 if len(seen) < 3 else 1e200)
        return float(len(seen)), grad, 1

    monkeypatch.setattr(policy_gradient, "_soft_return", huge_later)
    search = PolicyGradientSettings(horizon=20, particles=4, steps=10, holdout_particles=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        params, _ = search_policy(model, policy, start, STARTS, rng, search)
    assert len(seen) == 3  # the third gradient stopped the steps
    assert np.array_equal(params, start) or np.array_equal(params, seen[1])


def test_a_models_step_cost_is_its_basis_vectors_times_its_inputs() -> None:
    model = _ending_model(np.random.default_rng(7))
    basis = sum(gp.n_bv for gp in model.gps if gp is not None)
    assert basis > 0 and model.step_cost == basis * (3 + 1)


@pytest.mark.parametrize(("units", "evaluated"), [(None, 10), (3.0, 3), (2.5, 3), (0.0, 1)])
def test_the_adam_steps_stop_once_the_budget_is_spent(monkeypatch, units, evaluated) -> None:
    """Each return taken costs 5 particles' steps times the model's step cost: a budget of
    ``units`` of them (None: none) stops the steps at the return that spends it."""
    rng = np.random.default_rng(5)
    model = learned_model(rng, 20.0)
    policy = MLPFeedback(np.array([-20.0]), np.array([20.0]), np.zeros(2), np.ones(2), hidden=4)
    seen: list[np.ndarray] = []

    def counted(model, policy, theta, *rest):  # type: ignore[no-untyped-def]
        seen.append(theta.copy())
        return -float(len(seen)), np.ones(policy.n_params), 5

    monkeypatch.setattr(policy_gradient, "_soft_return", counted)
    budget = 1e300 if units is None else units * 5 * model.step_cost
    search = PolicyGradientSettings(horizon=20, particles=4, steps=10, holdout_particles=2,
                                    budget=budget)  # fmt: skip
    search_policy(model, policy, policy.initial(rng), STARTS, rng, search)
    assert len(seen) == evaluated


def test_bad_settings_and_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="holdout_particles"):
        PolicyGradientSettings(holdout_particles=1)
    with pytest.raises(ValueError, match="learning_rate"):
        PolicyGradientSettings(learning_rate=-1.0)
    with pytest.raises(ValueError, match="budget"):
        PolicyGradientSettings(budget=float("nan"))
    with pytest.raises(ValueError, match="branch_horizon"):
        PolicyGradientSettings(horizon=10, branch_horizon=11)
    with pytest.raises(ValueError, match="whole_steps"):
        PolicyGradientSettings(whole_steps=-1)
    with pytest.raises(ValueError, match="whole_particles"):
        PolicyGradientSettings(whole_particles=0)
    with pytest.raises(ValueError, match="high > low"):
        MLPFeedback(np.array([1.0]), np.array([1.0]), np.zeros(2), np.ones(2))
    with pytest.raises(ValueError, match="hidden"):
        MLPFeedback(np.array([0.0]), np.array([1.0]), np.zeros(2), np.ones(2), hidden=0)
    policy = MLPFeedback(np.array([0.0]), np.array([1.0]), np.zeros(2), np.ones(2), hidden=3)
    with pytest.raises(ValueError, match="params"):
        policy.act(np.zeros(3), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="params"):
        search_policy(learned_model(np.random.default_rng(0), 1.0), policy, np.zeros(3), STARTS,
                      np.random.default_rng(0))  # fmt: skip
    branched = PolicyGradientSettings(horizon=10, branch_horizon=5, steps=1)
    for bad, match in ((np.zeros((0, 2)), "at least one"), (np.zeros((3, 3)), "branch_from"),
                       (np.full((3, 2), np.nan), "branch_from")):  # fmt: skip
        with pytest.raises(ValueError, match=match):
            search_policy(learned_model(np.random.default_rng(0), 1.0), policy,
                          policy.initial(np.random.default_rng(0)), STARTS,
                          np.random.default_rng(0), branched, branch_from=bad)  # fmt: skip


def test_the_support_holdout_spacing_is_the_newest_states_distance_to_the_rest() -> None:
    rng = np.random.default_rng(7)
    S = np.cumsum(0.05 * rng.normal(size=(300, 2)), axis=0)  # one trajectory: steps are short
    A = rng.uniform(-1.0, 1.0, size=(300, 1))
    S2 = np.vstack([S[1:], S[-1:] + 0.05])
    fitted = {
        h: GPDynamicsModel(2, 1, ModelSettings(support_holdout=h)).fit(
            S, A, np.zeros(300), S2, np.zeros(300), np.random.default_rng(0)
        )
        for h in (0.0, 0.2)
    }
    support = fitted[0.2].support
    old, new = np.vstack([S[:240], S2[:240]]), np.vstack([S[240:], S2[240:]])
    gaps = np.sqrt(((new[:, None, :] - old[None, :, :]) ** 2 / support.scale**2).sum(-1)).min(1)
    assert support.spacing == pytest.approx(np.quantile(gaps, 0.99), rel=1e-12)
    assert support.spacing > 2.0 * fitted[0.0].support.spacing  # a trajectory's step is shorter
    np.testing.assert_allclose(support.distance(new), 0.0, atol=1e-12)  # the newest are seen
    arrays = fitted[0.2].to_arrays()
    assert GPDynamicsModel.from_arrays(arrays).settings == fitted[0.2].settings
    arrays["settings"] = arrays["settings"][:7]  # an archive from before the holdout
    assert GPDynamicsModel.from_arrays(arrays).settings.support_holdout == 0.0
