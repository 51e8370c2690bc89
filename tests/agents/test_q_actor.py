"""The actor trained on ``Q`` (:mod:`geoq.agents.q_actor`): its action gradient against
central differences of the GP's own predictions, its climb against a known maximiser,
and the agent with it (same seed, same curve; save and load continue identically)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from tests.agents._tasks import PointToGoalWithDistractors

from geoq._io import ArchiveError
from geoq.agents import GPQAgent, GPQConfig
from geoq.agents.q_actor import (
    QActor,
    central_gradient,
    closed_form_gradient,
    curves_inside,
    mean_action_gradient,
)
from geoq.gp import SparseOnlineGP
from geoq.kernels import SquaredExponential, make_kernel
from geoq.learners.scaling import InputScaling

LOW, HIGH = np.array([-2.0, -1.0]), np.array([2.0, 1.0])
SCALING = InputScaling((1.5, 0.7, 2.0, 1.0), (0.0,) * 4, ("s0", "s1", "a0", "a1"))


def _gp(rng: np.random.Generator, target, lengthscale=(0.8, 1.1, 0.6, 0.9)) -> SparseOnlineGP:  # type: ignore[no-untyped-def]
    """A GP of ``target(S, A)`` from 300 random pairs in ``[-1, 1]^2 x [LOW, HIGH]``, of
    scaled ``lengthscale`` [4]."""
    S, A = rng.uniform(-1, 1, (300, 2)), rng.uniform(LOW, HIGH, (300, 2))
    gp = SparseOnlineGP(SquaredExponential(lengthscale=list(lengthscale)), noise=1e-3,
                        max_bv=120)  # fmt: skip
    X = SCALING.transform(np.hstack([S, A]))
    y = target(S, A)
    return gp.fit(X, y).refit(X, y)


def _central(gp: SparseOnlineGP, S: np.ndarray, A: np.ndarray, h: float = 1e-5) -> np.ndarray:
    out = np.empty_like(A)
    for j in range(A.shape[1]):
        up, down = A.copy(), A.copy()
        up[:, j] += h
        down[:, j] -= h
        q_up = gp.predict(SCALING.transform(np.hstack([S, up])))
        q_down = gp.predict(SCALING.transform(np.hstack([S, down])))
        out[:, j] = (q_up - q_down) / (2 * h)
    return out


def test_the_closed_form_action_gradient_is_the_predictions_derivative() -> None:
    """Oracle: central differences of ``gp.predict`` in the raw actions (scaled inputs,
    ARD length-scales), to 1e-7 of the gradient's size; the actor's fallback (central
    differences of its own) agrees to its step's accuracy."""
    rng = np.random.default_rng(0)
    gp = _gp(rng, lambda S, A: np.sin(S[:, 0] + A[:, 0]) - (A[:, 1] - 0.3 * S[:, 1]) ** 2)
    assert not gp.features_repaired
    S, A = rng.uniform(-1, 1, (40, 2)), rng.uniform(LOW, HIGH, (40, 2))
    X = SCALING.transform(np.hstack([S, A]))
    closed = mean_action_gradient(gp, gp.alpha, X, 2, np.array([2.0, 1.0]))
    numeric = _central(gp, S, A)
    assert closed.shape == (40, 2)
    np.testing.assert_allclose(closed, numeric, atol=1e-7 * np.abs(numeric).max())
    np.testing.assert_allclose(closed_form_gradient(gp, SCALING, 2)(S, A), closed, rtol=1e-12)
    # the route for the graph kernels, at the actor's step (1e-3 of the box's widest side)
    np.testing.assert_allclose(central_gradient(gp, SCALING, 4e-3)(S, A), numeric, atol=1e-4)


