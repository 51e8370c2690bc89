"""GPQAgent: learns a task with a known optimal policy; API, determinism, persistence."""

from __future__ import annotations

import itertools
import json
import zipfile
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.agents._tasks import PointToGoal, steps_to_goal

import geoq  # noqa: F401  (registers the envs)
from geoq._io import ArchiveError
from geoq.agents import GPQAgent, GPQConfig
from geoq.agents.config import default_max_bv

KERNELS = ("euclidean", "nearest", "interpolated", "resistance")


def _agent(seed: int = 0, **kw: object) -> GPQAgent:
    kw.setdefault("max_bv", 60)
    return GPQAgent(PointToGoal(), seed=seed, gamma=0.9, **kw)  # type: ignore[arg-type]


def test_learns_the_optimal_policy_of_a_point_to_goal_task() -> None:
    agent = _agent().learn(400)
    assert agent.explorer.map is not None  # a point pushed by its action: the map acts
    for start in (-1.0, -0.6, -0.2, 0.2):
        optimal = steps_to_goal(lambda obs: np.array([1.0]), start)
        learned = steps_to_goal(lambda obs: agent.predict(obs)[0], start)
        assert learned <= optimal + 1, (start, learned, optimal)
    # The learned greedy action points at the goal from the left.
    actions, _ = agent.predict(np.array([[-0.9], [-0.3], [0.3]]))
    assert np.all(actions > 0.5)


def test_an_untrained_agent_does_not_solve_the_task() -> None:
    """The check above can fail: before learning, the greedy action is arbitrary."""
    agent = _agent()
    assert steps_to_goal(lambda obs: agent.predict(obs)[0], -1.0) > 18


def test_same_seed_same_learning_curve_and_actions() -> None:
    a, b = _agent(seed=3).learn(150), _agent(seed=3).learn(150)
    assert a.episodes == b.episodes
    for x, y in zip(a.buffer.arrays(), b.buffer.arrays(), strict=True):
        np.testing.assert_array_equal(x, y)
    obs = np.linspace(-1, 1, 9)[:, None]
    np.testing.assert_array_equal(a.predict(obs)[0], b.predict(obs)[0])
    c = _agent(seed=4).learn(150)
    assert not np.array_equal(c.buffer.arrays()[0], a.buffer.arrays()[0])


@pytest.mark.parametrize("kernel", KERNELS)
def test_save_load_round_trip_acts_identically(kernel: str, tmp_path: Path) -> None:
    # a window shorter than the run: the reloaded agent's first phase slides it
    agent = _agent(kernel=kernel, max_bv=30, window=50).learn(80)
    path = tmp_path / "agent.npz"
    agent.save(path)
    loaded = GPQAgent.load(path, env=PointToGoal())
    obs = np.linspace(-1, 1, 11)[:, None]
    np.testing.assert_array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])
    assert loaded.config == agent.config and loaded.episodes == agent.episodes
    assert loaded.num_timesteps == agent.num_timesteps == 80
    # Both continue identically (generator state and env seeding saved).
    agent.learn(40)
    loaded.learn(40)
    np.testing.assert_array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])


