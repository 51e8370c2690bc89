"""The actor's action gradient (``GPQConfig(actor="on")``): the squared exponential's
closed form against central differences, in the same process.

After every fitted-Q phase the actor takes :data:`~geoq.agents.q_actor.STEPS` Adam steps,
each asking ``Q``'s action gradient at :data:`~geoq.agents.q_actor.BATCH` stored states.
:func:`~geoq.agents.q_actor.closed_form_gradient` evaluates the kernel once per state
(after ``alpha``, O(m^3) once per phase); :func:`~geoq.agents.q_actor.central_gradient`,
the route for the graph kernels, predicts at ``2 d_a`` points per state. Sizes:
``InvertedDoublePendulum-v5`` (9 states, 1 action), ``Hopper-v5`` (11 + 3) and
``Walker2d-v5`` (17 + 6), each on a GP at the agent's budget of 800 basis vectors fitted
to 3,000 random pairs; the time is one phase's 50 gradients (the Adam steps' own cost
is the same for both and left out). The two agree to the central differences' accuracy.

Then a greedy ``predict`` (one state a call) of an agent whose actor acts, against the
same agent with its actor set idle (``Q``'s candidates act), in the same process:
``Pendulum-v1`` with ``actor="on"`` (no optional extra needed), rounds of 300 states.
"""

from __future__ import annotations

import time

import numpy as np

from geoq.agents import GPQAgent
from geoq.agents.q_actor import BATCH, STEPS, central_gradient, closed_form_gradient
from geoq.gp import SparseOnlineGP
from geoq.kernels import SquaredExponential
from geoq.learners.scaling import InputScaling

SIZES = (("9 states + 1 action", 9, 1), ("11 states + 3 actions", 11, 3),
         ("17 states + 6 actions", 17, 6))  # fmt: skip


def _case(d_s: int, d_a: int, n: int, max_bv: int):  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(0)
    d = d_s + d_a
    Z = np.hstack([rng.normal(size=(n, d_s)), rng.uniform(-1, 1, (n, d_a))])
    y = np.sin(Z @ rng.normal(size=d) / np.sqrt(d))
    gp = SparseOnlineGP(SquaredExponential(lengthscale=np.full(d, 1.5)), noise=0.01,
                        max_bv=max_bv)  # fmt: skip
    scaling = InputScaling((1.0,) * d, (0.0,) * d, tuple(f"x{i}" for i in range(d)))
    gp.fit(Z, y).refit(Z, y)
    return gp, scaling, Z[:BATCH, :d_s], Z[:BATCH, d_s:]


def _seconds(gradient, S: np.ndarray, A: np.ndarray, steps: int) -> float:  # type: ignore[no-untyped-def]
    start = time.perf_counter()
    for _ in range(steps):
        gradient(S, A)
    return time.perf_counter() - start


def _predict_ms(agent: GPQAgent, states: np.ndarray, active: bool) -> float:
    agent.actor.active = active
    start = time.perf_counter()
    for s in states:
        agent.predict(s, deterministic=True)
    return (time.perf_counter() - start) / len(states) * 1e3


def _predict(quick: bool) -> None:
    steps, n, rounds = (150, 20, 1) if quick else (1000, 300, 3)
    agent = GPQAgent("Pendulum-v1", seed=0, actor="on", explore_map="off").learn(steps)
    assert agent.actor.ready
    rng = np.random.default_rng(0)
    theta, speed = rng.uniform(-np.pi, np.pi, n), rng.uniform(-8, 8, n)
    states = np.column_stack([np.cos(theta), np.sin(theta), speed])
    print(f"greedy predict, one state a call, after {steps} steps ({agent.gp.n_bv} BVs)")
    print(f"{'round':<8}{'actor ms':>10}{'candidates ms':>15}{'ratio':>8}")
    for k in range(rounds):
        actor, candidates = _predict_ms(agent, states, True), _predict_ms(agent, states, False)
        print(f"{k:<8}{actor:>10.2f}{candidates:>15.2f}{actor / candidates:>8.2f}")


def main(quick: bool = False) -> None:
    n, max_bv, steps = (300, 60, 2) if quick else (3000, 800, STEPS)
    print(f"one phase's {steps} action gradients at {BATCH} states, {max_bv} basis vectors")
    print(f"{'size':<24}{'closed form s':>15}{'central s':>12}{'ratio':>8}{'max rel. diff':>15}")
    for label, d_s, d_a in SIZES:
        gp, scaling, S, A = _case(d_s, d_a, n, max_bv)
        start = time.perf_counter()
        closed = closed_form_gradient(gp, scaling, d_s)  # alpha: once per phase
        t_closed = time.perf_counter() - start + _seconds(closed, S, A, steps)
        central = central_gradient(gp, scaling, 2e-3)
        t_central = _seconds(central, S, A, steps)
        g, h = closed(S, A), central(S, A)
        diff = float(np.max(np.abs(g - h)) / np.max(np.abs(g)))
        print(f"{label:<24}{t_closed:>15.3f}{t_central:>12.3f}{t_central / t_closed:>8.1f}"
              f"{diff:>15.1e}")  # fmt: skip
    _predict(quick)


if __name__ == "__main__":
    main()
