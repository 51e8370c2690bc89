"""A saved agent's config edited by hand (``meta["config"]`` of the ``.npz``).

The rule: loading resolves the stored config exactly as a new agent's is
(:meth:`GPQConfig.for_dims`: ``"auto"``, ``max_bv: null``), so a file edited to the
settings it was made with loads and continues bit for bit; a config that contradicts
the rest of the file (the GP's budget, noise, kernel, the fitted length-scales, the
map) is an :class:`ArchiveError` that names the field. Before, ``prior: "auto"``
loaded and acted as ``midrange``, ``hyperparameters: "auto"`` stopped the evidence
fits, and ``max_bv: null`` loaded and then failed with a bare ``AssertionError``.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tests._fuzz import fuzz_settings
from tests.agents._tasks import PointToGoal, PointToGoalWithDistractors

from geoq._io import ArchiveError
from geoq.agents import GPQAgent, GPQConfig

FUZZ = fuzz_settings(40)

#: name -> (env factory, GPQAgent arguments): default budgets (``max_bv: null`` resolves
#: to the GP's), 1 + 1 inputs (``rule``, ``optimistic``, a map) and 5 + 1 (``evidence``,
#: ``empirical``, fitted length-scales), and a graph kernel.
AGENTS: dict[str, tuple[Callable[[], gymnasium.Env], dict[str, Any]]] = {
    "point": (PointToGoal, {}),
    "distractors": (lambda: PointToGoalWithDistractors(extra=4), {}),
    "nearest": (PointToGoal, {"kernel": "nearest", "max_bv": 30}),
}


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[GPQAgent, Path]]:
    """Each of :data:`AGENTS` after 60 steps, and its file."""
    out = {}
    for name, (make_env, kwargs) in AGENTS.items():
        agent = GPQAgent(make_env(), seed=0, gamma=0.9, **kwargs).learn(60)
        path = tmp_path_factory.mktemp(name) / "agent.npz"
        agent.save(path)
        out[name] = (agent, path)
    agent = out["distractors"][0]
    assert (agent.config.hyperparameters, agent.config.prior) == ("evidence", "empirical")
    assert agent.state.fitted_lengthscale is not None
    assert out["point"][0].explorer.map is not None
    return out


def _edited(path: Path, out: Path, **changes: Any) -> Path:
    """``path`` with its config's fields set to ``changes``."""
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(str(arrays["meta"]))
    meta["config"].update(changes)
    arrays["meta"] = np.asarray(json.dumps(meta))
    np.savez(out, **arrays)
    return out


def _continue(agent: GPQAgent, steps: int) -> dict[str, Any]:
    """What ``steps`` more steps leave: transitions, targets, weights, generator, actions."""
    agent.learn(steps)
    obs = np.linspace(-1, 1, 7)[:, None] * np.ones((1, agent.obs_dim))
    return {
        "buffer": agent.buffer.arrays(last=None), "targets": agent.buffer.targets(),
        "alpha": agent.gp.alpha, "rng": agent.rng.bit_generator.state,
        "episodes": agent.log.episodes_array(), "actions": agent.predict(obs)[0],
        "fits": agent.log.evidence_fits, "sweeps": agent.log.fitted_q_sweeps,
    }  # fmt: skip


@pytest.mark.parametrize("name", ["point", "distractors"])
@pytest.mark.parametrize(
    "changes",
    [{"prior": "auto"}, {"hyperparameters": "auto"}, {"max_bv": None},
     {"prior": "auto", "hyperparameters": "auto", "max_bv": None}],
)  # fmt: skip
def test_auto_and_null_resolve_as_a_new_agents_and_continue_bit_for_bit(
    name: str, changes: dict[str, Any], saved: dict[str, tuple[GPQAgent, Path]], tmp_path: Path
) -> None:
    agent, path = saved[name]
    make_env, kwargs = AGENTS[name]
    loaded = GPQAgent.load(_edited(path, tmp_path / "edited.npz", **changes), env=make_env())
    assert loaded.config == agent.config  # resolved: no "auto", max_bv a number
    fresh = GPQAgent(make_env(), seed=0, gamma=0.9, **{**kwargs, **changes})
    assert fresh.config == loaded.config  # exactly what a new agent of those settings holds
    twin = GPQAgent.load(path, env=make_env())
    a, b = _continue(twin, 40), _continue(loaded, 40)
    assert a.keys() == b.keys()
    for key in a:
        if isinstance(a[key], tuple):
            for x, y in zip(a[key], b[key], strict=True):
                np.testing.assert_array_equal(x, y, err_msg=key)
        elif isinstance(a[key], np.ndarray):
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        else:
            assert a[key] == b[key], key
    if name == "distractors":  # the evidence fits went on
        assert loaded.log.evidence_fits[-1]["transitions"] == 100


