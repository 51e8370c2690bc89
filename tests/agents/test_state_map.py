"""The exploration map against oracles: brute-force cell lookup, scipy's shortest paths on
grid worlds whose optimal routes are known in closed form, the kinematic test on
known dynamics."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse
from scipy.sparse.csgraph import shortest_path

from geoq.agents.map_cells import CellTree
from geoq.agents.map_explorer import moves_follow_actions
from geoq.agents.state_map import MapSettings, StateMap

GAMMA = 0.9
ONE_MOVE = MapSettings(side_scale=1.0)  # cells of one move: a grid world's cells


def _discounted_cost(n: np.ndarray) -> np.ndarray:
    """Value of ``n`` steps at reward -1: ``-(1 - gamma^n) / (1 - gamma)``."""
    return -(1 - GAMMA**n) / (1 - GAMMA)


# ----------------------------------------------------------------- the kinematic test
def test_moves_follow_actions_tells_a_pushed_point_from_an_integrator() -> None:
    rng = np.random.default_rng(0)
    A = rng.uniform(-1, 1, (200, 2))
    S = rng.uniform(0, 1, (200, 2))
    pushed = np.clip(S + 0.05 * A + rng.normal(0, 0.002, S.shape), 0, 1)
    blocked = rng.random(200) < 0.1  # a wall: some moves leave the point where it was
    pushed[blocked] = S[blocked]
    assert moves_follow_actions(S, A, pushed)
    # x' = x + v dt, v' = v + a dt: the position's move is the velocity's, not the action's
    X = np.column_stack([rng.uniform(-1, 1, 200), rng.uniform(-1, 1, 200)])
    a = A[:, :1]
    integrated = np.column_stack([X[:, 0] + 0.05 * X[:, 1], X[:, 1] + 0.05 * a[:, 0]])
    assert not moves_follow_actions(X, a, integrated)
    # a dimension that never moves says nothing; nothing moving at all is no kinematic task
    still = np.column_stack([pushed, np.ones(200)])
    assert moves_follow_actions(np.column_stack([S, np.ones(200)]), A, still)
    assert not moves_follow_actions(S, A, S)


# ----------------------------------------------------------------- the cells
def test_cells_locate_every_point_in_the_leaf_whose_box_holds_it() -> None:
    rng = np.random.default_rng(1)
    tree = CellTree(np.zeros(2), np.ones(2), np.array([0.25, 0.5]))
    X = rng.uniform(0, 1, (400, 2))
    tree.locate(X, create=True)
    for _ in range(30):  # random splits of random leaves
        leaf = int(rng.integers(tree.n_leaves))
        dim = int(rng.integers(2))
        lo, hi = tree.leaf_low[leaf, dim], tree.leaf_high[leaf, dim]
        tree.split(leaf, dim, float(lo + rng.uniform(0.1, 0.9) * (hi - lo)))
    leaves = tree.locate(X)
    inside = np.all((X[:, None, :] >= tree.leaf_low) & (X[:, None, :] < tree.leaf_high), axis=2)
    assert np.all(inside.sum(axis=1) == 1)  # the leaves partition the grid cells they cover
    np.testing.assert_array_equal(leaves, np.argmax(inside, axis=1))
    copy = CellTree.from_arrays(tree.to_arrays())
    np.testing.assert_array_equal(copy.locate(X), leaves)
    with pytest.raises(ValueError, match="outside leaf"):
        tree.split(0, 0, float(tree.leaf_high[0, 0]) + 1.0)


def test_a_grid_cell_without_a_point_has_no_leaf() -> None:
    tree = CellTree(np.zeros(1), np.ones(1), np.array([0.1]))
    tree.locate(np.array([[0.05]]), create=True)
    np.testing.assert_array_equal(tree.locate(np.array([[0.05], [0.55]])), [0, -1])


# ----------------------------------------------------------------- grid worlds
MOVES = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])


def _grid_world(n: int, wall_col: int | None, door_row: int, goal: tuple[int, int],
                visited: set[tuple[int, int]] | None = None) -> StateMap:  # fmt: skip
    """An ``n x n`` grid world on the unit square (cell side ``1 / n``, moves of one cell),
    every move tried once from every cell centre in ``visited`` (default: all but the
    goal). A wall between columns ``wall_col`` and ``wall_col + 1`` blocks every row but
    ``door_row`` (the point stays). Reward -1; entering ``goal`` terminates."""
    h = 1.0 / n
    S, K, S2, done = [], [], [], []
    cells = visited if visited is not None else set(itertools.product(range(n), range(n)))
    for (i, j), (k, move) in itertools.product(sorted(cells - {goal}), enumerate(MOVES)):
        ti, tj = min(max(i + int(move[0]), 0), n - 1), min(max(j + int(move[1]), 0), n - 1)
        if wall_col is not None and {i, ti} == {wall_col, wall_col + 1} and j != door_row:
            ti, tj = i, j
        S.append([(i + 0.5) * h, (j + 0.5) * h])
        S2.append([(ti + 0.5) * h, (tj + 0.5) * h])
        K.append(k)
        done.append((ti, tj) == goal)
    S_, S2_ = np.array(S), np.array(S2)
    return StateMap(np.zeros(2), np.ones(2), 0.2 * MOVES, GAMMA, S_, np.array(K),
                    -np.ones(len(K)), S2_, np.array(done), settings=ONE_MOVE)  # fmt: skip


def _steps_to(n: int, wall_col: int | None, door_row: int, targets: list[tuple[int, int]],
              blocked_cells: set[tuple[int, int]] = frozenset()) -> np.ndarray:  # fmt: skip
    """Fewest moves ``[n, n]`` from each cell to any of ``targets`` (scipy's BFS)."""
    idx = {c: a for a, c in enumerate(itertools.product(range(n), range(n)))}
    rows, cols = [], []
    for (i, j), move in itertools.product(itertools.product(range(n), range(n)), MOVES):
        ti, tj = i + int(move[0]), j + int(move[1])
        if not (0 <= ti < n and 0 <= tj < n) or (i, j) in blocked_cells:
            continue
        if wall_col is not None and {i, ti} == {wall_col, wall_col + 1} and j != door_row:
            continue
        rows.append(idx[(i, j)])
        cols.append(idx[(ti, tj)])
    graph = scipy.sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n * n, n * n))
    dist = shortest_path(graph, unweighted=True, indices=[idx[t] for t in targets]).min(axis=0)
    return dist.reshape(n, n)


