"""The dynamics model's prediction, against each output's GP asked in turn.

A planner asks the model about ``P`` particles at every model step of every plan:
``GPDynamicsModel.predict_mean`` (one compiled loop over every output's basis) and,
with the std, ``GPDynamicsModel.predict``; a sampled roll-out's step,
``GPDynamicsModel.draw``, asks only the state changes for their std. The baseline, in
the same process, asks each output's :class:`~geoq.gp.SparseOnlineGP` in turn, without
and with the std (every output's, for ``draw`` too). Sizes:
InvertedPendulum's (4 states, 1 action: 6 outputs) and Reacher's (10 + 2: 12), on
2,000 transitions of smooth random dynamics, 200 basis vectors per output, 64
particles (the planner's default samples).

Second table: a policy search's scoring (:func:`~geoq.models.policy_returns`, 32
candidate gains x 16 particles over 200 model steps, random gains of which some end
their roll-outs early), stepping only the particles still running, against stepping
every particle to the horizon (the roll-out before it learned to skip, in the same
process; the returns agree to 1e-9).

Third table: the network policy's search (:func:`~geoq.models.soft_return`, a 32-unit
:class:`~geoq.models.MLPFeedback`, 16 particles over 50 model steps): the return with
its gradient by the reverse pass, against the return alone by the exact roll-out
(:func:`~geoq.models.rollout_returns`, means); central finite differences would take
two roll-outs per weight.

Fourth table: the same smooth return with ends (16 particles over 200 model steps,
weights of which some end their roll-outs early), stepping only the roll-outs still
running, against stepping every one to the horizon (the reverse pass before it
learned to skip, in the same process; values and gradients agree to 1e-9).

Fifth table: what a search's budget (``PolicyGradientSettings.budget``) buys at three
task sizes, each output at its full 200 basis vectors and every roll-out running the
whole horizon (the costliest search of that size): the model's
:attr:`~geoq.models.GPDynamicsModel.step_cost`, the seconds per unit of it of one
timed :func:`~geoq.models.soft_return` (16 particles), the Adam steps the budget
allows (at most the default 100), and the Adam steps' seconds under the budget against
those of 100 steps (both from the one timed return: the 100 steps of the largest size
take minutes).
"""

from __future__ import annotations

import time

import numpy as np

from geoq.models import (
    GPDynamicsModel,
    LinearFeedback,
    MLPFeedback,
    ModelSettings,
    PolicyGradientSettings,
    policy_returns,
    rollout_returns,
    soft_return,
)

#: The tables' task sizes: InvertedPendulum's and Reacher's.
SIZES = (("4 states + 1 action", 4, 1), ("10 states + 2 actions", 10, 2))


def _net_case(model: GPDynamicsModel, seed: int, spread: float, horizon: int):  # type: ignore[no-untyped-def]
    """A network policy for ``model``, weights ``spread`` away from its first ones, 16
    starts and the means' zero normals over ``horizon`` steps."""
    d_s, d_a = model.obs_dim, model.action_dim
    rng = np.random.default_rng(seed)
    policy = MLPFeedback(-np.ones(d_a), np.ones(d_a), model.x_mean[:d_s], model.x_scale[:d_s])
    params = policy.initial(rng) + spread * rng.normal(size=policy.n_params)
    return policy, params, rng.normal(size=(16, d_s)), np.zeros((horizon, 16, d_s))


def _model(d_s: int, d_a: int, n: int, max_bv: int, ends: bool = True) -> GPDynamicsModel:
    rng = np.random.default_rng(0)
    S, A = rng.normal(size=(n, d_s)), rng.uniform(-1.0, 1.0, size=(n, d_a))
    S2 = S + 0.1 * np.sin(S @ rng.normal(size=(d_s, d_s))) + 0.1 * A @ rng.normal(size=(d_a, d_s))
    R, T = -np.sum(S**2, axis=1), (np.abs(S[:, 0]) > 2.0) * float(ends)
    return GPDynamicsModel(d_s, d_a, ModelSettings(max_bv=max_bv)).fit(S, A, R, S2, T, rng)


def _seconds(fn, repeats: int) -> float:  # type: ignore[no-untyped-def]
    fn()
    start = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - start) / repeats