def test_the_actor_climbs_to_q_s_maximiser() -> None:
    """Oracle: the argmax of ``gp.predict`` over a grid of actions (steps 0.02 and 0.01) at
    each of 50 fresh states; the actor is within 0.03 of it after 1,000 Adam steps. The GP
    learns ``Q = -(a0 - 0.5 s0)^2 - (a1 + 0.4 s1)^2``, whose maximiser is near."""
    rng = np.random.default_rng(1)
    gp = _gp(rng, lambda S, A: -((A[:, 0] - 0.5 * S[:, 0]) ** 2) - (A[:, 1] + 0.4 * S[:, 1]) ** 2)
    actor = QActor("on", LOW, HIGH)
    states = rng.uniform(-1, 1, (400, 2))
    for _ in range(20):
        actor.train(states, gp, SCALING, rng)
    S = rng.uniform(-0.9, 0.9, (50, 2))
    grid = np.stack(np.meshgrid(np.linspace(-1, 1, 101), np.linspace(-0.6, 0.6, 121)), -1)
    grid = grid.reshape(-1, 2)
    X = SCALING.transform(np.hstack([np.repeat(S, len(grid), 0), np.tile(grid, (len(S), 1))]))
    argmax = grid[gp.predict(X).reshape(len(S), -1).argmax(axis=1)]
    assert np.max(np.abs(actor.act(S) - argmax)) < 0.03
    truth = np.column_stack([0.5 * S[:, 0], -0.4 * S[:, 1]])
    assert np.max(np.abs(actor.act(S) - truth)) < 0.15
    a = actor.explore(S, 0.3, rng)
    assert np.all((a >= LOW) & (a <= HIGH)) and not np.allclose(a, actor.act(S))


def test_off_trains_nothing_and_saves_nothing() -> None:
    rng = np.random.default_rng(2)
    actor = QActor("off", LOW, HIGH)
    actor.train(rng.uniform(-1, 1, (50, 2)), _gp(rng, lambda S, A: -(A**2).sum(1)), SCALING, rng)
    assert not actor.ready and actor.to_arrays() == {}


def test_curved_acts_only_where_q_can_turn_inside_the_box() -> None:
    """The box's sides in scaled units are (4 / 2, 2 / 1) = (2, 2): action length-scales of
    at most 2 pass the gate. A curved actor is ``on``'s bit for bit where they do; where one
    does not, or they are not measured yet, it is idle: no draw from the generator, no
    training, not acting. Its flag is saved and restored with it."""
    width = HIGH - LOW
    target = lambda S, A: -((A - 0.3 * S) ** 2).sum(axis=1)  # noqa: E731
    rng = np.random.default_rng(4)
    turns, flat = _gp(rng, target, (0.8, 1.1, 2.0, 2.0)), _gp(rng, target, (0.8, 1.1, 2.0, 2.01))
    assert curves_inside(turns, SCALING, width) and not curves_inside(flat, SCALING, width)
    states = rng.uniform(-1, 1, (100, 2))
    curved, on = QActor("curved", LOW, HIGH), QActor("on", LOW, HIGH)
    before = np.random.default_rng(5).bit_generator.state
    draws = np.random.default_rng(5)
    curved.train(states, flat, SCALING, draws)
    assert not curved.ready and curved.to_arrays() == {} and draws.bit_generator.state == before
    curved.train(states, turns, SCALING, draws, measured=False)  # the rule's, before a fit
    assert not curved.ready and draws.bit_generator.state == before
    curved.train(states, turns, SCALING, np.random.default_rng(6))
    on.train(states, turns, SCALING, np.random.default_rng(6))
    assert curved.ready
    np.testing.assert_array_equal(curved.params, on.params)
    curved.train(states, flat, SCALING, draws)  # weights kept, idle
    assert not curved.ready and draws.bit_generator.state == before
    saved = curved.to_arrays()
    restored = QActor("curved", LOW, HIGH)
    restored.restore(saved, 2)
    assert not restored.ready
    np.testing.assert_array_equal(restored.params, curved.params)
    restored.restore({**saved, "active": np.bool_(True)}, 2)
    assert restored.ready
    with pytest.raises(ValueError, match="active flag"):
        restored.restore({**saved, "active": np.array([1.0, 0.0])}, 2)
    nearest = SparseOnlineGP(make_kernel("nearest"), noise=1e-2, max_bv=10)
    assert not curves_inside(nearest, SCALING, width)  # no length-scales to read


def test_auto_is_off_where_q_alone_learns_and_curved_elsewhere() -> None:
    assert GPQConfig().for_dims(3, 1).actor == "off"  # Pendulum-v1's inputs
    assert GPQConfig().for_dims(11, 3).actor == "curved"  # Hopper-v5's
    assert GPQConfig(actor="on").for_dims(3, 1).actor == "on"
    assert GPQConfig(actor="off").for_dims(11, 3).actor == "off"