@pytest.mark.parametrize(("wall_col", "door_row"), [(None, 0), (2, 4), (1, 0)])
def test_the_exploit_plan_values_every_cell_by_its_shortest_route_to_the_goal(
    wall_col: int | None, door_row: int
) -> None:
    n, goal = 6, (5, 0)
    m = _grid_world(n, wall_col, door_row, goal)
    m.plan()
    steps = _steps_to(n, wall_col, door_row, [goal])
    centres = (np.array(list(itertools.product(range(n), range(n)))) + 0.5) / n
    leaves = m.cells.locate(centres)
    want = _discounted_cost(steps.reshape(-1))
    away = np.array([tuple(c) != goal for c in itertools.product(range(n), range(n))])
    np.testing.assert_allclose(m.V_exploit[leaves][away], want[away], atol=2e-3)
    # the greedy move from each cell goes one step down the shortest route
    best, known = m.greedy(centres[away])
    assert known.all()
    for c, choices in zip(centres[away], best, strict=True):
        i, j = (c * n).astype(int)
        for k in np.flatnonzero(choices):
            ti, tj = i + int(MOVES[k, 0]), j + int(MOVES[k, 1])
            assert 0 <= ti < n and 0 <= tj < n and steps[ti, tj] == steps[i, j] - 1, (i, j, k)


