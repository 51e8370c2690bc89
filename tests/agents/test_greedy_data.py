"""``greedy_actions="data"`` (and ``"auto"`` past one action dimension): the greedy action
among the actions the data hold near a state."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import geoq.agents.greedy_data as greedy_data
from geoq.agents import GPQAgent, GPQConfig
from geoq.agents.greedy_data import nearest_actions

#: TwoRooms (2 states, 2 actions) with its map off and a length-scale per input, so that
#: the greedy actions are ``Q``'s and the metric weighs the two states differently.
TASK = dict(explore_map="off", lengthscale=(0.1, 0.4, 0.6, 0.6), n_candidates=8)


def _brute_nearest(s: np.ndarray, stored: np.ndarray, period: np.ndarray, ls: np.ndarray,
                   k: int) -> list[int]:  # fmt: skip
    """Indices of the ``k`` stored states nearest ``s``, nearest first, ties to the earlier."""
    distances = []
    for j, t in enumerate(stored):
        r2 = 0.0
        for x, y, p, length in zip(s, t, period, ls, strict=True):
            diff = x - y
            if p > 0:
                diff = (diff + p / 2) % p - p / 2
            r2 += (diff / length) ** 2
        distances.append((r2, j))
    return [j for _, j in sorted(distances)[:k]]


def test_nearest_actions_are_the_brute_force_nearest_in_the_kernels_metric() -> None:
    rng = np.random.default_rng(0)
    stored = rng.uniform(-3, 3, (60, 3))
    stored[10] = stored[3]  # a tie: the earlier first
    actions = rng.uniform(-1, 1, (60, 2))
    states = np.vstack([rng.uniform(-3, 3, (5, 3)), stored[3] + 1e-3])
    period, ls = np.array([2 * np.pi, 0.0, 0.0]), np.array([0.5, 2.0, 1.0])
    got = nearest_actions(states, stored, actions, 7, period, ls)
    assert got.shape == (6, 7, 2)
    for i, s in enumerate(states):
        np.testing.assert_array_equal(got[i], actions[_brute_nearest(s, stored, period, ls, 7)])
    assert nearest_actions(states, stored[:4], actions[:4], 7, period, ls).shape == (6, 4, 2)


def test_the_greedy_action_is_the_best_stored_action_near_the_state_by_q_mean() -> None:
    agent = GPQAgent("geoq/TwoRooms-v0", seed=1, greedy_actions="data", **TASK).learn(300)
    stored = agent.buffer.transitions(last=agent.config.window)
    scale = np.asarray(agent.scaling.scale)[:2]
    ls = np.asarray(agent.config.lengthscale)[:2]
    states = stored.states[::5] + 0.01
    got, _ = agent.predict(states, deterministic=True)
    chosen = []
    for s in states:
        near = _brute_nearest(s / scale, stored.states / scale, np.zeros(2), ls, 8)
        saved, agent.candidates = agent.candidates, stored.actions[near]  # Q's candidates' path
        try:
            mean = agent.q_mean(s[None])[0]
        finally:
            agent.candidates = saved
        chosen.append(stored.actions[near][np.argmax(mean)])
    np.testing.assert_array_equal(got, np.array(chosen))
    candidates, _ = replace_greedy(agent, "candidates").predict(states, deterministic=True)
    assert not np.array_equal(got, candidates)  # the data's actions, not the candidates'


def replace_greedy(agent: GPQAgent, greedy: str) -> GPQAgent:
    """``agent`` seeking its greedy actions as ``greedy`` says (nothing else changed)."""
    agent.config = replace(agent.config, greedy_actions=greedy)
    return agent


def test_seeking_greedy_actions_in_the_data_changes_nothing_learned_by_ucb() -> None:
    runs = []
    for greedy in ("candidates", "data"):
        agent = GPQAgent("geoq/TwoRooms-v0", seed=2, greedy_actions=greedy, exploration="ucb",
                         **TASK)  # fmt: skip
        for _ in range(3):
            agent.learn(120)
            agent.predict(agent.buffer.transitions().states[-5:], deterministic=True)
        runs.append(agent)
    a, b = runs
    for x, y in zip(a.buffer.arrays(), b.buffer.arrays(), strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a.buffer.targets(), b.buffer.targets())
    assert a.rng.bit_generator.state == b.rng.bit_generator.state


def test_greedy_actions_in_the_data_survive_save_and_load(tmp_path: Path) -> None:
    agent = GPQAgent("geoq/TwoRooms-v0", seed=3, greedy_actions="data", **TASK).learn(300)
    agent.save(tmp_path / "a.npz")
    loaded = GPQAgent.load(tmp_path / "a.npz")
    assert loaded.config.greedy_actions == "data"
    states = agent.buffer.transitions().states[::29]
    np.testing.assert_array_equal(loaded.predict(states)[0], agent.predict(states)[0])


def test_a_batch_of_states_taken_in_blocks_gets_the_same_actions(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    agent = GPQAgent("geoq/TwoRooms-v0", seed=4, greedy_actions="data", **TASK).learn(300)
    states = agent.buffer.transitions().states[::3] + 0.01
    whole, _ = agent.predict(states)
    monkeypatch.setattr(greedy_data, "BLOCK", 7 * len(agent.buffer))  # 7 states a block
    np.testing.assert_array_equal(agent.predict(states)[0], whole)
    monkeypatch.setattr(greedy_data, "BLOCK", 1)  # one state a block
    np.testing.assert_array_equal(agent.predict(states)[0], whole)


@pytest.mark.parametrize(
    ("env_id", "resolved"),
    [("geoq/TwoRooms-v0", "data"), ("geoq/PendulumSwingUp-v0", "candidates")],
)
def test_auto_seeks_greedy_actions_in_the_data_past_one_action_dimension(
    env_id: str, resolved: str
) -> None:
    kwargs = TASK if env_id == "geoq/TwoRooms-v0" else {"explore_map": "off"}  # Q acts
    agent = GPQAgent(env_id, seed=5, **kwargs).learn(300)
    assert GPQConfig().greedy_actions == "auto" and agent.config.greedy_actions == resolved
    states = agent.buffer.transitions(last=300).states[::3] + 0.01
    default, _ = agent.predict(states)
    np.testing.assert_array_equal(default, replace_greedy(agent, resolved).predict(states)[0])
    other = "candidates" if resolved == "data" else "data"
    assert not np.array_equal(default, replace_greedy(agent, other).predict(states)[0])


def test_files_without_greedy_actions_keep_the_candidates(tmp_path: Path) -> None:
    """An agent saved before ``greedy_actions`` existed took the candidates' best."""
    agent = GPQAgent("geoq/TwoRooms-v0", seed=6, **TASK).learn(200)
    path, old = tmp_path / "agent.npz", tmp_path / "old.npz"
    agent.save(path)
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(str(arrays["meta"]))
    del meta["config"]["greedy_actions"]
    arrays["meta"] = np.asarray(json.dumps(meta))
    np.savez(old, **arrays)
    assert GPQAgent.load(path).config.greedy_actions == "data"
    assert GPQAgent.load(old).config.greedy_actions == "candidates"


