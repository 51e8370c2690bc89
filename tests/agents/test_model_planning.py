"""The agent with a learned dynamics model and a planner (``planner="cem"``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from geoq._io import ArchiveError
from geoq.agents import GPQAgent

from ._tasks import PointToGoal

SETTINGS = {"planner": "cem", "warmup_steps": 40, "n_candidates": 5}


def _agent(seed: int = 0, **extra: object) -> GPQAgent:
    return GPQAgent(PointToGoal(), seed=seed, **{**SETTINGS, **extra})


def _steps_to_goal(agent: GPQAgent, start: float) -> int:
    env = PointToGoal()
    obs, _ = env.reset(seed=0, options={"state": [start]})
    for t in range(1, 41):
        obs, _, terminated, _, _ = env.step(agent.predict(obs)[0])
        if terminated:
            return t
    return 41


def test_the_model_is_fitted_at_the_warm_up_and_then_takes_each_step() -> None:
    agent = _agent().learn(39)
    assert not agent.planning.model.fitted and not agent.planning.active
    agent.learn(21)
    model = agent.planning.model
    assert agent.planning.active and model.n_seen == 60
    assert agent.planning.next_fit == 80
    agent.learn(30)
    assert model.n_seen == 80 + 10 and agent.planning.next_fit == 160  # refitted at 80


def test_planning_learns_the_point_task_and_acts_in_the_box() -> None:
    agent = _agent().learn(300)
    for start in (-1.0, -0.5, 0.0):
        # the optimum is 1 + ceil((0.7 - start) / 0.1) steps at a = 1; allow 3 more
        assert _steps_to_goal(agent, start) <= int(np.ceil((0.7 - start) / 0.1)) + 4
    actions = agent.buffer.arrays()[1]
    assert np.all(actions >= -1.0) and np.all(actions <= 1.0)


@pytest.mark.parametrize("planner", ["cem", "cem-q"])
def test_the_same_seed_learns_the_same_steps(planner: str) -> None:
    a, b = _agent(3, planner=planner).learn(120), _agent(3, planner=planner).learn(120)
    assert all(np.array_equal(x, y) for x, y in zip(a.buffer.arrays(), b.buffer.arrays(),
                                                    strict=True))  # fmt: skip


def test_a_greedy_plan_draws_nothing_from_the_learning() -> None:
    a, b = _agent(4).learn(80), _agent(4).learn(80)
    state = a.rng.bit_generator.state
    for x in np.linspace(-1.0, 0.6, 5):
        a.predict(np.array([x]))
    assert a.rng.bit_generator.state == state
    a.learn(40)
    b.learn(40)
    assert np.array_equal(a.buffer.arrays()[1], b.buffer.arrays()[1])


def test_save_and_load_continue_identically_model_included(tmp_path) -> None:
    agent = _agent(5).learn(90)
    for x in (-0.4, 0.1):
        agent.predict(np.array([x]))  # a greedy warm start, saved with the plans
    agent.save(tmp_path / "a.npz")
    loaded = GPQAgent.load(tmp_path / "a.npz", env=PointToGoal())
    assert loaded.planning.model.n_seen == agent.planning.model.n_seen
    for ours, theirs in ((agent.planning.greedy, loaded.planning.greedy),
                         (agent.planning.training, loaded.planning.training)):  # fmt: skip
        for field in ("mean", "elites"):
            a, b = getattr(ours, field), getattr(theirs, field)
            assert (a is None and b is None) or np.array_equal(a, b), field
    assert loaded.planning.greedy.elites is not None
    obs = np.array([-0.3])
    assert np.array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])
    agent.learn(50)
    loaded.learn(50)
    for x, y in zip(agent.buffer.arrays(), loaded.buffer.arrays(), strict=True):
        assert np.array_equal(x, y)


def test_a_stored_model_must_match_the_config(tmp_path) -> None:
    agent = _agent(6).learn(60)
    agent.save(tmp_path / "a.npz")
    with np.load(tmp_path / "a.npz", allow_pickle=False) as f:
        arrays = dict(f)
    off = {k: v for k, v in arrays.items()}
    meta = str(off["meta"]).replace('"planner": "cem"', '"planner": "off"')
    off["meta"] = np.asarray(meta)
    np.savez(tmp_path / "off.npz", **off)
    with pytest.raises(ArchiveError, match="planner"):
        GPQAgent.load(tmp_path / "off.npz", env=PointToGoal())
    damaged = [("model/next_fit", np.array(10), "next_fit"),
               ("model/elites_training", np.zeros((8, 3, 1)), "elites_training"),
               ("model/plan_greedy", np.full((11, 1), 2.0), "plan_greedy")]  # fmt: skip
    for key, bad, match in damaged:
        np.savez(tmp_path / "bad.npz", **(arrays | {key: bad}))
        with pytest.raises(ArchiveError, match=match):
            GPQAgent.load(tmp_path / "bad.npz", env=PointToGoal())


def test_without_a_planner_nothing_is_modelled(tmp_path) -> None:
    agent = GPQAgent(PointToGoal(), seed=0, warmup_steps=40).learn(60)
    assert agent.config.planner == "off" and not agent.planning.model.fitted
    agent.save(tmp_path / "a.npz")
    with np.load(tmp_path / "a.npz", allow_pickle=False) as f:
        assert not any(k.startswith("model/") for k in f.files)


def test_an_unknown_planner_is_refused() -> None:
    with pytest.raises(ValueError, match="planner"):
        GPQAgent(PointToGoal(), planner="mpc")


# ---------------------------------------------------------------- planner="policy"
POLICY = {"planner": "policy", "warmup_steps": 40, "n_candidates": 5, "explore_map": "off",
          "policy_horizon": 40}  # fmt: skip


POLICY_PLANNERS = pytest.mark.parametrize("planner", ["policy", "policy-net"])


def _policy_agent(seed: int = 0, planner: str = "policy") -> GPQAgent:
    return GPQAgent(PointToGoal(), seed=seed, **(POLICY | {"planner": planner}))


def _enough_steps(agent: GPQAgent) -> GPQAgent:
    """``policy-net``'s searches given 200 Adam steps: its default of one per horizon step
    (40 here) finds no weights that reach the point's goal by 239 steps, so ``Q`` keeps
    acting (docs/design-notes.md, part fourteen); these tests are of the loop around it."""
    feedback = agent.planning.feedback
    feedback.gradient_settings = replace(feedback.gradient_settings, steps=200)
    return agent


@POLICY_PLANNERS
def test_a_policy_is_searched_at_episode_starts_once_the_warm_up_is_over(planner: str) -> None:
    agent = _policy_agent(planner=planner)
    assert GPQAgent(PointToGoal(), planner="policy").config.policy_horizon == 1000  # no limit
    assert GPQAgent("Pendulum-v1", planner="policy").config.policy_horizon == 200
    assert GPQAgent("Pendulum-v1", planner="policy", policy_horizon=7).config.policy_horizon == 7
    agent.learn(39)
    assert not agent.planning.active and not agent.planning.model.fitted
    agent = _enough_steps(_policy_agent(planner=planner)).learn(239)
    feedback = agent.planning.feedback
    starts = len(agent.episodes) + 1  # the unfinished episode's start too
    assert agent.planning.active and len(feedback.starts) == starts
    assert 40 <= feedback.searched_at <= 239 and np.isfinite(feedback.value)
    # a greedy action is the policy's, with nothing drawn
    state, obs = agent.rng.bit_generator.state, np.array([-0.2])
    expected = feedback.policy.act(feedback.gains, obs[None])[0]
    np.testing.assert_array_equal(agent.predict(obs)[0], expected)
    assert agent.rng.bit_generator.state == state


def test_a_greedy_action_is_the_policys_while_q_on_trial_trails_it() -> None:
    """``Q`` on trial against the policy's weights: greedy actions are ``Q``'s until its
    fresh returns so far have a mean below the policy's, then the policy's."""
    agent = _policy_agent(planner="policy-net").learn(239)
    feedback, obs = agent.planning.feedback, np.array([-0.2])
    feedback.acting = False  # Q acts, as it would after a search that kept it
    q_greedy = agent.predict(obs)[0]
    incumbent = feedback.gains + 0.5
    policy_greedy = feedback.policy.act(incumbent, obs[None])[0]
    assert not np.array_equal(q_greedy, policy_greedy)
    feedback.kept = (incumbent, 1.0, [-2.0, -3.0], True)  # Q on trial against them
    feedback.returns = [-2.0]
    assert not agent.planning.greedy_active and not agent.planning.active
    np.testing.assert_array_equal(agent.predict(obs)[0], q_greedy)
    feedback.returns = [-2.0, -3.5]
    assert agent.planning.greedy_active and not agent.planning.active
    np.testing.assert_array_equal(agent.predict(obs)[0], policy_greedy)


class PointToCentre(PointToGoal):
    """:class:`PointToGoal`'s moves, paid ``-x'^2`` a step, never terminating: a regulator,
    where a feedback policy is the answer (``a = -1`` right of 0, ``+1`` left, until near)."""

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, *_ = super().step(action)
        return obs, -float(obs[0] ** 2), False, self._t >= 40, {}


@POLICY_PLANNERS
def test_the_policy_learns_to_regulate_the_point(planner: str) -> None:
    agent = _enough_steps(GPQAgent(PointToCentre(), seed=1, **(POLICY | {"planner": planner})))
    agent.learn(300)
    for start in (-1.0, -0.5, 0.6, 1.0):
        env = PointToCentre()
        obs, _ = env.reset(seed=0, options={"state": [start]})
        path = []
        for _ in range(20):
            obs, *_ = env.step(agent.predict(obs)[0])
            path.append(abs(obs[0]))
        # at most one step slower than full speed, then held within 0.1
        assert max(path[int(np.ceil(abs(start) / 0.1)) :]) < 0.1, (start, path)


@POLICY_PLANNERS
def test_a_policy_agent_learns_the_same_steps_and_saves_and_loads(tmp_path, planner: str) -> None:
    a, b = _policy_agent(3, planner).learn(150), _policy_agent(3, planner).learn(150)
    for x, y in zip(a.buffer.arrays(), b.buffer.arrays(), strict=True):
        assert np.array_equal(x, y)
    a.planning.feedback.overshoot = 0.25  # a shortfall on record, read by the next gate
    a.planning.feedback.q_lost_at = 120  # Q lost a trial there: no new one before 240
    if planner == "policy-net":  # weights the model could not score, on trial against others
        feedback = a.planning.feedback
        feedback.acting, feedback.blind = True, True
        feedback.kept = (feedback.gains + 0.5, -1.0, [-2.0, -3.0], True)
    a.save(tmp_path / "a.npz")
    loaded = GPQAgent.load(tmp_path / "a.npz", env=PointToGoal())
    ours, theirs = a.planning.feedback, loaded.planning.feedback
    assert np.array_equal(ours.gains, theirs.gains) and np.array_equal(ours.starts, theirs.starts)
    assert (ours.value, ours.searched_at) == (theirs.value, theirs.searched_at)
    assert type(ours.policy) is type(theirs.policy) and ours.net == (planner == "policy-net")
    assert (ours.returns, ours.episode_from) == (theirs.returns, theirs.episode_from)
    assert ours.q_returns == theirs.q_returns and ours.overshoot == theirs.overshoot == 0.25
    assert ours.q_lost_at == theirs.q_lost_at == 120
    assert ours.blind == theirs.blind == (planner == "policy-net")
    assert ours.real_test == theirs.real_test == (planner == "policy-net")
    assert (ours.kept is None) == (theirs.kept is None) and ours.acting == theirs.acting
    a.learn(120)
    loaded.learn(120)
    for x, y in zip(a.buffer.arrays(), loaded.buffer.arrays(), strict=True):
        assert np.array_equal(x, y)
    with np.load(tmp_path / "a.npz", allow_pickle=False) as f:
        arrays = dict(f)
    damaged = [("model/policy_gains", np.zeros((2, 2)), "policy_gains"),
               ("model/policy_starts", np.full((3, 1), np.nan), "policy_starts"),
               ("model/policy_scale", np.zeros(1), "scale"),
               ("model/policy_returns", np.array([np.nan]), "policy_returns"),
               ("model/policy_q_returns", np.ones((1, 1)), "policy_q_returns"),
               ("model/policy_overshoot", np.array(np.inf), "policy_overshoot"),
               ("model/policy_overshoot", np.array(-1.0), "policy_overshoot"),
               ("model/policy_acting", np.array(2.0), "policy_acting"),
               ("model/policy_q_lost_at", np.array(-1), "policy_q_lost_at"),
               ("model/policy_q_lost_at", np.array(1.5), "policy_q_lost_at"),
               ("model/policy_blind", np.array(1.0), "policy_blind")]  # fmt: skip
    if planner == "policy-net":  # blind, but on trial against Q
        damaged.append(("model/policy_kept_acting", np.array(False), "policy_blind"))
    for key, bad, match in damaged:
        np.savez(tmp_path / "bad.npz", **(arrays | {key: bad}))
        with pytest.raises(ArchiveError, match=match):
            GPQAgent.load(tmp_path / "bad.npz", env=PointToGoal())


def test_a_bad_policy_horizon_is_refused() -> None:
    with pytest.raises(ValueError, match="policy_horizon"):
        GPQAgent(PointToGoal(), planner="policy", policy_horizon=0)