def test_fitted_q_phases_follow_train_every_and_train_fraction(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Mid-episode phases at multiples of ``train_every`` once the window grew by
    ``train_fraction`` since the last phase; one at every episode's end (the rule
    replayed step by step)."""
    phases: list[int] = []
    train = GPQAgent.train

    def spy(self: GPQAgent) -> int:
        phases.append(self.num_timesteps)
        return train(self)

    monkeypatch.setattr(GPQAgent, "train", spy)
    agent = _agent(train_every=5, train_fraction=0.2, window=60).learn(150)
    ends = {e.timesteps for e in agent.episodes}
    expected, last = [], 0
    for t in range(1, 151):
        if t in ends or (t % 5 == 0 and t - last >= 0.2 * min(t, 60)):
            expected.append(t)
            last = t
    if agent.episodes[-1].timesteps != 150:
        expected.append(150)  # learn() ends with a phase
    assert phases == expected
    skipped = [t for t in range(5, 150, 5) if t not in phases]
    assert len(skipped) > 5  # the fraction did skip multiples of train_every


def test_residuals_say_whether_a_phase_converged() -> None:
    """A phase cut at one sweep leaves targets moving; one given room converges (the
    tiny task's fitted-Q is a contraction) and its residual is within the tolerance."""
    cut = _agent(max_bv=30, max_sweeps=1, sweep_tol=1e-9).learn(60)
    assert set(cut.log.fitted_q_sweeps) == {1} and min(cut.log.fitted_q_residuals) > 0.0
    room = _agent(max_bv=30, max_sweeps=5_000).learn(60)
    pairs = zip(room.log.fitted_q_sweeps, room.log.fitted_q_residuals, strict=True)
    converged = [r for n, r in pairs if n < 5_000]
    assert converged and max(converged) <= room.config.sweep_tol * 2 * max(
        abs(v) for v in room.value_bounds()
    )


def test_round_trip_keeps_the_phase_schedule(tmp_path: Path) -> None:
    agent = _agent(max_bv=30, train_every=3, train_fraction=0.25).learn(70)
    path = tmp_path / "agent.npz"
    agent.save(path)
    loaded = GPQAgent.load(path, env=PointToGoal())
    assert loaded.state.last_train_timestep == agent.state.last_train_timestep
    agent.learn(50)
    loaded.learn(50)
    assert loaded.log.fitted_q_sweeps == agent.log.fitted_q_sweeps
    assert loaded.log.fitted_q_residuals == agent.log.fitted_q_residuals
    obs = np.linspace(-1, 1, 11)[:, None]
    np.testing.assert_array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])


def test_files_without_train_fraction_keep_the_fixed_schedule(tmp_path: Path) -> None:
    """An agent saved before ``train_fraction`` existed had phases every ``train_every``."""
    agent = _agent(max_bv=20, train_every=7, train_fraction=0.0).learn(40)
    path, old = tmp_path / "agent.npz", tmp_path / "old.npz"
    agent.save(path)
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(str(arrays["meta"]))
    del meta["config"]["train_fraction"], meta["last_train_timestep"]
    del meta["fitted_q_residuals"]  # not recorded before either
    arrays["meta"] = np.asarray(json.dumps(meta))
    np.savez(old, **arrays)
    loaded = GPQAgent.load(old, env=PointToGoal())
    assert loaded.config == agent.config and loaded.config.train_fraction == 0.0
    n_old = len(agent.log.fitted_q_sweeps)
    agent.learn(30)
    loaded.learn(30)
    assert loaded.log.fitted_q_sweeps == agent.log.fitted_q_sweeps
    assert np.all(np.isnan(loaded.log.fitted_q_residuals[:n_old]))
    assert loaded.log.fitted_q_residuals[n_old:] == agent.log.fitted_q_residuals[n_old:]


@pytest.mark.parametrize("kernel", ["euclidean", "nearest"])
def test_q_mean_is_the_mean_of_q_candidates_bit_for_bit(kernel: str) -> None:
    agent = _agent(kernel=kernel, max_bv=30).learn(60)
    for n in (1, 7, 200):  # both prediction routes (per-chunk solve, factored GEMM)
        states = np.linspace(-1, 1, n)[:, None]
        mean, _ = agent.q_candidates(states)
        q = agent.q_mean(states)
        assert q.shape == mean.shape == (n, agent.candidates.shape[0])
        np.testing.assert_array_equal(q.view(np.uint64), mean.view(np.uint64))


def test_candidate_inputs_are_the_public_inputs_bit_for_bit() -> None:
    agent = _agent(max_bv=10)
    states = np.random.default_rng(0).uniform(-3, 3, size=(5, agent.obs_dim))
    K = agent.candidates.shape[0]
    expected = agent.inputs(np.repeat(states, K, axis=0), np.tile(agent.candidates, (5, 1)))
    got = agent.scaling.transform_pairs(states, agent.candidates)
    assert got.tobytes() == expected.tobytes()


