"""Hostile inputs to the agent (issue 32): its constructor, ``learn`` with an env that
misbehaves, huge bounds, quantised action boxes, damaged files.

The rule: a call either raises a ``ValueError`` that names what was wrong (the argument,
or the env's reward / observation / flag) and leaves the agent exactly as it was, or it
works, and what it stores is what happened (the action the env executed).
"""

from __future__ import annotations

import copy
import json
import pickle
import sys
import threading
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tests._fuzz import fuzz_settings
from tests.agents._tasks import PointToGoal

from geoq._io import ArchiveError
from geoq.agents import GPQAgent, GPQConfig

FUZZ = fuzz_settings(40)
F32 = float(np.finfo(np.float32).max)


def _snapshot(agent: GPQAgent) -> dict[str, Any]:
    """Everything an agent has learned and will draw: buffer, GP, state, log, generator
    (copies: the GP's arrays are views of its live state)."""
    return copy.deepcopy({
        "buffer": agent.buffer.to_arrays(), "gp": agent.gp.to_arrays(),
        "state": agent.state.as_dict(), "log": agent.log.as_dict(),
        "episodes": agent.log.episodes_array(), "rng": agent.rng.bit_generator.state,
    })  # fmt: skip


def _assert_same(a: Any, b: Any, where: str = "") -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), where
        for k in a:
            _assert_same(a[k], b[k], f"{where}/{k}")
    elif isinstance(a, np.ndarray | list | tuple):
        assert np.shape(a) == np.shape(b), where
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=where)
    else:
        assert a == b or (a != a and b != b), where  # NaN equals NaN here


# ---------------------------------------------------------------- learn, a misbehaving env
BAD_OUTPUTS = {
    "reward": [1e200, -1e300, np.array([1.0, 2.0]), np.array([1.0]), "1", None, True, np.nan,
               np.inf, 10**400, 1 + 2j],
    "observation": [np.array([1e200]), np.array([np.nan]), np.array([1.0, 2.0]), "x", None,
                    np.array([[0.5]]), [0.1, [0.2]], np.array([1 + 1j])],
    "terminated": [None, "yes", np.array([True, False]), 1, 0.0],
    "truncated": [None, "no", np.array([False, False])],
    "info": [None, [], "done"],
    "tuple": [4, 6],
}  # fmt: skip
WORDS = {"reward": "reward", "observation": "observation", "terminated": "terminated",
         "truncated": "truncated", "info": "info", "tuple": "values"}  # fmt: skip


class Misbehaving(PointToGoal):
    """:class:`PointToGoal` whose ``bad_step``-th step returns ``value`` in place of ``what``;
    just before, it records the agent's snapshot (:meth:`watch`), its generator as it was
    before the step's action was chosen (an exploration map draws among ties)."""

    def __init__(self, bad_step: int, what: str, value: Any) -> None:
        super().__init__()
        self.bad_step, self.what, self.value, self.n = bad_step, what, value, 0
        self.agent: GPQAgent | None = None
        self.before: dict[str, Any] | None = None
        self.rng_at_choice: dict[str, Any] | None = None

    def watch(self, agent: GPQAgent) -> None:
        self.agent, explore = agent, agent._explore

        def watched(s: np.ndarray, q: Any) -> np.ndarray:
            self.rng_at_choice = copy.deepcopy(agent.rng.bit_generator.state)
            return explore(s, q)

        agent._explore = watched  # type: ignore[method-assign]

    def step(self, action: np.ndarray) -> Any:
        self.n += 1
        out = list(super().step(action))
        if self.n != self.bad_step:
            return tuple(out)
        if self.agent is not None:
            self.before = {**_snapshot(self.agent), "rng": self.rng_at_choice}
        if self.what == "tuple":
            return tuple(out[:4]) if self.value == 4 else (*out, None)
        key = ("observation", "reward", "terminated", "truncated", "info").index(self.what)
        out[key] = self.value
        return tuple(out)