@pytest.mark.parametrize(("wall_col", "door_row"), [(None, 0), (2, 4)])
def test_the_greedy_policy_weighs_each_move_by_laplaces_rule_in_closed_form(
    wall_col: int | None, door_row: int
) -> None:
    """Every move tried once from every cell: one that moved works with chance
    ``p = (1 + 1) / (1 + 2)``, and failing leaves the policy standing for good (the least
    return ``lo``), so ``n`` cells from the goal are worth ``a (1 - b^n) / (1 - b)`` with
    ``a = -p + (1 - p) lo`` and ``b = p gamma``; a blocked move is never taken."""
    n, goal = 6, (5, 0)
    m = _grid_world(n, wall_col, door_row, goal)
    m.plan()
    steps = _steps_to(n, wall_col, door_row, [goal]).reshape(-1)
    centres = (np.array(list(itertools.product(range(n), range(n)))) + 0.5) / n
    away = np.array([tuple(c) != goal for c in itertools.product(range(n), range(n))])
    lo, p = m.bounds()[0], 2 / 3
    a, b = -p + (1 - p) * lo, p * GAMMA
    want = a * (1 - b ** steps[away]) / (1 - b)
    Q = m.Q_greedy[m.cells.locate(centres[away])]
    np.testing.assert_allclose(Q.max(axis=1), want, atol=2e-3)
    blocked = np.all(m.S2 == m.S, axis=1)  # into the wall or the border
    assert blocked.any() and np.all(np.isneginf(m.Q_greedy[m.leaf_s[blocked], m.k[blocked]]))


def test_the_explore_plan_heads_for_the_nearest_unvisited_cell() -> None:
    n = 6
    visited = {(i, j) for i in range(3) for j in range(n)} | {(3, 5)}
    m = _grid_world(n, wall_col=2, door_row=5, goal=(5, 0), visited=visited)
    assert not m.done.any()  # no goal seen: every unvisited cell is worth r_max / (1 - gamma)
    m.plan()
    cells = itertools.product(range(n), range(n))
    has_leaf = [c for c in cells if m.cells.locate((np.array([c]) + 0.5) / n)[0] >= 0]
    frontier = [c for c in has_leaf if c not in visited]
    steps = _steps_to(n, 2, 5, frontier)
    for c in sorted(visited):
        leaf = m.cells.locate((np.array([c]) + 0.5) / n)[0]
        np.testing.assert_allclose(m.V_explore[leaf], _discounted_cost(steps[c]), atol=2e-3)
    # from the far corner the explore move heads for the door's frontier
    k = m.explore((np.array([0, 0]) + 0.5) / n, np.random.default_rng(0))
    ti, tj = int(MOVES[k, 0]), int(MOVES[k, 1])
    assert steps[ti, tj] == steps[0, 0] - 1
    # the exploit plan knows no route yet: an unexplored cell is not a goal
    assert not m.greedy(np.array([[0.1, 0.1]]))[1].any()


def test_a_found_goal_beats_the_unexplored_in_the_exploit_plan() -> None:
    n = 6
    visited = {(i, j) for i in range(n) for j in range(3)}  # the bottom half, goal inside
    m = _grid_world(n, wall_col=None, door_row=0, goal=(5, 0), visited=visited)
    m.plan()
    top = m.cells.locate(np.array([[0.5, 0.58]]))[0]  # row 3: unvisited, next to row 2
    assert top >= 0 and m.V_exploit[top] == m.bounds()[0]
    best, known = m.greedy(np.array([[0.5 / n, 2.5 / n]]))  # cell (0, 2), below row 3
    assert known.all()
    assert not best[0, 2]  # moving up into the unexplored is not the greedy move


def test_a_map_saved_as_arrays_plans_and_acts_identically() -> None:
    m = _grid_world(5, wall_col=1, door_row=4, goal=(4, 0))
    m.plan()
    copy = StateMap.from_arrays(m.to_arrays())
    X = np.random.default_rng(2).uniform(0, 1, (50, 2))
    for a, b in zip(m.greedy(X), copy.greedy(X), strict=True):
        np.testing.assert_array_equal(a, b)
    m.observe(np.array([0.1, 0.1]), 0, -1.0, np.array([0.3, 0.1]), False)
    copy.observe(np.array([0.1, 0.1]), 0, -1.0, np.array([0.3, 0.1]), False)
    m.plan()
    copy.plan()
    np.testing.assert_array_equal(m.Q_explore, copy.Q_explore)
    np.testing.assert_array_equal(m.Q_greedy, copy.Q_greedy)
    # a map saved before the cautious greedy policy acts on its exploit plan until it plans
    old = {k: v for k, v in m.to_arrays().items() if k != "Q_greedy"}
    np.testing.assert_array_equal(StateMap.from_arrays(old).Q_greedy, m.Q_exploit)
    bad = m.to_arrays()
    bad["k"] = bad["k"][:-1]
    with pytest.raises(ValueError, match="inconsistent"):
        StateMap.from_arrays(bad)