@pytest.mark.parametrize("kernel", ["euclidean", "resistance"])
def test_stored_next_q_is_q_mean_at_the_stored_next_states(kernel: str) -> None:
    """Graph replay's TD priorities: from the kept covariances (squared exponential) or
    one GP call (a kernel that follows its basis), the posterior mean either way."""
    agent = _agent(kernel=kernel, max_bv=30, window=50).learn(80)
    stored = agent.buffer.transitions(last=agent.config.window)
    q = agent.phase.stored_next_q(agent._phase_inputs(stored))
    assert q.shape == (50, agent.candidates.shape[0])
    expected = agent.q_mean(stored.next_states)
    np.testing.assert_allclose(q, expected, rtol=1e-12, atol=1e-12)


def test_damaged_files_raise_archive_error(tmp_path: Path) -> None:
    agent = _agent(max_bv=20).learn(30)
    path = tmp_path / "agent.npz"
    agent.save(path)
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[:-200])
    with pytest.raises(ArchiveError):
        GPQAgent.load(truncated)
    # Tamper: candidate actions outside the action box.
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    arrays["candidates"] = arrays["candidates"] * 10
    tampered = tmp_path / "tampered.npz"
    np.savez(tampered, **arrays)
    with pytest.raises(ArchiveError, match="inconsistent"):
        GPQAgent.load(tampered)
    with zipfile.ZipFile(path) as zf:
        assert all(not name.endswith(".pkl") for name in zf.namelist())
    # Tamper: two basis vectors in one covariance column.
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    good_slots = arrays["covariances/slots"]
    for bad in (np.zeros_like(good_slots), good_slots + 10**9, good_slots.astype(float)):
        arrays["covariances/slots"] = bad  # two BVs in one column, far outside the budget
        np.savez(tampered, **arrays)
        with pytest.raises(ArchiveError, match="inconsistent"):
            GPQAgent.load(tampered)


def test_files_without_covariance_slots_still_load(tmp_path: Path) -> None:
    """Agents saved before the fitted-Q column order was stored load and act the same."""
    agent = _agent(max_bv=20).learn(60)
    path, old = tmp_path / "agent.npz", tmp_path / "old.npz"
    agent.save(path)
    with np.load(path, allow_pickle=False) as npz:
        np.savez(old, **{k: npz[k] for k in npz.files if not k.startswith("covariances/")})
    loaded = GPQAgent.load(old, env=PointToGoal())
    obs = np.linspace(-1, 1, 7)[:, None]
    np.testing.assert_array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])
    assert len(loaded.learn(30).episodes) >= len(agent.episodes)


def test_predict_validates_observations_and_stays_in_the_box() -> None:
    agent = _agent().learn(50)
    action, state = agent.predict(np.array([0.1]))
    assert state is None and action.shape == (1,) and -1.0 <= action[0] <= 1.0
    actions, _ = agent.predict(np.linspace(-1, 1, 5)[:, None], deterministic=False)
    assert actions.shape == (5, 1) and np.all(np.abs(actions) <= 1.0)
    for bad, match in (([np.nan], "NaN"), ([0.1, 0.2], "shape"), ([[[0.1]]], "shape")):
        with pytest.raises(ValueError, match=match):
            agent.predict(np.array(bad))
    with pytest.raises(ValueError, match="complex"):
        agent.predict(np.array([0.1 + 1j]))


def test_swing_up_agent_acts_in_the_torque_box() -> None:
    agent = GPQAgent("geoq/PendulumSwingUp-v0", max_bv=40, seed=0, train_every=50).learn(60)
    obs = np.column_stack([np.linspace(-np.pi, np.pi, 7), np.linspace(-8, 8, 7)])
    actions, _ = agent.predict(obs)
    assert actions.shape == (7, 1) and np.all(np.abs(actions) <= 5.0)
    assert agent.scaling.periods[0] == pytest.approx(2 * np.pi)  # the angle wraps