@FUZZ
@given(what=st.sampled_from(sorted(BAD_OUTPUTS)), data=st.data(),
       bad_step=st.integers(1, 90), kernel=st.sampled_from(["euclidean", "nearest"]))  # fmt: skip
def test_a_refused_step_leaves_the_agent_exactly_as_it_was(
    what: str, data: st.DataObject, bad_step: int, kernel: str
) -> None:
    value = data.draw(st.sampled_from(BAD_OUTPUTS[what]), label="value")
    env = Misbehaving(bad_step, what, value)
    agent = GPQAgent(env, kernel=kernel, max_bv=20, seed=0, gamma=0.9, train_every=10)  # type: ignore[arg-type]
    env.watch(agent)
    before_learn = _snapshot(agent)
    with pytest.raises(ValueError, match=WORDS[what]) as info:
        agent.learn(100)
    message = str(info.value)
    assert "Misbehaving" in message or "env's" in message, message
    assert "standardise the targets" not in message and "rescale the inputs" not in message
    assert env.before is not None
    # The refused step changed nothing; refused as the call's first, nothing at all
    # (learn's draw of the first reset's seed is put back too).
    _assert_same(before_learn if bad_step == 1 else env.before, _snapshot(agent))
    assert agent.num_timesteps == bad_step - 1 == len(agent.buffer)
    if agent.num_timesteps:
        assert max(abs(v) for v in agent.value_bounds()) <= 1e3  # no trace of the reward
    env.bad_step = -1  # the env behaves again: learning goes on with finite values
    agent.learn(30)
    assert np.all(np.isfinite(agent.buffer.targets())) and np.all(
        np.abs(agent.buffer.targets()) < 1e3
    )


@pytest.mark.parametrize("exploration", ["gaussian", "thompson", "ucb"])
def test_a_refused_first_step_of_an_episode_is_as_if_learning_had_stopped_before(
    exploration: str,
) -> None:
    """The generator too: the agent refused at the first step of its 2nd episode equals a
    twin stopped by its callback after the 1st episode (the action drawn is put back)."""

    def make(env: gymnasium.Env) -> GPQAgent:
        return GPQAgent(env, max_bv=20, seed=3, gamma=0.9, exploration=exploration)  # type: ignore[arg-type]

    twin = make(PointToGoal()).learn(400, callback=lambda rec: False)
    first = twin.num_timesteps
    bad = Misbehaving(first + 1, "reward", 1e300)
    agent = make(bad)
    with pytest.raises(ValueError, match="reward"):
        agent.learn(400)
    a, b = _snapshot(twin), _snapshot(agent)
    del a["log"]["train_seconds"], b["log"]["train_seconds"]  # wall time
    _assert_same(a, b)
    # Refused at the very first step of a call: as before the call, generator included.
    before = _snapshot(agent)
    bad.n, bad.bad_step = 0, 1
    with pytest.raises(ValueError, match="reward"):
        agent.learn(50)
    _assert_same(before, _snapshot(agent))


class _BadReset(PointToGoal):
    def reset(self, **kwargs: Any) -> Any:
        _, info = super().reset(**kwargs)
        return np.array([np.inf]), info


def test_a_refused_reset_leaves_the_agent_as_before() -> None:
    agent = GPQAgent(_BadReset(), max_bv=10, seed=1)
    before = _snapshot(agent)
    with pytest.raises(ValueError, match="_BadReset returned an observation with NaN or inf"):
        agent.learn(10)
    _assert_same(before, _snapshot(agent))


def test_bad_learn_arguments_are_refused_before_any_step() -> None:
    agent = GPQAgent(PointToGoal(), max_bv=10, seed=0)
    before = _snapshot(agent)
    for kwargs, match in (({"callback": 42}, "callback must be None or a function"),
                          ({"progress_bar": "yes"}, "progress_bar must be True or False"),
                          ({"total_timesteps": True}, "total_timesteps")):  # fmt: skip
        with pytest.raises(ValueError, match=match):
            agent.learn(**{"total_timesteps": 50, **kwargs})
    _assert_same(before, _snapshot(agent))


