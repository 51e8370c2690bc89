"""Replay along the graph: the imagined transitions against a brute-force oracle; the
agent's replay modes against a task whose optimal Q is known in closed form."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.agents._tasks import PointToGoal

from geoq.agents import GPQAgent
from geoq.agents.buffer import Transitions
from geoq.agents.graph_replay import GraphModel, imagine_transitions, link_radius


def _brute_force(S, A, R, S2, term, state, action, *, units, periods, eps, max_links, ridge=0.1):
    """One imagined transition by a loop over every stored node (no tree, no batching)."""
    radius = link_radius(eps)
    x = np.concatenate([state, action])
    found = []
    for j in range(len(R)):
        diff = x - np.concatenate([S[j], A[j]])
        for k, p in enumerate(periods):
            if p > 0:
                diff[k] = (diff[k] + p / 2) % p - p / 2
        d = float(np.sqrt(np.sum((diff / units) ** 2)))
        if d <= radius:
            found.append((d, j))
    found = sorted(found)[:max_links]
    if not found:
        return None
    w = np.array([np.exp(-0.5 * d * d) for d, _ in found])
    w /= w.sum()
    # Local-linear ridge fit as one least-squares problem: sqrt(w)-scaled rows plus
    # sqrt(ridge) rows on the slopes; the intercept is the prediction.
    rows, rhs = [], []
    for wi, (_, j) in zip(w, found, strict=True):
        off = np.concatenate([S[j], A[j]]) - x
        ds = S2[j] - S[j]
        for k, p in enumerate(periods):
            if p > 0:
                off[k] = (off[k] + p / 2) % p - p / 2
                if k < S.shape[1]:
                    ds[k] = (ds[k] + p / 2) % p - p / 2
        rows.append(np.sqrt(wi) * np.concatenate([[1.0], off / units]))
        rhs.append(np.sqrt(wi) * np.concatenate([ds, [R[j], float(term[j])]]))
    d = len(x)
    for k in range(d):
        e = np.zeros(d + 1)
        e[k + 1] = np.sqrt(ridge)
        rows.append(e)
        rhs.append(np.zeros(S.shape[1] + 2))
    beta = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0]
    pred = beta[0]
    nxt = state + pred[: S.shape[1]]
    for k, p in enumerate(periods[: S.shape[1]]):
        if p > 0:
            nxt[k] = (nxt[k] + p / 2) % p - p / 2
    r = float(np.clip(pred[S.shape[1]], R.min(), R.max()))
    return nxt, r, pred[S.shape[1] + 1] > 0.5, len(found)


@settings(max_examples=25, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**31 - 1), periodic=st.booleans(), n=st.integers(1, 40))
def test_imagined_transitions_match_a_brute_force_graph(seed: int, periodic: bool, n: int) -> None:
    rng = np.random.default_rng(seed)
    period = 2 * np.pi
    S = np.column_stack([rng.uniform(-np.pi, np.pi, n), rng.uniform(-2, 2, n)])
    A = rng.uniform(-1, 1, (n, 1))
    S2 = S + rng.normal(0, 0.2, (n, 2))
    if periodic:
        S2[:, 0] = (S2[:, 0] + np.pi) % period - np.pi
    R = rng.normal(size=n)
    term = rng.random(n) < 0.3
    periods = np.array([period if periodic else 0.0, 0.0, 0.0])
    units = np.array([0.8, 0.7, 0.9])
    candidates = np.linspace(-1, 1, 5)[:, None]
    priority = rng.random(n)
    model = GraphModel(units=units, periods=periods, eps=0.4, max_links=4)
    im = imagine_transitions(Transitions(S, A, R, S2, term), model, candidates, priority, 10 * n)
    # Every source state is paired with the candidates other than the one nearest its action.
    expected_pairs = set()
    for i in range(n):
        nearest = int(np.argmin(np.abs(candidates[:, 0] - A[i, 0])))
        for k in range(5):
            if k != nearest:
                expected_pairs.add((i, k))
    oracle = {}
    for i, k in expected_pairs:
        got = _brute_force(
            S, A, R, S2, term, S[i], candidates[k], units=units, periods=periods, eps=0.4,
            max_links=4,
        )  # fmt: skip
        if got is not None:
            oracle[(tuple(S[i]), float(candidates[k, 0]))] = got
    assert len(im) == len(oracle)
    for row in range(len(im)):
        nxt, r, t, links = oracle[(tuple(im.states[row]), float(im.actions[row, 0]))]
        np.testing.assert_allclose(im.next_states[row], nxt, rtol=1e-10, atol=1e-10)
        assert im.rewards[row] == pytest.approx(r, rel=1e-10, abs=1e-12)
        assert bool(im.terminated[row]) == t
        assert im.n_linked[row] == links


def test_budget_takes_the_highest_priority_sources_first() -> None:
    S = np.linspace(0, 1, 20)[:, None]
    A = np.zeros((20, 1))
    R = -np.ones(20)
    S2 = S + 0.01
    priority = np.zeros(20)
    priority[[3, 11]] = [2.0, 1.0]
    candidates = np.array([[-1.0], [0.0], [1.0]])
    stored = Transitions(S, A, R, S2, np.zeros(20, dtype=bool))
    model = GraphModel(units=np.array([0.2, 1.0]), periods=np.zeros(2), eps=0.3)
    im = imagine_transitions(stored, model, candidates, priority, budget=4)
    assert len(im) == 4
    np.testing.assert_array_equal(im.states[:, 0], S[[3, 3, 11, 11], 0])
    np.testing.assert_array_equal(im.actions[:, 0], [-1.0, 1.0, -1.0, 1.0])  # 0 was taken
    assert len(imagine_transitions(stored, model, candidates, priority, budget=0)) == 0
    with pytest.raises(ValueError, match="eps"):
        link_radius(1.0)


def _optimal_q(x: float, a: float, gamma: float) -> float:
    """Q* of :class:`PointToGoal` by value iteration along the chain of full-speed steps."""
    x2 = float(np.clip(x + 0.1 * a, -1.0, 1.0))
    if abs(x2 - PointToGoal.GOAL) < 0.1:
        return -1.0
    if x2 > PointToGoal.GOAL:  # past the goal: come back at full speed
        n = int(np.ceil((x2 - 0.9) / 0.1 - 1e-12)) + 1
    else:
        n = int(np.floor((0.7 - x2) / 0.1 + 1e-12)) + 1
    return -1.0 - gamma * (1.0 - gamma**n) / (1.0 - gamma)


@pytest.mark.parametrize("replay", ["uniform", "graph"])
def test_replay_converges_to_the_optimal_values_of_a_known_task(replay: str) -> None:
    agent = GPQAgent(
        PointToGoal(),
        seed=0,
        gamma=0.9,
        max_bv=60,
        replay=replay,  # type: ignore[arg-type]
        # the GP's own exploration: under the map's, the GP never tries most candidates at a
        # state, and its max over them keeps their optimistic prior (the map acts there)
        explore_map="off",
    ).learn(400)
    xs = np.linspace(-0.9, 0.4, 14)
    mean, _ = agent.q_candidates(xs[:, None])
    best = agent.candidates[:, 0] == 1.0
    q_star = np.array([_optimal_q(x, 1.0, 0.9) for x in xs])
    err = np.abs(mean[:, best][:, 0] - q_star)
    # The optimal values run from -1 to -6.1: the GP follows the staircase within a step.
    assert np.max(err) < 0.6, err
    assert np.mean(err) < 0.25, err
    if replay == "graph":
        assert agent.log.imagined_counts and max(agent.log.imagined_counts) > 0


def test_graph_replay_is_reproducible_and_never_moves_predict_without_learn() -> None:
    a = GPQAgent(PointToGoal(), seed=5, gamma=0.9, max_bv=40, replay="graph").learn(150)  # type: ignore[arg-type]
    b = GPQAgent(PointToGoal(), seed=5, gamma=0.9, max_bv=40, replay="graph").learn(150)  # type: ignore[arg-type]
    obs = np.linspace(-1, 1, 9)[:, None]
    first = a.predict(obs)[0]
    np.testing.assert_array_equal(first, b.predict(obs)[0])
    np.testing.assert_array_equal(a.buffer.targets(), b.buffer.targets())
    assert np.all(np.isfinite(a.buffer.targets()))
    np.testing.assert_array_equal(a.predict(obs)[0], first)


@pytest.mark.parametrize("kernel", ["nearest", "interpolated", "resistance"])
def test_graph_replay_runs_with_the_graph_kernels(kernel: str) -> None:
    agent = GPQAgent(
        PointToGoal(),
        kernel=kernel,
        seed=1,
        gamma=0.9,
        max_bv=20,
        replay="graph",  # type: ignore[arg-type]
    ).learn(80)
    assert max(agent.log.imagined_counts) > 0
    assert np.all(np.isfinite(agent.buffer.targets()))
    actions, _ = agent.predict(np.linspace(-1, 1, 5)[:, None])
    assert np.all(np.abs(actions) <= 1.0)