def test_unsupported_envs_and_arguments_raise() -> None:
    with pytest.raises(ValueError, match="Box action space"):
        GPQAgent("CartPole-v1")
    dict_env = PointToGoal()
    dict_env.observation_space = gymnasium.spaces.Dict(  # type: ignore[assignment]
        {"x": gymnasium.spaces.Box(-1, 1, (1,))}
    )
    with pytest.raises(ValueError, match="Box observation space"):
        GPQAgent(dict_env)
    with pytest.raises(ValueError, match="kernel"):
        GPQAgent(PointToGoal(), kernel="rbf")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="gamma"):
        GPQAgent(PointToGoal(), gamma=1.0)
    with pytest.raises(TypeError, match="unknown"):
        GPQAgent(PointToGoal(), learning_rate=1e-3)
    with pytest.raises(ValueError, match="lengthscale"):
        GPQAgent(PointToGoal(), lengthscale=(0.1, 0.2, 0.3))
    with pytest.raises(ValueError, match="unknown GPQConfig"):
        GPQConfig.from_dict({"kernel": "euclidean", "bogus": 1})


def test_default_budget_doubles_past_three_inputs() -> None:
    assert [default_max_bv(d) for d in (1, 2, 3, 4, 5, 9)] == [400, 400, 400, 800, 800, 800]
    assert GPQAgent(PointToGoal()).config.max_bv == 400  # 1 + 1 inputs
    assert GPQAgent("geoq/PendulumSwingUp-v0").config.max_bv == 400  # 2 + 1
    assert GPQAgent("Pendulum-v1").config.max_bv == 800  # 3 + 1
    assert GPQAgent("geoq/TwoRooms-v0").config.max_bv == 800  # 2 + 2
    assert GPQAgent("Pendulum-v1", max_bv=50).config.max_bv == 50  # explicit wins
    assert GPQConfig().max_bv is None and GPQConfig.from_dict({"max_bv": None}).max_bv is None
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match="max_bv"):
            GPQConfig(max_bv=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="input_dim"):
        default_max_bv(0)


def test_replay_none_keeps_the_online_targets_and_uniform_rebootstraps_them() -> None:
    fixed = {"train_every": 250, "train_fraction": 0.0}  # no phase inside the first episode
    none = _agent(replay="none", **fixed).learn(120)
    uniform = _agent(replay="uniform", **fixed).learn(120)
    assert none.log.fitted_q_sweeps and set(none.log.fitted_q_sweeps) == {0}
    assert max(uniform.log.fitted_q_sweeps) > 0
    assert set(none.log.fitted_q_residuals) == {0.0}
    assert len(uniform.log.fitted_q_residuals) == len(uniform.log.fitted_q_sweeps)
    # Without replay a stored target is exactly what was bootstrapped online: r + gamma max Q
    # clipped, never recomputed; the sweeps of uniform replay move them.
    # The first episode (40 steps) is the same for both (same seed, same prior); its
    # targets differ only because uniform replay re-bootstrapped them.
    np.testing.assert_array_equal(uniform.buffer.arrays()[0][:40], none.buffer.arrays()[0][:40])
    assert not np.array_equal(uniform.buffer.targets()[:40], none.buffer.targets()[:40])
    before = none.buffer.targets()
    none.train()
    np.testing.assert_array_equal(none.buffer.targets(), before)
    with pytest.raises(ValueError, match="replay must be one of"):
        _agent(replay="bogus")


class _UnboundedPoint(PointToGoal):
    """:class:`PointToGoal` whose observation space declares no bounds."""

    def __init__(self) -> None:
        super().__init__()
        self.observation_space = gymnasium.spaces.Box(-np.inf, np.inf, shape=(1,))