# ---------------------------------------------------------------- learn(0)
def _learned(agent: GPQAgent) -> dict[str, Any]:
    """:func:`_snapshot` (without the wall time) plus the exploration map and the fitted-Q
    phases' column order: everything later numbers depend on."""
    out = _snapshot(agent)
    del out["log"]["train_seconds"]
    out["explorer"] = copy.deepcopy(agent.explorer.to_arrays())
    out["slots"] = copy.deepcopy(agent.phase.covariances.slot_arrays())
    return out


@fuzz_settings(12)
@given(
    before=st.integers(0, 90), after=st.integers(1, 90), zeros=st.integers(1, 3),
    kernel=st.sampled_from(["euclidean", "nearest"]),
    exploration=st.sampled_from(["ucb", "thompson", "gaussian"]),
)  # fmt: skip
def test_learn_zero_changes_nothing_later_runs_depend_on(
    before: int, after: int, zeros: int, kernel: str, exploration: str
) -> None:
    """``learn(0)`` drew the next episode's seed from the agent's generator (and ran a
    phase when the last call ended mid-episode): an agent that called it went on
    differently from one that never did."""

    def make() -> GPQAgent:
        return GPQAgent(PointToGoal(), kernel=kernel, max_bv=20, seed=5, gamma=0.9,  # type: ignore[arg-type]
                        exploration=exploration, train_every=10)  # type: ignore[arg-type]  # fmt: skip

    a, b = make().learn(before), make().learn(before)
    seen = _learned(a)
    for _ in range(zeros):
        a.learn(0)
        a.learn(0, progress_bar=True, callback=lambda rec: None)
    _assert_same(seen, _learned(a))
    a.learn(after)
    b.learn(after)
    _assert_same(_learned(b), _learned(a))
    obs = np.linspace(-1, 1, 9)[:, None]
    np.testing.assert_array_equal(a.predict(obs)[0], b.predict(obs)[0])


# ---------------------------------------------------------------- threads
class _ShortEpisodes(PointToGoal):
    """:class:`PointToGoal` cut after 3 steps: a reset, a phase and a callback every 3 steps."""

    def step(self, action: np.ndarray) -> Any:
        obs, reward, terminated, truncated, info = super().step(action)
        truncated = truncated or (self._t >= 3 and not terminated)
        return obs, reward, terminated, truncated, info


THREADED_RUNS = {
    # The map is built after 2 K = 128 steps and planned lazily: the IndexError's home.
    "tworooms": (lambda: gymnasium.make("geoq/TwoRooms-v0"), {"max_bv": 60}, 360),
    "short_episodes": (_ShortEpisodes, {"max_bv": 30, "train_every": 2}, 150),
    "warmup": (lambda: _Bounds(-np.inf, 1.0), {"max_bv": 30, "warmup_steps": 40}, 120),
}


def _run_state(agent: GPQAgent) -> dict[str, Any]:
    """:func:`_learned` and the posterior weights, less the GP's counts of what its
    predictions repaired (they count calls; nothing reads them back to learn)."""
    out = _learned(agent)
    for key in ("predict_rescaled", "predict_clipped", "warned"):
        del out["gp"][key]
    out["alpha"] = agent.gp.alpha
    return out