def test_a_wall_splits_the_cell_it_runs_through() -> None:
    """One candidate moves from the left half of a cell and is blocked from its right
    half (a wall at x = 0.6 inside the cell [0.4, 0.8)): the cell splits between."""
    rng = np.random.default_rng(3)
    S = np.column_stack([rng.uniform(0.0, 1.0, 300), rng.uniform(0.0, 1.0, 300)])
    k = rng.integers(0, 4, 300)
    S2 = np.clip(S + 0.1 * MOVES[k], 0, 1)
    crossing = (k == 0) & (S[:, 0] < 0.6) & (S2[:, 0] >= 0.6)
    S2[crossing] = S[crossing]
    m = StateMap(np.zeros(2), np.ones(2), MOVES, GAMMA, S, k, -np.ones(300), S2,
                 np.zeros(300, dtype=bool), settings=MapSettings(side_scale=4.0))  # fmt: skip
    assert m.cells.n_leaves > m.cells.n_roots  # splits happened
    walls = m.cells.leaf_high[:, 0][np.abs(m.cells.leaf_high[:, 0] - 0.6) < 0.05]
    assert walls.size > 0  # a leaf ends at the wall


def test_a_cell_is_not_cut_across_its_move() -> None:
    """A rightward move blocked from the lower half of a cell and not from the upper
    (by chance, as a few tries can be): no wall blocks a move by its height, so no cut
    is along y, although one at y = 0.2 would separate them exactly; the same outcomes
    by x are cut at x = 0.2."""
    rng = np.random.default_rng(4)
    S = rng.uniform(0.02, 0.38, (40, 2))
    k = np.zeros(40, dtype=np.int64)
    for dim in (1, 0):
        blocked = S[:, dim] < 0.2
        S2 = np.where(blocked[:, None], S, S + 0.1 * MOVES[0])
        m = StateMap(np.zeros(2), np.ones(2), MOVES, GAMMA, S, k, -np.ones(40), S2,
                     np.zeros(40, dtype=bool), settings=MapSettings(side_scale=4.0))  # fmt: skip
        cuts = m.cells.node_threshold[m.cells.node_dim == dim]
        if dim == 1:
            assert cuts.size == 0, cuts
        else:
            assert np.any(np.abs(cuts - 0.2) < 0.02), cuts


def test_the_blocked_moves_kept_up_to_date_match_a_recount_from_scratch() -> None:
    """``observe`` updates one candidate's typical move at a time; the blocked test then
    agrees with every transition's move against its candidate's quantile recounted."""
    rng = np.random.default_rng(6)
    m = _grid_world(5, wall_col=1, door_row=4, goal=(4, 0))
    for i in range(120):
        s, k = rng.uniform(0, 1, 2), int(rng.integers(4))
        s2 = s if rng.random() < 0.3 else np.clip(s + rng.uniform(0.5, 1.5) * 0.2 * MOVES[k], 0, 1)
        if i % 2:  # long moves right: the grid world's one-cell moves right become "blocked"
            s, k = rng.uniform(0, 0.1, 2), 0
            s2 = s + np.array([0.9, 0.0])
        m.observe(s, k, -1.0, s2, False)
    q, fraction = m.settings.quantile, m.settings.blocked_fraction
    dist = [float(np.linalg.norm((b - a) / m.cells.side)) for a, b in zip(m.S, m.S2, strict=True)]
    moves = np.array(dist)
    want = [d < fraction * np.quantile(moves[m.k == k], q) for d, k in zip(dist, m.k, strict=True)]
    np.testing.assert_array_equal(m._blocked(), want)
    assert np.any(want & (m.k == 0) & (moves > 0.5))  # the typical move right has grown
    m.plan()  # the arrays hold plans for the current leaves
    np.testing.assert_array_equal(StateMap.from_arrays(m.to_arrays())._blocked(), want)