def test_the_agent_with_an_actor_repeats_and_continues_identically(tmp_path: Path) -> None:
    """Same seed, same curve; saved mid-run and loaded, the rest of the run is the
    original's bit for bit (actor and GP); greedy actions are the actor's."""

    def run() -> GPQAgent:
        agent = GPQAgent("Pendulum-v1", seed=3, actor="on", explore_map="off", max_bv=60)
        return agent.learn(500)

    a, b = run(), run()
    assert a.actor.ready
    np.testing.assert_array_equal(a.actor.params, b.actor.params)
    np.testing.assert_array_equal(a.gp.alpha, b.gp.alpha)
    a.save(tmp_path / "a.npz")
    c = GPQAgent.load(tmp_path / "a.npz")
    a.learn(400)
    c.learn(400)
    np.testing.assert_array_equal(a.actor.params, c.actor.params)
    np.testing.assert_array_equal(a.gp.alpha, c.gp.alpha)
    obs = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, -2.0]])
    np.testing.assert_array_equal(c.predict(obs)[0], c.actor.act(obs))
    off = GPQAgent("Pendulum-v1", seed=3, explore_map="off", max_bv=60).learn(500)
    assert not np.array_equal(off.gp.alpha, b.gp.alpha)  # the actor's data, not Q's


def test_a_bad_actor_setting_or_archive_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="actor must be one of"):
        GPQConfig(actor="trial")  # type: ignore[arg-type]
    agent = GPQAgent("Pendulum-v1", seed=0, actor="on", explore_map="off", max_bv=60).learn(250)
    path = tmp_path / "a.npz"
    agent.save(path)
    with np.load(path) as f:
        arrays = dict(f)
    arrays["actor/params"] = arrays["actor/params"][:-1]
    np.savez(tmp_path / "short.npz", **arrays)
    with pytest.raises(ArchiveError, match="actor's weights"):
        GPQAgent.load(tmp_path / "short.npz")
    arrays["actor/params"] = np.zeros(len(arrays["actor/adam_m"]))
    arrays["actor/adam_v"] = -arrays["actor/adam_v"] - 1.0  # would be NaN weights, silently
    np.savez(tmp_path / "negative.npz", **arrays)
    with pytest.raises(ArchiveError, match="Adam state"):
        GPQAgent.load(tmp_path / "negative.npz")


def test_a_graph_kernel_agent_climbs_by_central_differences() -> None:
    """The geodesic kernels have no closed form here: the actor takes the central route."""
    agent = GPQAgent("Pendulum-v1", kernel="nearest", seed=0, actor="on", explore_map="off",
                     max_bv=40).learn(300)  # fmt: skip
    route = agent.actor._gradient(agent.gp, agent.scaling, agent.obs_dim)
    assert agent.actor.ready and route.__qualname__.startswith("central_gradient")
    se = GPQAgent("Pendulum-v1", seed=0, actor="on", explore_map="off", max_bv=40).learn(300)
    route = se.actor._gradient(se.gp, se.scaling, se.obs_dim)
    assert route.__qualname__.startswith("closed_form_gradient")


def test_files_from_before_the_actor_keep_acting_without_one(tmp_path: Path) -> None:
    """A file whose config has no ``actor`` (saved before it) loads with ``off``, where a new
    agent of its task resolves ``auto`` to ``curved``."""
    env = PointToGoalWithDistractors(extra=4)  # 5 + 1 inputs: the rule cannot cover them
    agent = GPQAgent(env, seed=0, max_bv=20).learn(40)
    assert agent.config.actor == "curved"
    agent.save(tmp_path / "agent.npz")
    with np.load(tmp_path / "agent.npz", allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files if not k.startswith("actor/")}
    meta = json.loads(str(arrays["meta"]))
    del meta["config"]["actor"]
    arrays["meta"] = np.asarray(json.dumps(meta))
    np.savez(tmp_path / "old.npz", **arrays)
    loaded = GPQAgent.load(tmp_path / "old.npz", env=PointToGoalWithDistractors(extra=4))
    assert loaded.config.actor == "off" and not loaded.actor.ready