@pytest.mark.parametrize("name", sorted(THREADED_RUNS))
def test_predict_from_another_thread_while_learning_never_raises_and_changes_nothing(
    name: str, tmp_path: Path
) -> None:
    """``predict`` in one thread while ``learn`` ran in another raised ``IndexError`` (the
    map's plans, the GP's arrays caught mid-step). Each learning step now holds the
    agent's lock; a callback in the learning thread predicts and saves under it too (a
    re-entrant lock); the run is bit for bit the one without them."""
    make_env, kwargs, steps = THREADED_RUNS[name]
    reference = GPQAgent(make_env(), seed=0, **kwargs).learn(steps)
    agent = GPQAgent(make_env(), seed=0, **kwargs)
    rng = np.random.default_rng(0)
    obs = rng.uniform(-1, 1, size=(16, agent.obs_dim))
    errors: list[BaseException] = []
    calls = [0, 0]
    stop = threading.Event()

    def ask() -> None:
        try:
            while not stop.is_set():
                agent.predict(obs, deterministic=True)
                agent.predict(obs[0])
                calls[0] += 1
        except BaseException as exc:
            errors.append(exc)

    def callback(rec: Any) -> None:
        agent.predict(obs)
        agent.save(tmp_path / "inside.npz")
        calls[1] += 1

    switch = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)  # hand the GIL over often: a race shows at once
    thread = threading.Thread(target=ask, daemon=True)
    thread.start()
    try:
        agent.learn(steps, callback=callback)
    finally:
        stop.set()
        thread.join(timeout=60)
        sys.setswitchinterval(switch)
    assert not thread.is_alive()
    assert not errors, repr(errors[0])
    assert calls[0] >= 20 and calls[1] >= 1, calls
    if name == "tworooms":
        assert agent.explorer.map is not None
    _assert_same(_run_state(reference), _run_state(agent))
    GPQAgent.load(tmp_path / "inside.npz", env=make_env())  # saved whole, mid-learning


@fuzz_settings(15)
@given(
    name=st.sampled_from(sorted(THREADED_RUNS)), steps=st.integers(0, 200),
    exploration=st.sampled_from(["ucb", "thompson", "gaussian", "greedy"]),
)  # fmt: skip
def test_a_deterministic_predict_draws_nothing_from_the_generator(
    name: str, steps: int, exploration: str
) -> None:
    """What lets other threads predict while the agent learns without changing its run:
    before the warm-up, with and without a map, under every exploration mode."""
    make_env, kwargs, _ = THREADED_RUNS[name]
    agent = GPQAgent(make_env(), seed=1, exploration=exploration, **kwargs).learn(steps)  # type: ignore[arg-type]
    before = _run_state(agent)
    obs = np.random.default_rng(2).uniform(-1, 1, size=(9, agent.obs_dim))
    for x in (obs, obs[0]):
        agent.predict(x, deterministic=True)
    _assert_same(before, _run_state(agent))
    drawn = agent.rng.bit_generator.state
    agent.predict(obs, deterministic=False)  # the exploration's draws, if any, are its own
    if exploration == "greedy" and not agent.state.scaling_pending:
        assert agent.rng.bit_generator.state == drawn


def test_copies_and_pickles_get_their_own_lock_and_continue_alike() -> None:
    agent = GPQAgent(PointToGoal(), max_bv=20, seed=0).learn(60)
    twins = [copy.deepcopy(agent), pickle.loads(pickle.dumps(agent))]
    assert all(t._lock is not agent._lock for t in twins)
    agent.learn(40)
    for twin in twins:
        twin.learn(40)
        _assert_same(_run_state(agent), _run_state(twin))


# ---------------------------------------------------------------- spaces
class _Bounds(PointToGoal):
    def __init__(self, low: float, high: float, dtype: Any = np.float32) -> None:
        super().__init__()
        self.observation_space = gymnasium.spaces.Box(low, high, shape=(1,), dtype=dtype)


@pytest.mark.parametrize(
    ("low", "high", "dtype"),
    [(-F32, F32, np.float32), (-1.79e308, 1.79e308, np.float64),
     (-1e10, 1e10, np.float64), (-1.0, 1e7, np.float64), (-np.inf, 1.0, np.float32)],
)  # fmt: skip
def test_huge_observation_bounds_are_no_bounds_and_scale_from_data(
    low: float, high: float, dtype: Any
) -> None:
    agent = GPQAgent(_Bounds(low, high, dtype), max_bv=60, seed=0, gamma=0.9, warmup_steps=40)
    assert agent.state.scaling_pending  # the data-scaling path, not a division by 1e38
    agent.learn(120)
    assert not agent.state.scaling_pending and agent.scaling.scale[0] < 10.0
    assert np.ptp(agent.q_mean(np.array([[-0.9], [0.5]]))) > 0  # states are told apart


