"""The exploration map under hostile input (hardening round 3): wide, degenerate and
huge declared boxes, constant features, relabelled action boxes, failure ends, plans read
inside ``learn``'s callbacks, damaged map arrays and the map's own classes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.agents._tasks import MovingPoint, TwoRoomsWithPit

import geoq  # noqa: F401  (registers the envs)
from geoq._io import ArchiveError
from geoq.agents import GPQAgent
from geoq.agents.map_cells import CellTree, around_sums
from geoq.agents.state_map import MapSettings, StateMap

F32_MAX = float(np.finfo(np.float32).max)


def _dense_around(a: np.ndarray) -> np.ndarray:
    """The dense grid's ``3^d`` neighbourhood sums (the map's sums before the sparse grid)."""
    out = a
    for ax in range(a.ndim - 1):
        pad = [(1, 1) if i == ax else (0, 0) for i in range(a.ndim)]
        p, n = np.pad(out, pad), out.shape[ax]
        shifted = [p[tuple(slice(s, s + n) if i == ax else slice(None) for i in range(a.ndim))]
                   for s in range(3)]  # fmt: skip
        out = shifted[0] + shifted[1] + shifted[2]
    return out


@settings(max_examples=60, deadline=None)
@given(st.data())
def test_the_neighbourhood_sums_are_a_dense_grids_bit_for_bit(data: st.DataObject) -> None:
    d = data.draw(st.integers(1, 4))
    shape = data.draw(st.lists(st.integers(1, 5), min_size=d, max_size=d))
    size = int(np.prod(shape))
    flat = np.arange(size)
    cells_at = data.draw(st.lists(st.sampled_from(flat.tolist()), min_size=1, unique=True))
    data_at = data.draw(st.lists(st.sampled_from(cells_at), min_size=0, unique=True))
    w = data.draw(st.integers(1, 3))
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    values = rng.normal(size=(len(data_at), w)) * 10.0 ** rng.integers(-8, 8, (len(data_at), 1))
    tree = CellTree(np.zeros(d), np.asarray(shape, dtype=np.float64), np.ones(d))
    roots = np.stack(np.unravel_index(np.asarray(cells_at), shape), axis=1)
    tree.locate(roots + 0.5, create=True)
    starts = np.stack(np.unravel_index(np.asarray(data_at, dtype=np.int64), shape), axis=1)
    dense = np.zeros((*shape, w))
    dense[tuple(starts.T)] = values
    expected = _dense_around(dense)[tuple(tree.root_grid.T)]
    got = around_sums(tree, starts.reshape(-1, d).astype(np.int64), values)
    np.testing.assert_array_equal(got, expected)  # the same bits, not only close


@pytest.mark.parametrize(
    "kw",
    [{"obs_low": -1e5, "obs_high": 1e5}, {"obs_low": -F32_MAX, "obs_high": F32_MAX},
     {"d": 3, "obs_low": -1e3, "obs_high": 1e3}, {"obs_low": -1e300, "obs_high": 1e300},
     {"constant": 48}, {"constant": 20, "obs_low": -1e4, "obs_high": 1e4}],
)  # fmt: skip
def test_the_map_follows_the_cells_visited_not_the_declared_box(kw: dict[str, Any]) -> None:
    """Before: ``MemoryError`` from +-1e3 on (a dense grid over the declared box), minutes
    at +-100, and a neighbourhood sum over ``3^d`` cells with constant features."""
    agent = GPQAgent(MovingPoint(**kw), seed=0, explore_map="on").learn(100)
    m = agent.explorer.map
    assert m is not None
    distinct = len(np.unique(m.cells.grid_coords(np.vstack([m.S, m.S2])), axis=0))
    assert m.cells.n_roots <= distinct and m.cells.n_leaves <= 4 * m.n_transitions
    assert sum(a.nbytes for a in m.cells.to_arrays().values()) < 2_000_000
    leaves = m.cells.locate(m.S)
    assert np.all(leaves >= 0)
    in_box = np.all((m.cells.low <= m.S) & (m.S < m.cells.high), axis=1)
    holds = (m.cells.leaf_low[leaves] <= m.S) & (m.S < m.cells.leaf_high[leaves])
    assert in_box.sum() > 50 and holds[in_box].all()  # the leaf whose box holds it


@pytest.mark.parametrize("value", [5e5, 0.0, -3.0, 1e12])
def test_a_dimension_declared_with_low_equal_to_high_is_one_cell_wide(value: float) -> None:
    env = MovingPoint(constant=1, constant_value=value, obs_low=[-1, -1, value],
                      obs_high=[1, 1, value])  # fmt: skip
    agent = GPQAgent(env, seed=0, explore_map="on").learn(100)
    m = agent.explorer.map
    assert m is not None and set(m.cells.root_grid[:, 2].tolist()) == {0}
    agent.predict(env.reset(seed=1)[0])


def test_no_leaf_is_halved_along_a_dimension_nothing_moved_along() -> None:
    """With nothing left to explore the visited leaves are halved, along the moving
    dimensions only: a constant feature's halves are never reached."""
    rng = np.random.default_rng(0)
    S = np.column_stack([rng.uniform(0, 1, 400), np.full(400, 0.3)])
    step = rng.choice([-0.05, 0.05], 400)
    S2 = np.column_stack([np.clip(S[:, 0] + step, 0, 1), S[:, 1]])
    k = (step > 0).astype(np.int64)
    m = StateMap(np.zeros(2), np.ones(2), np.array([[-1.0, 0], [1.0, 0]]), 0.9, S, k,
                 -np.ones(400), S2, np.zeros(400, bool), declared_box=True)  # fmt: skip
    m.plan()
    assert m.halvings > 0
    split = m.cells.node_dim[m.cells.node_dim >= 0]
    assert split.size and np.all(split == 0)


