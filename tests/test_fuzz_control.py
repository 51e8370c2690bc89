"""Property-based fuzzing of the other public entry points (issue 12): the graph, the envs,
``collect_rollouts``, the learner and the agent.

The rule, as in ``tests/test_fuzz.py``: a call either raises a clear ``ValueError`` and
leaves the object as it was, or returns finite results that respect the object's own
contract (observations inside the observation space, actions inside the action box,
shortest paths symmetric with a zero diagonal).
"""

from __future__ import annotations

import warnings
from typing import Any

import gymnasium
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tests._fuzz import fuzz_settings

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent, GPQConfig
from geoq.gp import NumericalWarning
from geoq.graph import MDPGraph
from geoq.learners.q_gp import GPQFunction, QGPConfig
from geoq.policies import default_policy
from geoq.rollouts import collect_rollouts

FUZZ = fuzz_settings(60)
EXTREME = st.one_of(
    st.floats(-3, 3),
    st.sampled_from([0.0, 1e-300, 5e-324, 1e149, -1e151, 1e300, np.inf, -np.inf, np.nan]),
)


def _refused_or(
    call: Any, check: Any, refusals: tuple[type[Exception], ...] = (ValueError,)
) -> None:
    """Run ``call``; a refusal must say something, anything else must pass ``check``."""
    try:
        out = call()
    except refusals as exc:
        assert str(exc)
        return
    check(out)


@FUZZ
@given(points=st.lists(st.lists(EXTREME, min_size=2, max_size=2), min_size=1, max_size=8),
       removals=st.lists(st.integers(-2, 10), max_size=4))  # fmt: skip
def test_graph_stays_a_metric_or_refuses(points: list[list[float]], removals: list[int]) -> None:
    g = MDPGraph(eps=0.3, temporal_edges=True)
    for p in points:
        before = (g.n_nodes, g.version)
        _refused_or(lambda p=p: g.add_node(np.array(p)), lambda _: None)
        if g.n_nodes == before[0]:
            assert g.version == before[1], "a refused add changed the graph"
    for i in removals:
        n = g.n_nodes
        # An index out of range is an IndexError, as for a Python sequence.
        _refused_or(lambda i=i: g.remove_node(i), lambda _: None, (IndexError,))
        assert g.n_nodes in (n, n - 1)
    P = g.shortest_paths
    assert P.shape == (g.n_nodes, g.n_nodes)
    assert np.all(np.diag(P) == 0) and np.array_equal(P, P.T)
    assert not np.any(np.isnan(P)) and np.all(P >= 0)
    assert np.all(np.isfinite(g.nodes))


@FUZZ
@given(env_id=st.sampled_from(["geoq/PendulumSwingUp-v0", "geoq/TwoRooms-v0"]),
       actions=st.lists(st.lists(EXTREME, min_size=1, max_size=3), min_size=1, max_size=5),
       seed=st.integers(0, 2**31 - 1))  # fmt: skip
def test_envs_keep_observations_in_their_space(
    env_id: str, actions: list[list[float]], seed: int
) -> None:
    env = gymnasium.make(env_id)
    obs, _ = env.reset(seed=seed)
    assert env.observation_space.contains(obs)
    for a in actions:
        state = env.unwrapped.state.copy()  # type: ignore[attr-defined]

        def check(out: Any) -> None:
            o, r, *_ = out
            assert env.observation_space.contains(o) and np.isfinite(r)

        try:
            check(env.step(np.array(a)))
        except ValueError as exc:
            assert str(exc)
            assert np.array_equal(env.unwrapped.state, state), "a refused step moved the env"  # type: ignore[attr-defined]


@FUZZ
@given(n=st.one_of(st.integers(-1, 3), st.sampled_from([1.5, "2", None])),
       steps=st.one_of(st.integers(-1, 4), st.sampled_from([2.0, None])),
       gamma=st.one_of(st.floats(-0.5, 1.5), st.sampled_from([np.nan, np.inf])),
       torque=EXTREME)  # fmt: skip
def test_collect_rollouts_refuses_or_records_finite_clipped_data(
    n: Any, steps: Any, gamma: float, torque: float
) -> None:
    def policy(states: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return np.full(states.shape[0], torque)

    def check(rollouts: Any) -> None:
        for ro in rollouts:
            for arr in (ro.states, ro.actions, ro.rewards, ro.returns):
                assert np.all(np.isfinite(arr))
            assert np.all(np.abs(ro.actions) <= 5.0)  # the torque box

    try:
        check(collect_rollouts(n, steps, policy, np.random.default_rng(0), gamma=gamma))
    except (ValueError, TypeError) as exc:  # TypeError: a non-integer count, said clearly
        assert str(exc)


@pytest.fixture(scope="module")
def learner() -> GPQFunction:
    rollouts = collect_rollouts(2, 30, default_policy(), np.random.default_rng(1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        return GPQFunction(QGPConfig(max_bv=20)).fit(rollouts)


@FUZZ
@given(state=st.lists(EXTREME, min_size=2, max_size=2), action=EXTREME)
def test_learner_predicts_finite_values_or_refuses(
    learner: GPQFunction, state: list[float], action: float
) -> None:
    def check(out: Any) -> None:
        mean, std = out
        assert np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std >= 0)

    _refused_or(
        lambda: learner.predict(np.array([state]), np.array([action]), return_std=True), check
    )


@pytest.fixture(scope="module")
def agent() -> GPQAgent:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        return GPQAgent("geoq/TwoRooms-v0", max_bv=30, seed=0).learn(60)


@FUZZ
@given(obs=st.lists(EXTREME, min_size=1, max_size=4), deterministic=st.booleans())
def test_agent_acts_in_the_box_or_refuses(
    agent: GPQAgent, obs: list[float], deterministic: bool
) -> None:
    def check(out: Any) -> None:
        action, extra = out
        assert extra is None and action.shape == (2,)
        assert np.all(action >= agent.action_low) and np.all(action <= agent.action_high)

    _refused_or(lambda: agent.predict(np.array(obs), deterministic=deterministic), check)


@FUZZ
@given(field=st.sampled_from(["gamma", "beta", "max_bv", "replay_eps", "replay_budget",
                              "noise", "window", "warmup_steps"]),
       value=st.one_of(EXTREME, st.integers(-5, 5),
                       st.sampled_from(["1", None, True])))  # fmt: skip
def test_agent_config_refuses_bad_values_with_the_field_name(field: str, value: Any) -> None:
    try:
        GPQConfig.from_dict({field: value})
    except ValueError as exc:
        assert field in str(exc)