@pytest.mark.parametrize(
    ("name", "changes", "field"),
    [("point", {"max_bv": 20}, "max_bv"), ("nearest", {"max_bv": None}, "max_bv"),
     ("point", {"noise": 0.02}, "noise"), ("point", {"tol": 1e-4}, "tol"),
     ("point", {"amplitude": 2.0}, "amplitude"), ("point", {"kernel": "nearest"}, "kernel"),
     ("nearest", {"kernel": "interpolated"}, "kernel"),
     ("nearest", {"kernel": "resistance"}, "kernel"), ("nearest", {"eps": 0.5}, "eps"),
     ("nearest", {"sigma_sp": 0.1}, "sigma_sp"), ("point", {"lengthscale": 0.3}, "lengthscale"),
     ("point", {"state_lengthscale": 0.2}, "state_lengthscale"),
     ("point", {"action_lengthscale": 0.5}, "action_lengthscale"),
     ("distractors", {"hyperparameters": "rule"}, "hyperparameters"),
     ("distractors", {"lengthscale": [0.3, 0.3]}, "lengthscale has 2 entries"),
     ("point", {"n_candidates": 5}, "n_candidates"),
     ("point", {"explore_map": "off"}, "explore_map")],
)  # fmt: skip
def test_a_config_the_file_contradicts_is_refused_by_name(
    name: str, changes: dict[str, Any], field: str,
    saved: dict[str, tuple[GPQAgent, Path]], tmp_path: Path,
) -> None:  # fmt: skip
    _, path = saved[name]
    edited = _edited(path, tmp_path / "edited.npz", **changes)
    with pytest.raises(ArchiveError, match=f"inconsistent GPQAgent archive.*{field}"):
        GPQAgent.load(edited, env=AGENTS[name][0]())


def test_an_evidence_agent_edited_to_auto_on_covered_inputs_is_refused(tmp_path: Path) -> None:
    """``auto`` on 1 + 1 inputs resolves to ``rule``: fitted length-scales contradict it."""
    agent = GPQAgent(PointToGoal(), seed=0, max_bv=30, hyperparameters="evidence").learn(40)
    assert agent.state.fitted_lengthscale is not None
    agent.save(tmp_path / "agent.npz")
    edited = _edited(tmp_path / "agent.npz", tmp_path / "edited.npz", hyperparameters="auto")
    with pytest.raises(ArchiveError, match="fitted_lengthscale is set but config hyperparameters"):
        GPQAgent.load(edited, env=PointToGoal())


EDITS: dict[str, list[Any]] = {
    "prior": ["auto", "midrange", "optimistic", "empirical", "bogus"],
    "hyperparameters": ["auto", "rule", "evidence"],
    "max_bv": [None, 30, 400, 800, 20, 0, 2.5],
    "kernel": ["euclidean", "nearest", "interpolated", "resistance"],
    "amplitude": [1.0, 2.0], "noise": [0.01, 0.02], "tol": [1e-6, 1e-4],
    "lengthscale": [None, 0.3, [0.15, 0.6], [0.1, 0.2, 0.3], -1.0],
    "state_lengthscale": [0.15, 0.2], "action_lengthscale": [0.6, 0.5],
    "eps": [0.3, 0.5], "sigma_sp": [0.03, 0.1], "n_candidates": [21, 5],
    "explore_map": ["auto", "on", "off"], "gamma": [0.9, 0.5],
}  # fmt: skip


@FUZZ
@given(
    name=st.sampled_from(sorted(AGENTS)),
    changes=st.dictionaries(st.sampled_from(sorted(EDITS)), st.none(), min_size=1, max_size=3),
    data=st.data(),
)
def test_an_edited_config_loads_resolved_and_consistent_or_is_refused_by_name(
    name: str, changes: dict[str, Any], data: st.DataObject,
    saved: dict[str, tuple[GPQAgent, Path]], tmp_path_factory: pytest.TempPathFactory,
) -> None:  # fmt: skip
    changes = {k: data.draw(st.sampled_from(EDITS[k]), label=k) for k in changes}
    agent, path = saved[name]
    make_env = AGENTS[name][0]
    edited = _edited(path, tmp_path_factory.mktemp("edited") / "agent.npz", **changes)
    try:
        loaded = GPQAgent.load(edited, env=make_env())
    except ArchiveError as exc:
        assert "GPQAgent archive" in str(exc)
        assert any(field in str(exc) for field in changes), (changes, str(exc))
        return
    c = loaded.config
    assert c.max_bv == loaded.gp.max_bv and "auto" not in (c.hyperparameters, c.prior)
    stored = {**agent.config.as_dict(), **changes}
    assert c == GPQConfig.from_dict(stored).for_dims(agent.obs_dim, agent.action_dim)
    loaded.learn(20)  # no AssertionError, no IndexError: the agent is whole
    again = tmp_path_factory.mktemp("again") / "agent.npz"
    loaded.save(again)
    assert GPQAgent.load(again, env=make_env()).config == c