def _relabelled(low: float, high: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    env = MovingPoint(goal=(0.6, 0.6), start=(-0.6, -0.6), step=0.1, radius=0.2, limit=60,
                      action_low=low, action_high=high)  # fmt: skip
    agent = GPQAgent(env, seed=seed, max_bv=60).learn(400)
    assert agent.explorer.map is not None
    mid, half = 0.5 * (low + high), 0.5 * (high - low)
    X = np.random.default_rng(0).uniform(-1, 1, (100, 2))
    return (agent.buffer.arrays()[1] - mid) / half, (agent.predict(X)[0] - mid) / half


@pytest.mark.parametrize("box", [(0.0, 1.0), (-3.0, 5.0)])
def test_a_relabelled_action_box_learns_and_acts_alike(box: tuple[float, float]) -> None:
    """The same physics with the action box ``[0, 1]`` for ``[-1, 1]``: before, moves were
    compared in raw coordinates (all of ``[0, 1]^2`` points one way: 16 of 64 opposite pairs
    counted alike) and the greedy actions differed by up to 1.9 half-ranges."""
    actions, greedy = _relabelled(-1.0, 1.0, seed=1)
    actions2, greedy2 = _relabelled(*box, seed=1)
    np.testing.assert_allclose(actions2, actions, atol=1e-9)
    np.testing.assert_allclose(greedy2, greedy, atol=1e-9)


def test_opposite_moves_are_never_alike_whatever_the_box() -> None:
    agent = GPQAgent(MovingPoint(action_low=0.0, action_high=1.0), seed=0)
    c = agent.explorer.centred
    np.testing.assert_allclose(c, agent.candidates * 2 - 1)
    unit = c / np.linalg.norm(c, axis=1, keepdims=True)
    opposite = unit @ unit.T < -0.7
    assert opposite.any() and not (opposite & (unit @ unit.T >= MapSettings().blocked_cos)).any()


def test_a_failure_end_is_evidence_about_its_place_not_a_goal() -> None:
    """A pit (reward -100, the episode ends) seen first: the frontier stays optimistic,
    no route is known, and a goal seen later is a goal."""
    S = np.array([[0.1, 0.1], [0.2, 0.1], [0.3, 0.1]])
    S2 = S + np.array([0.1, 0.0])
    m = StateMap(np.zeros(2), np.ones(2), np.array([[1.0, 0], [-1.0, 0]]), 0.9, S,
                 np.zeros(3, np.int64), [-1.0, -1.0, -100.0], S2, [False, False, True])  # fmt: skip
    assert m._frontier() == m.bounds()[1] == 0.0
    m.plan()
    assert not m.knows_route(m.cells.locate(S)).any()
    m.observe(np.array([0.6, 0.5]), 0, -1.0, np.array([0.7, 0.5]), True)  # a goal
    assert m._frontier() == -1.0
    assert m.bounds()[0] == pytest.approx(
        -10.0
    )  # standing still for good, not the pit's -100 / (1 - gamma)


@pytest.mark.parametrize("seed", [1, 3])
def test_a_pit_hit_early_does_not_stop_the_search_for_the_goal(seed: int) -> None:
    """TwoRooms with a pit off the route: on these seeds it is hit by step 100; before,
    the goal was then found 0 times in 1,500 steps (the frontier was worth the pit)."""
    agent = GPQAgent(TwoRoomsWithPit(), seed=seed, max_bv=100).learn(700)
    _, _, r, _, t = agent.buffer.arrays()
    assert np.flatnonzero(t & (r < -50))[0] < 100  # the pit came first
    assert sum(e.success for e in agent.episodes) >= 3


def test_predict_and_save_in_a_callback_see_the_current_plan(tmp_path: Path) -> None:
    """Before: inside ``learn``'s callbacks the plans were those of before the episode's
    last moves (an ``IndexError`` at a new leaf, files that did not load)."""
    X = np.random.default_rng(0).uniform(0, 1, (40, 2))
    seen: list[tuple[np.ndarray, np.ndarray]] = []

    def check(_: Any) -> None:
        path = tmp_path / f"at{len(seen)}.npz"
        agent.save(path)
        loaded = GPQAgent.load(path)
        seen.append((agent.predict(X)[0], loaded.predict(X)[0]))

    agent = GPQAgent("geoq/TwoRooms-v0", seed=0, max_bv=60)
    agent.learn(600, callback=check)
    plain = GPQAgent("geoq/TwoRooms-v0", seed=0, max_bv=60).learn(600)
    assert len(seen) >= 3
    for here, there in seen:
        np.testing.assert_array_equal(here, there)
    for a, b in zip(agent.buffer.arrays(), plain.buffer.arrays(), strict=True):
        np.testing.assert_array_equal(a, b)  # the callback changed nothing


# ---------------------------------------------------------------- damaged map arrays
def _saved_with_map(tmp_path: Path) -> tuple[Path, dict[str, np.ndarray]]:
    agent = GPQAgent(MovingPoint(goal=(0.5, 0.5)), seed=0, max_bv=40).learn(200)
    assert agent.explorer.map is not None
    path = tmp_path / "agent.npz"
    agent.save(path)
    with np.load(path, allow_pickle=False) as npz:
        return path, {k: npz[k] for k in npz.files}


def _cycle(a: dict[str, np.ndarray]) -> None:
    """The first root's node made a split whose both sides are itself."""
    node = a["explorer/map/cells/root_node"][0]
    a["explorer/map/cells/node_dim"][node] = 0
    a["explorer/map/cells/node_low"][node] = a["explorer/map/cells/node_high"][node] = node


DAMAGE = {
    "cell index": lambda a: a["explorer/map/leaf_s"].__setitem__(0, 10**6),
    "split dimension": lambda a: a["explorer/map/cells/node_dim"].__setitem__(0, 7),
    "negative root": lambda a: a["explorer/map/cells/root_node"].__setitem__(0, -3),
    "root off the grid": lambda a: a["explorer/map/cells/root_grid"].__setitem__((0, 0), -(2**60)),
    "NaN value": lambda a: a["explorer/map/V_explore"].__setitem__(0, np.nan),
    "NaN Q": lambda a: a["explorer/map/Q_greedy"].__setitem__((0, 0), np.nan),
    "other candidates": lambda a: a["explorer/map/candidates"].__setitem__((0, 0), 0.123),
    "other choice": lambda a: a["explorer/map/k"].__setitem__(0, 10**4),
    "a cycle": _cycle,
    "leaf boxes": lambda a: a["explorer/map/cells/leaf_high"].__setitem__((0, 0), -5.0),
    "counters": lambda a: a["explorer/map/counters"].__setitem__(0, 1.5),
    "decided": lambda a: a.__setitem__("explorer/decided", np.array(7)),
}


@pytest.mark.parametrize("name", sorted(DAMAGE))
def test_a_damaged_map_array_is_an_archive_error_at_load(name: str, tmp_path: Path) -> None:
    _, arrays = _saved_with_map(tmp_path)
    DAMAGE[name](arrays)
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    with pytest.raises(ArchiveError, match=r"exploration.map"):
        GPQAgent.load(bad, env=MovingPoint(goal=(0.5, 0.5)))


def test_a_stored_map_with_explore_map_off_is_refused(tmp_path: Path) -> None:
    import json

    _, arrays = _saved_with_map(tmp_path)
    meta = json.loads(str(arrays["meta"]))
    meta["config"]["explore_map"] = "off"
    arrays["meta"] = np.asarray(json.dumps(meta))
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    with pytest.raises(ArchiveError, match="explore_map is 'off'"):
        GPQAgent.load(bad)


def test_a_map_saved_with_stale_plans_loads_and_continues_as_the_original(
    tmp_path: Path,
) -> None:
    """A file written by the code before (plans behind the leaves inside a callback)."""
    agent = GPQAgent(MovingPoint(goal=(0.5, 0.5)), seed=0, max_bv=40).learn(200)
    m = agent.explorer.map
    assert m is not None
    m.observe(m.S[-1] + [0.9, 0.9], 0, -1.0, m.S[-1] + [0.95, 0.9], False)  # a new leaf
    arrays = {k[4:]: v for k, v in agent.explorer.to_arrays().items() if k.startswith("map/")}
    assert arrays["V_explore"].shape[0] == m.cells.n_leaves
    stale = {**arrays, "V_explore": arrays["V_explore"][:-1], "Q_explore": arrays["Q_explore"][:-1]}
    stale["counters"] = stale["counters"].copy()
    stale["counters"][1] = 1.0
    StateMap.from_arrays(stale).plan()
    with pytest.raises(ValueError, match="rows"):
        stale["counters"][1] = 0.0
        StateMap.from_arrays(stale)


# ---------------------------------------------------------------- the map's classes
@pytest.mark.parametrize(
    "kw",
    [{"gamma": 1.0}, {"states": np.zeros((0, 2))}, {"choices": [-1, 0]},
     {"choices": [0, 0, 0]}, {"rewards": [np.nan, 0.0]}, {"terminated": [2, 0]},
     {"next_states": np.zeros((3, 2))}, {"candidates": np.zeros((0, 2))},
     {"low": [0.0, np.nan]}, {"low": [2.0, 0.0]}, {"declared_box": "yes"}],
)  # fmt: skip
def test_state_map_refuses_bad_input_with_a_value_error(kw: dict[str, Any]) -> None:
    args: dict[str, Any] = {
        "low": np.zeros(2), "high": np.ones(2), "candidates": np.eye(2), "gamma": 0.9,
        "states": np.full((2, 2), 0.5), "choices": [0, 1], "rewards": [-1.0, -1.0],
        "next_states": np.full((2, 2), 0.6), "terminated": [False, False],
    }  # fmt: skip
    args.update(kw)
    with pytest.raises(ValueError):
        StateMap(**args)


@pytest.mark.parametrize(
    "kw",
    [{"quantile": 1.5}, {"quantile": 0.0}, {"side_scale": -1.0}, {"blocked_cos": 2.0},
     {"max_macro": 0}, {"max_sweeps": 2.5}, {"tol": 0.0}, {"route_margin": 1.0},
     {"min_split_fraction": 0.0}, {"nearest_tries": "no"}, {"blocked_fraction": np.nan}],
)  # fmt: skip
def test_map_settings_refuse_values_out_of_range(kw: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match=next(iter(kw))):
        MapSettings(**kw)


def test_observe_refuses_a_bad_transition() -> None:
    m = StateMap(np.zeros(2), np.ones(2), np.eye(2), 0.9, np.full((2, 2), 0.5), [0, 1],
                 [-1.0, -1.0], np.full((2, 2), 0.6), [False, False])  # fmt: skip
    for bad in ({"k": 2}, {"k": -1}, {"s": np.zeros(3)}, {"r": np.inf}, {"s2": [np.nan, 0]}):
        args: dict[str, Any] = {"s": np.zeros(2), "k": 0, "r": -1.0, "s2": np.ones(2),
                                "terminated": False, **bad}  # fmt: skip
        with pytest.raises(ValueError):
            m.observe(**args)
    assert m.n_transitions == 2


def test_cell_tree_refuses_a_bad_box_and_bad_splits() -> None:
    with pytest.raises(ValueError, match="low <= high"):
        CellTree(np.ones(2), np.zeros(2), np.ones(2))
    with pytest.raises(ValueError, match="finite"):
        CellTree(np.zeros(2), np.array([1.0, np.inf]), np.ones(2))
    tree = CellTree(np.zeros(2), np.ones(2), np.full(2, 0.5))
    tree.locate(np.array([[0.1, 0.1]]), create=True)
    for leaf, dim, cut in ((5, 0, 0.2), (0, 2, 0.2), (0, -1, 0.2), (0, 0, 0.9)):
        with pytest.raises(ValueError):
            tree.split(leaf, dim, cut)