def test_bounded_observations_keep_the_half_range() -> None:
    agent = GPQAgent(_Bounds(-2.0, 2.0), max_bv=10)
    assert not agent.state.scaling_pending and agent.scaling.scale[0] == 2.0


@pytest.mark.parametrize("high", [1e6, F32, np.inf])
def test_huge_action_bounds_are_refused(high: float) -> None:
    env = PointToGoal()
    env.action_space = gymnasium.spaces.Box(-high, high, shape=(1,), dtype=np.float64)
    with pytest.raises(ValueError, match=r"finite action bounds below 1e\+06.*RescaleAction"):
        GPQAgent(env)


class _Quantised(PointToGoal):
    def __init__(self, dtype: Any, low: float = -1, high: float = 1) -> None:
        super().__init__()
        self.action_space = gymnasium.spaces.Box(low, high, shape=(1,), dtype=dtype)
        self.received: list[float] = []

    def step(self, action: np.ndarray) -> Any:
        assert action.dtype == self.action_space.dtype
        self.received.append(float(action[0]))
        return super().step(np.asarray(action, dtype=np.float64))


@pytest.mark.parametrize(
    ("dtype", "low", "high"),
    [(np.int64, -1, 1), (np.int8, -3, 2), (np.float16, -1, 1), (np.uint8, 0, 3)],
)
def test_quantised_action_boxes_store_what_the_env_executed(
    dtype: Any, low: float, high: float
) -> None:
    env = _Quantised(dtype, low, high)
    agent = GPQAgent(env, max_bv=20, seed=0).learn(80)
    stored = agent.buffer.arrays()[1][:, 0]
    np.testing.assert_array_equal(stored, np.array(env.received))
    assert np.all((stored >= low) & (stored <= high))
    if np.dtype(dtype).kind in "iu":
        assert np.all(stored == np.rint(stored)) and len(np.unique(stored)) > 1


# ---------------------------------------------------------------- the constructor
SETTINGS = {
    "gamma": st.one_of(st.floats(-1, 2), st.sampled_from([np.float32(0.9), True, "0.9", 1.0])),
    "beta": st.one_of(st.floats(0, 10), st.sampled_from([1e308, np.float64(2.0), -1.0, None])),
    "max_bv": st.one_of(st.integers(-2, 60), st.sampled_from([np.int64(30), np.int32(8), 2.0,
                                                                True, 10**6])),
    "n_candidates": st.one_of(st.integers(0, 40), st.sampled_from([np.int16(5), 10**12, 5.5])),
    "lengthscale": st.one_of(st.none(), st.floats(-1, 2), st.lists(st.floats(0.01, 2), max_size=3),
                             st.sampled_from([np.array([0.3, 0.4]), "0.3", ["0.1", "0.2"], True,
                                              np.float32(0.2), [[0.3, 0.4]]])),
    "tol": st.one_of(st.floats(-1, 2), st.sampled_from([np.float32(1e-4), "1e-6", None])),
    "amplitude": st.sampled_from([1.0, 1e308, 1e-300, np.float64(2.0), 0.0]),
    "reward_bounds": st.sampled_from([None, (-1.0, 0.0), np.array([-1.0, 0.0]), (0.0, 1e300),
                                      (1.0, -1.0), "ab", (np.float32(-1), np.int64(0))]),
    "seed": st.one_of(st.none(), st.integers(-3, 2**40), st.sampled_from([True, 1.5, "0",
                                                                          np.int64(7)])),
}  # fmt: skip


