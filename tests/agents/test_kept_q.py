"""The kept ``Q`` (:mod:`geoq.agents.kept_q`): its record against a hand-run sequence of
episodes, its greedy actions against the agent as it was when copied (a copy of the
whole agent, taken by a callback), learning alike with or without it, and save / load."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from geoq._io import ArchiveError
from geoq.agents import GPQAgent, GPQConfig
from geoq.agents.buffer import TransitionBuffer
from geoq.agents.kept_q import KeptQ
from geoq.agents.q_actor import QActor
from geoq.gp import SparseOnlineGP
from geoq.kernels import SquaredExponential
from geoq.learners.scaling import InputScaling

OBS = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, -2.0], [-1.0, 0.0, 1.0], [0.6, -0.8, 3.0]])


def _stub() -> SimpleNamespace:
    """What :class:`KeptQ` reads of an agent, with a GP to copy and a buffer to count."""
    low, high = np.array([-1.0]), np.array([1.0])
    gp = SparseOnlineGP(SquaredExponential(lengthscale=0.5), noise=0.01, max_bv=20)
    gp.update(np.array([0.0, 0.0]), 1.0)
    agent = SimpleNamespace(
        gp=gp, actor=QActor("off", low, high), buffer=TransitionBuffer(1, 1),
        scaling=InputScaling((1.0, 1.0), (0.0, 0.0), ("s", "a")),
        state=SimpleNamespace(scaling_pending=False, y_mean=0.0, y_scale=1.0),
        explorer=SimpleNamespace(map=None),
        planning=SimpleNamespace(active=False), _lengthscale=lambda: 0.5,
    )  # fmt: skip
    return agent


def _episode(kept: KeptQ, agent: SimpleNamespace, ret: float | None, policy: bool = False) -> None:
    """An episode of one stored transition: ``ret`` None, cut short (no end)."""
    agent.planning.active = policy
    kept.start_episode(agent)  # type: ignore[arg-type]
    agent.buffer.add(np.zeros(1), np.zeros(1), 0.0, np.zeros(1), False)
    agent.gp.update(np.array([0.1 * len(agent.buffer), 0.0]), float(len(agent.buffer)))
    if ret is not None:
        kept.end_episode(ret)


def test_the_copy_kept_ran_the_best_episode_so_far() -> None:
    """A hand-run sequence: the copy kept is the one whose episode returned the most so
    far (of equals, the newer); a policy's episode and an episode cut short keep nothing;
    a copy is the GP as its episode started, not as it is now."""
    kept, agent = KeptQ(True), _stub()
    _episode(kept, agent, 10.0)  # stored 0
    assert kept.kept is not None and kept.kept.stored == 0 and kept.record == 10.0
    _episode(kept, agent, 5.0)
    assert kept.kept.stored == 0
    _episode(kept, agent, 500.0, policy=True)  # a policy's: not Q's record
    _episode(kept, agent, None)  # cut short: does not count
    assert kept.kept.stored == 0 and kept.record == 10.0
    _episode(kept, agent, 30.0)  # stored 4
    _episode(kept, agent, 30.0)  # stored 5: equal, the newer kept
    assert kept.kept.stored == 5 and kept.record == 30.0
    x = np.array([[0.3, 0.0]])
    assert kept.kept.gp.basis_vectors.shape == (6, 2)  # as its episode started
    assert agent.gp.n_bv > 6 and kept.kept.gp.predict(x) != agent.gp.predict(x)
    off, stub = KeptQ(False), _stub()
    _episode(off, stub, 1.0)
    assert off.kept is None and off.running is None and off.to_arrays() == {}


def test_nothing_is_copied_in_the_warm_up_or_where_a_map_acts() -> None:
    kept, agent = KeptQ(True), _stub()
    agent.state.scaling_pending = True
    kept.start_episode(agent)  # type: ignore[arg-type]
    assert kept.running is None
    agent.state.scaling_pending, agent.explorer.map = False, object()
    kept.start_episode(agent)  # type: ignore[arg-type]
    assert kept.running is None


@pytest.mark.parametrize("greedy_actions", ["candidates", "data"])
def test_greedy_actions_are_those_of_the_agent_when_the_kept_copy_was_made(
    greedy_actions: str,
) -> None:
    """Oracle: a deep copy of the whole agent taken where the kept episode started (the
    callback of the episode before, or before learning), its own greedy actions; learning
    is the same with ``keep_q`` off, bit for bit, and only the greedy actions differ."""
    settings = {"seed": 2, "explore_map": "off", "max_bv": 50, "greedy_actions": greedy_actions}
    agent = GPQAgent("Pendulum-v1", keep_q="on", **settings)
    snapshots = {0: copy.deepcopy(agent)}

    def snapshot(record: object) -> None:
        snapshots[len(agent.buffer)] = copy.deepcopy(agent)

    agent.learn(800, callback=snapshot)
    kept = agent.kept_q.kept
    assert kept is not None and kept.stored in snapshots
    was = snapshots[kept.stored]
    was.kept_q.kept = None
    many = np.random.default_rng(0).uniform([-1, -1, -8], [1, 1, 8], (64, 3))
    np.testing.assert_array_equal(agent.predict(many)[0], was.predict(many)[0])
    off = GPQAgent("Pendulum-v1", keep_q="off", **settings).learn(800)
    np.testing.assert_array_equal(off.buffer.to_arrays()["a"], agent.buffer.to_arrays()["a"])
    np.testing.assert_array_equal(off.gp.alpha, agent.gp.alpha)
    assert off.kept_q.kept is None
    assert not np.array_equal(agent.predict(many)[0], off.predict(many)[0])


def test_off_is_the_default_and_other_settings_are_refused() -> None:
    assert GPQConfig().for_dims(11, 3).keep_q == "off"  # Hopper-v5's inputs
    assert GPQConfig(keep_q="on").for_dims(3, 1).keep_q == "on"
    assert GPQAgent("Pendulum-v1", seed=0).kept_q.on is False
    with pytest.raises(ValueError, match="keep_q must be one of"):
        GPQConfig(keep_q="auto")  # type: ignore[arg-type]


def test_save_and_load_continue_identically(tmp_path: Path) -> None:
    """The kept copy and its record are saved; a loaded agent acts greedily as
    the original and, learning on, keeps the same copies."""
    a = GPQAgent("Pendulum-v1", seed=1, keep_q="on", explore_map="off", max_bv=50).learn(700)
    assert a.kept_q.kept is not None
    a.save(tmp_path / "a.npz")
    b = GPQAgent.load(tmp_path / "a.npz")
    assert b.kept_q.record == a.kept_q.record and b.kept_q.kept is not None
    np.testing.assert_array_equal(b.predict(OBS)[0], a.predict(OBS)[0])
    a.learn(600)
    b.learn(600)
    assert b.kept_q.kept is not None and b.kept_q.kept.stored == a.kept_q.kept.stored
    np.testing.assert_array_equal(b.predict(OBS)[0], a.predict(OBS)[0])
    np.testing.assert_array_equal(b.gp.alpha, a.gp.alpha)


def test_a_bad_kept_q_archive_is_refused(tmp_path: Path) -> None:
    agent = GPQAgent("Pendulum-v1", seed=1, keep_q="on", explore_map="off", max_bv=50).learn(700)
    path = tmp_path / "a.npz"
    agent.save(path)
    with np.load(path) as f:
        arrays = dict(f)
    for key, value, match in (
        ("kept_q/record", np.array(np.nan), "record"),
        ("kept_q/stored", np.int64(10_000), "stored"),
        ("kept_q/stored", np.float64(3.5), "stored"),
        ("kept_q/scale", np.array([1.0, 1.0]), "scale"),
        ("kept_q/lengthscale", np.array([-1.0]), "lengthscale"),
        ("kept_q/y", np.array([0.0, 0.0]), "y_scale"),
    ):
        np.savez(tmp_path / "bad.npz", **(arrays | {key: value}))
        with pytest.raises(ArchiveError, match=match):
            GPQAgent.load(tmp_path / "bad.npz")
    meta = json.loads(str(arrays["meta"]))
    meta["config"]["keep_q"] = "off"
    np.savez(tmp_path / "off.npz", **(arrays | {"meta": np.asarray(json.dumps(meta))}))
    with pytest.raises(ArchiveError, match="keep_q is off"):
        GPQAgent.load(tmp_path / "off.npz")
    del meta["config"]["keep_q"]  # a file from before keep_q: none kept, as it acted
    old = {k: v for k, v in arrays.items() if not k.startswith("kept_q/")}
    np.savez(tmp_path / "old.npz", **(old | {"meta": np.asarray(json.dumps(meta))}))
    loaded = GPQAgent.load(tmp_path / "old.npz")
    assert loaded.config.keep_q == "off" and loaded.kept_q.kept is None