def test_a_greedy_failure_seen_splits_the_cell_that_straddles_the_wall() -> None:
    """Leaf aliasing (docs/exploration.md): a wall at x = 0.5, a door at 0.6 <= y < 0.7, and
    no transition from the wall's left in the cell [0.3, 0.6)^2, which straddles it. The
    rightward moves tried from the cell's right part all moved, so the greedy policy at
    (0.45, 0.45) presses into the wall, for good: ``predict`` learns nothing. Once that
    step is observed (in training) the cell splits at the wall, and from the new cell,
    whose only try was blocked, the map knows no route (the GP chooses there)."""
    step = 0.1

    def world(s: np.ndarray, k: int) -> np.ndarray:
        s2 = np.clip(s + step * MOVES[k], 0, 1)
        crosses = (s[0] < 0.5) != (s2[0] < 0.5) and not 0.6 <= s[1] < 0.7
        return s.copy() if crosses else s2

    rng = np.random.default_rng(0)
    S = rng.uniform(0, 1, (1500, 2))
    S = S[
        (S[:, 0] < 0.85)
        & ~((S[:, 0] >= 0.3) & (S[:, 0] < 0.5) & (S[:, 1] >= 0.3) & (S[:, 1] < 0.6))
    ]
    k = rng.integers(0, 4, len(S))
    S2 = np.array([world(s, int(a)) for s, a in zip(S, k, strict=True)])
    m = StateMap(np.zeros(2), np.ones(2), step * MOVES, GAMMA, S, k, -np.ones(len(S)), S2,
                 S2[:, 0] >= 0.85, settings=MapSettings())  # fmt: skip
    start = np.array([0.45, 0.45])
    m.plan()
    best, known = m.greedy(start[None])
    assert known[0] and best[0, 0] and np.array_equal(world(start, 0), start)  # into the wall
    m.observe(start, 0, -1.0, world(start, 0), False)
    m.plan()
    leaf = m.cells.locate(start[None])[0]
    assert 0.45 < m.cells.leaf_high[leaf, 0] <= 0.5  # the cell now ends at the wall
    assert not m.greedy(start[None])[1][0]


# ----------------------------------------------------------------- halving in a declared box
def test_with_nothing_in_reach_the_visited_leaves_halve_down_to_the_least_width() -> None:
    """A line of ten cells, each left from its centre by both moves, no termination: no
    frontier is in reach. In the declared box every visited leaf is halved at its middle
    until the halves would be narrower than ``min_split_fraction`` (1/16 of a cell: four
    rounds); a half nothing started from, out of reach, is not halved again."""
    h, moves = 0.125, np.array([[1.0], [-1.0]])  # binary fractions: no rounding
    centres = (np.arange(10) + 0.5) * h
    i, k = np.repeat(np.arange(10), 2), np.tile([0, 1], 10)
    S, S2 = centres[i, None], centres[np.clip(i + 1 - 2 * k, 0, 9), None]  # the same floats
    box = (np.zeros(1), np.full(1, 10 * h))
    args = (*box, h * moves, GAMMA, S, k, -np.ones(20), S2, np.zeros(20))
    m = StateMap(*args, settings=ONE_MOVE, declared_box=True)
    m.plan()
    assert m.halvings == 4 and m.cells.n_leaves == 10 * (1 + 4)
    width = (m.cells.leaf_high - m.cells.leaf_low)[:, 0] / h
    for w, count in ((1 / 2, 10), (1 / 4, 10), (1 / 8, 10), (1 / 16, 20)):
        assert np.sum(width == w) == count
    visited = m.cells.locate(centres[:, None])
    np.testing.assert_array_equal(width[visited], 1 / 16)
    # the data's range (no declared box): nothing is halved
    undeclared = StateMap(*args, settings=ONE_MOVE)
    undeclared.plan()
    assert undeclared.halvings == 0 and undeclared.cells.n_leaves == 10
    saved = StateMap.from_arrays(m.to_arrays())
    assert saved.declared_box and saved.halvings == 4
    old = m.to_arrays()
    old["counters"] = old["counters"][:4]  # a map saved before the halving
    assert not StateMap.from_arrays(old).declared_box


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_the_explore_plan_finds_a_goal_smaller_than_its_cells(seed: int) -> None:
    """An open square, eight moves of 0.05 (cells 0.15 wide), a goal disc of radius 0.025
    and episodes of 100 steps from random starts, acting only on the explore plan. Once
    every cell has been left from, halving gives the plan somewhere new to go: the goal is
    found within 1,000 steps (without the declared box, seed 1 has not found it in 3,000)."""
    angle = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    C = 0.05 * np.column_stack([np.cos(angle), np.sin(angle)])
    goal, rng = np.array([0.83, 0.27]), np.random.default_rng(seed)
    S = rng.uniform(0, 1, (16, 2))
    k = rng.integers(0, 8, 16)
    S2 = np.clip(S + C[k], 0, 1)
    m = StateMap(np.zeros(2), np.ones(2), C, 0.99, S, k, -np.ones(16), S2,
                 np.hypot(*(S2 - goal).T) < 0.025, declared_box=True)  # fmt: skip
    s, found = rng.uniform(0, 1, 2), None
    for n in range(1000):
        a = m.explore(s, rng)
        s2 = np.clip(s + C[a] + rng.normal(0, 0.005, 2), 0, 1)
        m.observe(s, a, -1.0, s2, bool(np.hypot(*(s2 - goal)) < 0.025))
        if m.done.any():
            found = n
            break
        s = s2 if (n + 1) % 100 else rng.uniform(0, 1, 2)
    assert found is not None and m.halvings >= 1