def test_infinite_observation_bounds_scale_inputs_from_warm_up_data(tmp_path: Path) -> None:
    # The warm-up states span about half the box: finer length-scales, more BVs.
    agent = GPQAgent(_UnboundedPoint(), seed=0, gamma=0.9, max_bv=120, warmup_steps=60)
    assert agent.state.scaling_pending
    # Before the warm-up fixes the scaling the agent acts as the warm-up does: the box's
    # centre when deterministic, uniform over the box otherwise.
    np.testing.assert_array_equal(agent.predict(np.array([0.0]))[0], [0.0])
    np.testing.assert_array_equal(agent.predict(np.zeros((3, 1)))[0], np.zeros((3, 1)))
    drawn = agent.predict(np.zeros((200, 1)), deterministic=False)[0]
    assert drawn.shape == (200, 1) and np.all(np.abs(drawn) <= 1.0) and np.ptp(drawn) > 1.5
    with pytest.raises(ValueError, match=r"infinite bounds.*warm-up"):
        agent.q_candidates(np.array([[0.0]]))
    agent = GPQAgent(_UnboundedPoint(), seed=0, gamma=0.9, max_bv=120, warmup_steps=60)
    agent.learn(30)  # not enough to fix the scaling: nothing streamed
    assert agent.state.scaling_pending and agent.gp.n_bv == 0
    agent.learn(370)
    assert not agent.state.scaling_pending
    # The scale follows the states seen (rescaled as exploration widened them).
    S, _, _, S2, _ = agent.buffer.arrays(last=None)
    states = np.concatenate([S[:, 0], S2[:, 0]])
    q05, q95 = np.quantile(states, [0.05, 0.95])
    assert 0.5 * (q95 - q05) <= 1.5 * agent.scaling.scale[0]
    assert agent.scaling.scale[1] == 1.0  # the action keeps its box's half-range
    for start in (-1.0, -0.6, -0.2, 0.2):
        optimal = steps_to_goal(lambda obs: np.array([1.0]), start)
        learned = steps_to_goal(lambda obs: agent.predict(obs)[0], start)
        assert learned <= optimal + 1, (start, learned, optimal)
    path = tmp_path / "agent.npz"
    agent.save(path)
    loaded = GPQAgent.load(path, env=_UnboundedPoint())
    assert loaded.scaling == agent.scaling and not loaded.state.scaling_pending
    assert agent.log.rescales >= 2 and loaded.log.rescales == agent.log.rescales  # warm-up + growth
    obs = np.linspace(-1, 1, 7)[:, None]
    np.testing.assert_array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])


def test_declared_reward_bounds_set_the_value_bounds_from_the_first_step() -> None:
    agent = _agent(reward_bounds=(-1.0, 0.5))  # gamma 0.9
    assert agent.value_bounds() == pytest.approx((-10.0, 5.0))
    agent.learn(40)  # PointToGoal pays -1 per step: inside the declared range, no change
    assert agent.value_bounds() == pytest.approx((-10.0, 5.0))
    assert _agent().learn(40).value_bounds() == pytest.approx((-10.0, -1.0))  # seen only
    car = GPQAgent("MountainCarContinuous-v0", max_bv=10)  # known: -0.1 a^2, +100 at the flag
    assert car.state.reward_range == (-0.1, 0.0)
    assert car.state.terminal_reward_range == (99.9, 100.0)
    # The flag's reward ends the episode: received once, not 100 / (1 - gamma) = 5,000.
    assert car.value_bounds() == pytest.approx((-0.1 / (1.0 - car.config.gamma), 100.0))
    config = GPQConfig(reward_bounds=(-2.0, 3.0))
    assert GPQConfig.from_dict(config.as_dict()) == config
    for bad in ((1.0, -1.0), (0.0, np.inf), (0.0,), "ab", (True, 1.0)):
        with pytest.raises(ValueError, match="reward_bounds"):
            GPQConfig(reward_bounds=bad)  # type: ignore[arg-type]