def main(quick: bool = False) -> None:
    n, max_bv, particles, repeats = (200, 30, 16, 3) if quick else (2000, 200, 64, 50)
    print(f"{'task sizes':<22} {'what':<11} {'model':>9} {'per output':>11} {'ratio':>7}")
    for name, d_s, d_a in SIZES:
        model = _model(d_s, d_a, n, max_bv)
        rng = np.random.default_rng(1)
        S, A = rng.normal(size=(particles, d_s)), rng.uniform(-1, 1, size=(particles, d_a))
        X = (np.hstack([S, A]) - model.x_mean) / model.x_scale
        calls = {
            "means": lambda: model.predict_mean(S, A),  # noqa: B023
            "means, std": lambda: model.predict(S, A),  # noqa: B023
            "draw": lambda: model.draw(S, A, rng),  # noqa: B023
        }
        for what, call in calls.items():
            std = what != "means"
            ours = _seconds(call, repeats)
            each = _seconds(
                lambda: [gp.predict(X, return_std=std) for gp in model.gps if gp is not None],  # noqa: B023
                repeats,
            )
            print(f"{name:<22} {what:<11} {1e3 * ours:>7.2f}ms {1e3 * each:>9.2f}ms "
                  f"{each / ours:>6.1f}x")  # fmt: skip
    search_scoring(quick)
    gradient_cost(quick)
    gradient_running_only(quick)
    search_budget(quick)