def test_greedy_actions_are_validated() -> None:
    with pytest.raises(ValueError, match="greedy_actions must be one of"):
        GPQAgent("geoq/TwoRooms-v0", greedy_actions="nearest")


@pytest.mark.parametrize("mode", ["gaussian", "greedy"])
def test_training_actions_noise_the_greedy_action_among_the_data(mode: str) -> None:
    """``exploration="gaussian"`` with the data's greedy: that action plus the noise the
    agent's generator draws next, clipped to the box; ``greedy``: that action alone."""
    agent = GPQAgent("geoq/TwoRooms-v0", seed=7, greedy_actions="data", exploration=mode,
                     action_noise=0.8, **TASK).learn(300)  # fmt: skip
    states = agent.buffer.transitions().states[::7] + 0.01
    greedy, _ = agent.predict(states, deterministic=True)
    draws = np.random.default_rng()
    draws.bit_generator.state = agent.rng.bit_generator.state
    got, _ = agent.predict(states, deterministic=False)
    half = 0.5 * (agent.action_high - agent.action_low)
    noise = 0.8 * half * draws.standard_normal(greedy.shape) if mode == "gaussian" else 0.0
    np.testing.assert_array_equal(got, np.clip(greedy + noise, agent.action_low,
                                               agent.action_high))  # fmt: skip
    assert agent.rng.bit_generator.state == draws.bit_generator.state
    if mode == "gaussian":
        assert np.any(got == agent.action_high) and np.any(np.abs(got) < agent.action_high)
    candidates, _ = replace_greedy(agent, "candidates").predict(states, deterministic=True)
    assert not np.array_equal(greedy, candidates)


def test_learning_takes_its_training_actions_around_the_datas_greedy(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Where ``Q`` acts, every training step's action is :func:`act_in_data`'s (the map and
    the planner off), as the stored transitions show."""
    agent = GPQAgent("geoq/TwoRooms-v0", seed=8, greedy_actions="data", exploration="gaussian",
                     **TASK).learn(200)  # fmt: skip
    taken: list[np.ndarray] = []

    def spy(*args: object) -> np.ndarray:
        assert args[3] == "gaussian"
        taken.append(greedy_data.act_in_data(*args))  # type: ignore[arg-type]
        return taken[-1]

    monkeypatch.setattr("geoq.agents.gpq.act_in_data", spy)
    agent.learn(60)
    assert len(taken) == 60
    np.testing.assert_array_equal(agent.buffer.transitions().actions[-60:], np.vstack(taken))