def test_evidence_hyperparameters_fit_the_lengthscales_on_a_doubling_schedule(
    tmp_path: Path,
) -> None:
    agent = _agent(hyperparameters="evidence").learn(400)
    fits = agent.log.evidence_fits
    assert len(fits) >= 3
    sizes = [f["transitions"] for f in fits]
    assert all(b >= 2 * a for a, b in itertools.pairwise(sizes))
    for f in fits:  # each fit improves on the length-scales in use (its warm start)
        assert f["log_evidence"] >= f["log_evidence_start"]
    assert agent.state.fitted_lengthscale == tuple(fits[-1]["lengthscale"])
    np.testing.assert_array_equal(
        np.broadcast_to(agent.gp.kernel.lengthscale, (2,)), agent.state.fitted_lengthscale
    )
    rule = _agent().learn(400)
    assert rule.log.evidence_fits == [] and rule.state.fitted_lengthscale is None
    # Same seed, same fits; saved and reloaded, the agent keeps and continues them.
    again = _agent(hyperparameters="evidence").learn(400)
    assert again.log.evidence_fits == fits
    path = tmp_path / "agent.npz"
    agent.save(path)
    loaded = GPQAgent.load(path, env=PointToGoal())
    assert loaded.state.fitted_lengthscale == agent.state.fitted_lengthscale
    assert loaded.state.evidence_due == agent.state.evidence_due
    due = agent.state.evidence_due
    agent.learn(450)
    loaded.learn(450)
    assert agent.log.evidence_fits[-1]["transitions"] >= due  # the schedule went on
    assert loaded.log.evidence_fits == agent.log.evidence_fits
    obs = np.linspace(-1, 1, 7)[:, None]
    np.testing.assert_array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])
    with pytest.raises(ValueError, match="needs kernel='euclidean'"):
        _agent(hyperparameters="evidence", kernel="nearest")
    with pytest.raises(ValueError, match="hyperparameters must be one of"):
        _agent(hyperparameters="grid")


@settings(max_examples=60, deadline=None)
@given(
    r=st.tuples(st.floats(-5, 5), st.floats(-5, 5)).map(sorted),
    t=st.one_of(st.none(), st.tuples(st.floats(-200, 200), st.floats(-200, 200)).map(sorted)),
    gamma=st.floats(0.0, 0.99),
)
def test_value_bounds_hold_every_discounted_return_brute_force(
    r: list[float], t: list[float] | None, gamma: float
) -> None:
    """Oracle: the extreme discounted returns of k steps with rewards in [r_min, r_max]
    followed by a terminating reward in [t_min, t_max] (or none), over k up to 3,000."""
    agent = GPQAgent(
        PointToGoal(), max_bv=5, gamma=gamma, reward_bounds=tuple(r),
        terminal_reward_bounds=None if t is None else tuple(t),
    )  # fmt: skip
    lo, hi = agent.value_bounds()
    k = np.arange(3_001)[:, None]
    prefix = np.asarray(r)[None, :] * (1.0 - gamma**k) / (1.0 - gamma)  # [k, 2]
    returns = [prefix[1:]]  # k >= 1 rewards, no terminal one (gamma^k -> 0: continuing)
    if t is not None:
        returns.append(prefix + gamma**k * np.asarray(t)[None, :])  # then a terminal reward
    everything = np.concatenate([x.ravel() for x in returns])
    assert lo <= everything.min() + 1e-9 * (1 + abs(lo))
    assert hi >= everything.max() - 1e-9 * (1 + abs(hi))
    # ... and they are tight: each end is reached (or approached as k grows).
    assert everything.min() <= lo + 0.05 * (1 + abs(lo)) and everything.max() >= hi - 0.05 * (
        1 + abs(hi)
    )


def test_terminal_rewards_seen_widen_only_the_terminal_range() -> None:
    agent = _agent(reward_bounds=(-1.0, -1.0), terminal_reward_bounds=(5.0, 5.0)).learn(200)
    assert agent.state.reward_range == (-1.0, -1.0)  # PointToGoal pays -1 on every step,
    assert agent.state.terminal_reward_range == (-1.0, 5.0)  # the terminating ones included
    assert agent.value_bounds() == pytest.approx((-10.0, 5.0))
    with pytest.raises(ValueError, match="terminal_reward_bounds"):
        _agent(terminal_reward_bounds=(1.0, 0.0))