def _every_particle(model, policy, gains, starts, normals):  # type: ignore[no-untyped-def]
    """The baseline: every particle stepped to the horizon, ended or not."""
    C, P, d = gains.shape[0], starts.shape[0], model.obs_dim
    S, rows = np.tile(starts, (C, 1)), np.arange(C * P)
    alive, total = np.ones(C * P), np.zeros(C * P)
    for t in range(normals.shape[0]):
        mean, S = model.draw(S, policy.act_rows(gains[rows // P], S), np.tile(normals[t], (C, 1)))
        ends = mean[:, d + 1] > 0.5
        unknown = np.where(ends, 0.0, np.clip(model.support.distance(S) - 1.0, 0.0, 1.0))
        rest = (normals.shape[0] - t - 1) * float(model.reward_range[0])
        total += alive * (mean[:, d] + unknown * rest)
        alive = alive * ~ends * (1.0 - unknown)
    return total.reshape(C, P)


def search_scoring(quick: bool = False) -> None:
    """The second table (module docstring)."""
    n, max_bv, horizon, repeats = (200, 30, 20, 1) if quick else (2000, 200, 200, 3)
    print(f"\n{'task sizes':<22} {'running only':>13} {'every particle':>15} {'ratio':>7}")
    for name, d_s, d_a in SIZES:
        model = _model(d_s, d_a, n, max_bv)
        rng = np.random.default_rng(2)
        policy = LinearFeedback(
            -np.ones(d_a), np.ones(d_a), model.x_mean[:d_s], model.x_scale[:d_s]
        )
        gains = rng.normal(size=(32, *policy.shape))
        starts, normals = rng.normal(size=(16, d_s)), rng.standard_normal((horizon, 16, d_s))
        ours = policy_returns(model, policy, gains, starts, normals)
        np.testing.assert_allclose(ours, _every_particle(model, policy, gains, starts, normals),
                                   rtol=1e-9, atol=1e-9)  # fmt: skip
        fast = _seconds(lambda: policy_returns(model, policy, gains, starts, normals), repeats)  # noqa: B023
        slow = _seconds(lambda: _every_particle(model, policy, gains, starts, normals), repeats)  # noqa: B023
        print(f"{name:<22} {fast:>12.2f}s {slow:>14.2f}s {slow / fast:>6.1f}x")


def gradient_cost(quick: bool = False) -> None:
    """The third table (module docstring)."""
    n, max_bv, horizon, repeats = (200, 30, 10, 1) if quick else (2000, 200, 50, 10)
    print(f"\n{'task sizes':<22} {'weights':>8} {'gradient':>10} {'roll-out':>10} {'ratio':>7}")
    for name, d_s, d_a in SIZES:
        model = _model(d_s, d_a, n, max_bv, ends=False)
        model.support.spacing = 1e9  # no end and no halt: the two agree (to rounding)
        policy, params, starts, normals = _net_case(model, 3, 0.3, horizon)

        def exact() -> np.ndarray:
            return rollout_returns(model, starts, lambda t, S, rows: policy.act(params, S),  # noqa: B023
                                   horizon, gamma=1.0, noise=None)  # fmt: skip

        value, _ = soft_return(model, policy, params, starts, normals)
        np.testing.assert_allclose(value, exact().mean(), rtol=1e-9)
        grad = _seconds(lambda: soft_return(model, policy, params, starts, normals), repeats)  # noqa: B023
        plain = _seconds(exact, repeats)
        print(f"{name:<22} {policy.n_params:>8} {1e3 * grad:>8.1f}ms {1e3 * plain:>8.1f}ms "
              f"{grad / plain:>6.1f}x")  # fmt: skip


def _soft_every_particle(model, policy, params, starts, T):  # type: ignore[no-untyped-def]
    """The baseline of the fourth table: :func:`~geoq.models.soft_return` of the means'
    roll-outs with every roll-out stepped to the horizon ``T``, ended or not."""
    (P, d), r_least = starts.shape, float(model.reward_range[0])
    S, w, total, tape = starts.copy(), np.ones(P), np.zeros(P), []
    for t in range(T):
        A, cache = policy.forward(params, S)
        mean, jac = model.mean_gradients(S, A)
        S = S + mean[:, :d]
        end = np.clip(mean[:, d + 1], 0.0, 1.0)
        dist, dist_grad = model.support.distance_gradient(S)
        halt, rest = np.clip(dist - 1.0, 0.0, 1.0), (T - 1 - t) * r_least
        reward = mean[:, d] + (1.0 - end) * halt * rest
        total += w * reward
        live = ((mean[:, d + 1] > 0) & (mean[:, d + 1] < 1), (dist > 1) & (dist < 2))
        tape.append((cache, jac, w, reward, end, halt, rest, dist_grad, *live))
        w = w * (1.0 - end) * (1.0 - halt)
    grad, g_next, gw_next = np.zeros(policy.n_params), np.zeros((P, d)), np.zeros(P)
    for cache, jac, w, reward, end, halt, rest, dist_grad, end_live, halt_live in reversed(tape):
        g_end = -w * halt * rest - gw_next * w * (1.0 - halt)
        g_halt = w * (1.0 - end) * rest - gw_next * w * (1.0 - end)
        g_state = g_next + (g_halt * halt_live)[:, None] * dist_grad
        g_mean = np.zeros(jac.shape[:2])
        g_mean[:, :d], g_mean[:, d], g_mean[:, d + 1] = g_state, w, g_end * end_live
        g_input = np.einsum("pj,pjk->pk", g_mean, jac)
        g_params, g_policy_state = policy.backward(params, cache, g_input[:, d:])
        grad += g_params
        g_next = g_state + g_input[:, :d] + g_policy_state
        gw_next = reward + gw_next * (1.0 - end) * (1.0 - halt)
    return float(total.mean()), grad / P


def gradient_running_only(quick: bool = False) -> None:
    """The fourth table (module docstring)."""
    n, max_bv, horizon, repeats = (200, 30, 20, 1) if quick else (2000, 200, 200, 3)
    print(f"\n{'task sizes':<22} {'running only':>13} {'every roll-out':>15} {'ratio':>7}")
    for name, d_s, d_a in SIZES:
        model = _model(d_s, d_a, n, max_bv)
        policy, params, starts, normals = _net_case(model, 4, 1.0, horizon)
        value, grad = soft_return(model, policy, params, starts, normals)
        base_value, base_grad = _soft_every_particle(model, policy, params, starts, horizon)
        np.testing.assert_allclose(value, base_value, rtol=1e-9)
        np.testing.assert_allclose(grad, base_grad, rtol=1e-9, atol=1e-9 * np.abs(base_grad).max())
        args = (model, policy, params, starts)
        fast = _seconds(lambda: soft_return(*args, normals), repeats)  # noqa: B023
        slow = _seconds(lambda: _soft_every_particle(*args, horizon), repeats)  # noqa: B023
        print(f"{name:<22} {1e3 * fast:>11.1f}ms {1e3 * slow:>13.1f}ms {slow / fast:>6.1f}x")


#: The fifth table's sizes: InvertedPendulum's, Reacher's and HalfCheetah's, with their
#: search horizons (the task's time limit, at most 1,000 steps).
BUDGET_SIZES = (("4 + 1, 1,000 steps", 4, 1, 1000), ("10 + 2, 50 steps", 10, 2, 50),
                ("17 + 6, 1,000 steps", 17, 6, 1000))  # fmt: skip


def search_budget(quick: bool = False) -> None:
    """The fifth table (module docstring)."""
    n, max_bv, scale = (200, 30, 20) if quick else (2000, 200, 1)
    budget, steps = PolicyGradientSettings().budget, PolicyGradientSettings().steps
    print(f"\n{'task sizes':<22} {'step cost':>10} {'ns a unit':>10} {'Adam steps':>11} "
          f"{'budgeted':>9} {'100 steps':>10} {'ratio':>7}")  # fmt: skip
    for name, d_s, d_a, horizon in BUDGET_SIZES:
        horizon //= scale
        model = _model(d_s, d_a, n, max_bv, ends=False)
        model.support.spacing = 1e9  # no halt: every roll-out runs the whole horizon
        policy, params, starts, normals = _net_case(model, 5, 0.3, horizon)
        one = _seconds(lambda: soft_return(model, policy, params, starts, normals), 1)  # noqa: B023
        work = 16 * horizon * model.step_cost  # one return's units
        allowed = min(steps, int(np.ceil(budget / work)))
        print(f"{name:<22} {model.step_cost:>10,} {1e9 * one / work:>10.2f} {allowed:>11} "
              f"{allowed * one:>8.1f}s {steps * one:>9.1f}s {steps / allowed:>6.1f}x")  # fmt: skip


if __name__ == "__main__":
    main()