# ----------------------------------------------------------------- nearest tries
def test_the_nearest_tries_match_a_brute_force_search() -> None:
    rng = np.random.default_rng(4)
    C = 0.1 * np.array([[1.0, 0.0], [0.8, 0.6], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    S = np.round(rng.uniform(0, 1, (300, 2)), 2)  # repeated starts: ties in distance
    k = rng.integers(0, 5, 300)
    S2 = np.clip(S + C[k], 0, 1)
    S2 = np.where((rng.random(300) < 0.3)[:, None], S, S2)  # some tries blocked
    m = StateMap(np.zeros(2), np.ones(2), C, GAMMA, S, k, -np.ones(300), S2, np.zeros(300))
    X = np.vstack([np.round(rng.uniform(0, 1, (40, 2)), 2), S[:20]])
    near, blocked = m._nearest_tries(X)
    unit = C / np.linalg.norm(C, axis=1, keepdims=True)
    radius, is_blocked, scaled = m._typical.max(), m._blocked(), S / m.cells.side
    assert near.any() and blocked.any() and not blocked.all()
    for i, x in enumerate(X / m.cells.side):
        for c in range(5):
            tries = [j for j in range(300) if unit[c] @ unit[k[j]] >= 0.7
                     and np.linalg.norm(scaled[j] - x) <= radius]  # fmt: skip
            assert near[i, c] == bool(tries)
            if tries:
                d = min(np.linalg.norm(scaled[j] - x) for j in tries)
                nearest = [j for j in tries if np.linalg.norm(scaled[j] - x) == d]
                assert blocked[i, c] == any(is_blocked[j] for j in nearest)


def test_the_greedy_policy_weighs_each_move_by_its_nearest_try() -> None:
    """A line, moves of 0.1 right (0) and left (1): right moved from 0.30 and was blocked
    from 0.52, left moved from 0.75. At 0.55 the nearest right try was blocked, so the
    policy goes left whatever the plan says; at 0.33 no left try is within a move, so left
    counts half its value above the least return (-10): -7 against right's -5."""
    S, k = np.array([[0.30], [0.52], [0.75]]), np.array([0, 0, 1])
    S2 = np.array([[0.40], [0.52], [0.65]])
    m = StateMap(np.zeros(1), np.ones(1), np.array([[0.1], [-0.1]]), GAMMA, S, k,
                 -np.ones(3), S2, np.zeros(3), settings=ONE_MOVE)  # fmt: skip
    m.plan()
    assert np.isclose(m.bounds()[0], -10.0)
    for s, q, nearest, plain in (([0.55], [-1.0, -9.0], [False, True], [True, False]),
                                 ([0.33], [-5.0, -4.0], [True, False], [False, True])):  # fmt: skip
        m.Q_greedy[m.cells.locate(np.array([s]))[0]] = q
        np.testing.assert_array_equal(m.greedy(np.array([s]))[0][0], nearest)
        m.settings = MapSettings(side_scale=1.0, nearest_tries=False)
        np.testing.assert_array_equal(m.greedy(np.array([s]))[0][0], plain)
        m.settings = ONE_MOVE