@FUZZ
@given(chosen=st.fixed_dictionaries({}, optional=SETTINGS))  # type: ignore[arg-type]
def test_the_constructor_refuses_naming_the_setting_or_the_agent_learns_and_saves(
    chosen: dict[str, Any], tmp_path_factory: pytest.TempPathFactory
) -> None:
    try:
        agent = GPQAgent(PointToGoal(), **chosen)
    except ValueError as exc:
        assert any(name in str(exc) for name in chosen), (chosen, str(exc))
        return
    agent.learn(3)
    path = tmp_path_factory.mktemp("agent") / "agent.npz"
    agent.save(path)  # numpy scalars were made Python numbers: the JSON meta saves
    loaded = GPQAgent.load(path, env=PointToGoal())
    assert loaded.config == agent.config and loaded.seed == agent.seed
    assert GPQConfig.from_dict(json.loads(json.dumps(agent.config.as_dict()))) == agent.config


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"seed": True}, "seed"), ({"seed": -1}, "seed must be None or an integer >= 0"),
     ({"gamma": True}, "gamma"), ({"lengthscale": "0.3"}, "lengthscale"),
     ({"beta": 1e308}, "beta must be a finite number >= 0 and <= 1e\\+06"),
     ({"tol": 2.0}, "tol .* novelty threshold"), ({"scaling": "x"}, "scaling must be"),
     ({"scaling": (1.0,)}, "scaling must be"), ({"periods": [True]}, "periods"),
     ({"amplitude": 1e308}, "amplitude"), ({"reward_bounds": (0.0, 1e300)}, "reward_bounds"),
     ({"n_candidates": 10**9}, "n_candidates")],
)  # fmt: skip
def test_loose_or_overflowing_settings_are_refused_by_name(
    kwargs: dict[str, Any], match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        GPQAgent(PointToGoal(), **kwargs)


def test_scaling_takes_one_scale_per_input_and_predict_names_its_errors() -> None:
    agent = GPQAgent(PointToGoal(), max_bv=10, seed=0, scaling=[np.float32(0.5), 1])
    assert agent.scaling.scale == (0.5, 1.0) and type(agent.scaling.scale[0]) is float
    with pytest.raises(ValueError, match="no rows"):
        agent.predict(np.zeros((0, 1)))
    with pytest.raises(ValueError, match="observation reaches 1e\\+200"):
        agent.predict(np.array([1e200]))
    with pytest.raises(ValueError, match="deterministic must be True or False"):
        agent.predict(np.array([0.1]), deterministic="no")  # type: ignore[arg-type]


# ---------------------------------------------------------------- damaged files
def _tampered(path: Path, tmp: Path, change: Any) -> Path:
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(str(arrays["meta"]))
    change(meta)
    arrays["meta"] = np.asarray(json.dumps(meta))
    out = tmp / "tampered.npz"
    np.savez(out, **arrays)
    return out


@pytest.mark.parametrize(
    "change",
    [lambda m: m.update(reward_range=[5.0, -5.0]), lambda m: m.update(reward_range=[1e300, 1e300]),
     lambda m: m.update(reward_range=["a", 1]), lambda m: m.update(y_scale=-1.0),
     lambda m: m.update(rng_state={"bit_generator": "MT19937"}), lambda m: m.update(seed=-4),
     lambda m: m.update(seed=True), lambda m: m.update(env_id=3),
     lambda m: m.update(num_timesteps=-1),
     lambda m: m.update(fitted_q_sweeps=["x"]), lambda m: m.update(fitted_lengthscale=[0.1] * 7),
     lambda m: m["config"].update(lengthscale=[0.1, 0.2, 0.3]), lambda m: m.pop("rng_state")],
)  # fmt: skip
def test_tampered_fields_are_archive_errors_at_load(change: Any, tmp_path: Path) -> None:
    agent = GPQAgent(PointToGoal(), max_bv=10, seed=0).learn(30)
    path = tmp_path / "agent.npz"
    agent.save(path)
    with pytest.raises(ArchiveError, match="GPQAgent archive"):
        GPQAgent.load(_tampered(path, tmp_path, change), env=PointToGoal())
