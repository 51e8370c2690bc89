"""GPQConfig: every setting resolved and validated once, with one message per rule."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from tests._fuzz import fuzz_settings
from tests.agents._tasks import PointToGoal, PointToGoalWithDistractors, PointToGoalWithIdleAction

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent, GPQConfig
from geoq.agents._evidence import blind_actions
from geoq.agents.config import default_max_bv, rule_coverage
from geoq.agents.replay import GraphReplay, NoReplay, UniformReplay
from geoq.agents.state import LearningState, TrainingLog
from geoq.kernels import (
    KERNEL_NAMES,
    GeodesicKernel,
    ResistanceKernel,
    SquaredExponential,
    make_kernel,
)

FUZZ = fuzz_settings(60)


def test_max_bv_has_one_rule_in_the_config_the_agent_and_the_gp() -> None:
    message = r"max_bv must be an integer in \[1, 5000\]"
    for bad in (0, 6000, 2.5, True):
        with pytest.raises(ValueError, match=message):
            GPQConfig(max_bv=bad)
        with pytest.raises(ValueError, match=message):
            GPQAgent(PointToGoal(), max_bv=bad)
    assert GPQConfig().max_bv is None
    assert GPQConfig().for_dims(1, 1).max_bv == 400
    assert GPQConfig().for_dims(3, 2).max_bv == 800
    assert GPQAgent(PointToGoal()).config.max_bv == 400  # resolved once, stored once


def test_rule_coverage_counts_how_often_the_basis_tiles_the_box() -> None:
    # Four squares of half-side 0.5 tile [-1, 1]^2 exactly; a length-scale past the
    # box's half-range covers it whole along that input.
    assert rule_coverage(np.array([0.5, 0.5]), 4) == 1.0
    assert rule_coverage(np.array([3.0, 0.5]), 4) == 2.0
    assert rule_coverage(np.array([0.15, 0.15, 0.6]), 400) == pytest.approx(5.4)


@pytest.mark.parametrize(
    ("obs_dim", "action_dim", "hyperparameters", "prior"),
    [
        (1, 1, "rule", "optimistic"),  # PointToGoal
        (2, 1, "rule", "optimistic"),  # the swing-up, the mountain car
        (3, 1, "rule", "optimistic"),  # Pendulum-v1: coverage 1.6
        (2, 2, "rule", "optimistic"),  # TwoRooms
        (4, 1, "evidence", "empirical"),  # InvertedPendulum-v5: coverage 0.24
        (10, 2, "evidence", "empirical"),  # Reacher-v5
    ],
)
def test_auto_follows_whether_the_rule_covers_the_inputs(
    obs_dim: int, action_dim: int, hyperparameters: str, prior: str
) -> None:
    c = GPQConfig().for_dims(obs_dim, action_dim)
    assert (c.hyperparameters, c.prior) == (hyperparameters, prior)
    # A smaller budget, chosen for speed, does not change how the agent learns.
    small = GPQConfig(max_bv=10).for_dims(obs_dim, action_dim)
    assert (small.hyperparameters, small.prior) == (hyperparameters, prior)
    # Values given are kept.
    given = GPQConfig(hyperparameters="rule", prior="midrange").for_dims(obs_dim, action_dim)
    assert (given.hyperparameters, given.prior) == ("rule", "midrange")


@pytest.mark.parametrize(
    ("lengthscale", "max_bv"),
    [([-1.0, 0.5], 400), ([0.5, 0.0], 4), ([], 400), (np.array([np.nan, 0.5]), 4),
     ([np.inf], 4), ([[0.5, 0.5]], 4), ("0.5", 4), ([True], 4), ([1 + 1j], 4)],
)  # fmt: skip
def test_rule_coverage_refuses_lengthscales_that_are_not_finite_and_positive(
    lengthscale: Any, max_bv: int
) -> None:
    """``rule_coverage([-1, .5], 400)`` returned -200."""
    with pytest.raises(ValueError, match="lengthscale must be one finite length-scale > 0"):
        rule_coverage(lengthscale, max_bv)


@pytest.mark.parametrize("max_bv", [0, -3, 2.5, True, "400", None, np.float64(4.0)])
def test_rule_coverage_refuses_a_budget_that_is_not_an_integer_of_at_least_one(
    max_bv: Any,
) -> None:
    with pytest.raises(ValueError, match="max_bv must be an integer >= 1"):
        rule_coverage([0.5, 0.5], max_bv)


@FUZZ
@given(
    ls=st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=6),
    max_bv=st.one_of(st.integers(-5, 5000), st.sampled_from([np.int64(3), 1.0, True])),
)
def test_rule_coverage_is_the_tiling_count_or_a_value_error(ls: list[float], max_bv: Any) -> None:
    good_ls = len(ls) > 0 and all(np.isfinite(v) and v > 0 for v in ls)
    good_bv = not isinstance(max_bv, bool) and isinstance(max_bv, int | np.integer) and max_bv >= 1
    if not (good_ls and good_bv):
        with pytest.raises(ValueError, match=r"lengthscale|max_bv"):
            rule_coverage(ls, max_bv)
        return
    got = rule_coverage(ls, max_bv)
    expected = float(max_bv)
    for v in ls:
        expected *= min(v, 1.0)
    assert got == pytest.approx(expected, rel=1e-12, abs=1e-300) and got >= 0


#: ``(d_s, d_a)`` -> how ``auto`` resolves with the default length-scales and the
#: ``euclidean`` kernel: the bundled tasks, Gymnasium's classic ones, the MuJoCo dims
#: (InvertedPendulum 4 + 1, Swimmer 8 + 2, InvertedDoublePendulum 9 + 1 (v5) and
#: 11 + 1 (v4), Reacher 10 + 2, Hopper 11 + 3, HalfCheetah / Walker2d 17 + 6, Pusher
#: 23 + 7, Ant 27 + 8 / 105 + 8, Humanoid 348 + 17). Pinned: a change to the rule must
#: leave the defaults as they are on every task.
DEFAULT_RESOLUTION = {
    (1, 1): ("rule", "optimistic"),  # PointToGoal
    (2, 1): ("rule", "optimistic"),  # the swing-up, MountainCarContinuous-v0
    (3, 1): ("rule", "optimistic"),  # Pendulum-v1 (coverage 1.6)
    (2, 2): ("rule", "optimistic"),  # TwoRooms (6.5)
    (1, 2): ("rule", "optimistic"),
    (1, 3): ("rule", "optimistic"),
    (3, 2): ("evidence", "empirical"),  # 0.97
    (4, 1): ("evidence", "empirical"),  # 0.24
    (8, 2): ("evidence", "empirical"),
    (9, 1): ("evidence", "empirical"),
    (11, 1): ("evidence", "empirical"),
    (10, 2): ("evidence", "empirical"),
    (11, 3): ("evidence", "empirical"),
    (17, 6): ("evidence", "empirical"),
    (23, 7): ("evidence", "empirical"),
    (27, 8): ("evidence", "empirical"),
    (105, 8): ("evidence", "empirical"),
    (348, 17): ("evidence", "empirical"),
}


@pytest.mark.parametrize("kernel", KERNEL_NAMES)
@pytest.mark.parametrize("max_bv", [None, 10, 5000])
def test_defaults_resolve_as_pinned_on_every_task(kernel: str, max_bv: int | None) -> None:
    for (obs_dim, action_dim), (hyperparameters, prior) in DEFAULT_RESOLUTION.items():
        c = GPQConfig(kernel=kernel, max_bv=max_bv).for_dims(obs_dim, action_dim)  # type: ignore[arg-type]
        if kernel != "euclidean":
            hyperparameters = "rule"  # no length-scale per input to fit
        assert (c.hyperparameters, c.prior) == (hyperparameters, prior), (obs_dim, action_dim)
        assert c.max_bv == (default_max_bv(obs_dim + action_dim) if max_bv is None else max_bv)
        assert c.for_dims(obs_dim, action_dim) == c  # resolved: resolves to itself


@pytest.mark.parametrize(
    ("env_id", "hyperparameters", "prior"),
    [("geoq/PendulumSwingUp-v0", "rule", "optimistic"), ("geoq/TwoRooms-v0", "rule", "optimistic"),
     ("Pendulum-v1", "rule", "optimistic"), ("MountainCarContinuous-v0", "rule", "optimistic")],
)  # fmt: skip
def test_the_bundled_tasks_resolve_as_pinned(env_id: str, hyperparameters: str, prior: str) -> None:
    c = GPQAgent(env_id, max_bv=10).config
    assert (c.hyperparameters, c.prior, c.lengthscale) == (hyperparameters, prior, None)
    assert c.planner == "off"


@FUZZ
@given(
    obs_dim=st.integers(1, 400), action_dim=st.integers(1, 20),
    kernel=st.sampled_from(KERNEL_NAMES), max_bv=st.one_of(st.none(), st.integers(1, 5000)),
)  # fmt: skip
def test_defaults_resolve_by_the_coverage_of_the_default_rule(
    obs_dim: int, action_dim: int, kernel: str, max_bv: int | None
) -> None:
    """Oracle: the rule before explicit length-scales were told apart (no length-scale
    given: coverage of 0.15 per state and 0.6 per action at the default budget)."""
    budget = 400 if obs_dim + action_dim <= 3 else 800
    covered = budget * 0.15**obs_dim * 0.6**action_dim >= 1.0
    c = GPQConfig(kernel=kernel, max_bv=max_bv).for_dims(obs_dim, action_dim)  # type: ignore[arg-type]
    fit = not covered and kernel == "euclidean"
    assert c.hyperparameters == ("evidence" if fit else "rule")
    assert c.prior == ("optimistic" if covered else "empirical")
    assert c.planner == ("off" if covered else "policy-net")
    assert c.for_dims(obs_dim, action_dim) == c
    chosen = GPQConfig(kernel=kernel, max_bv=max_bv, planner="off").for_dims(obs_dim, action_dim)  # type: ignore[arg-type]
    assert chosen.planner == "off"


LENGTHSCALES = st.floats(1e-3, 10.0)


@FUZZ
@given(
    obs_dim=st.integers(1, 40), action_dim=st.integers(1, 8), data=st.data(),
    how=st.sampled_from(["lengthscale", "per_input", "state", "action", "both"]),
)  # fmt: skip
def test_lengthscales_given_are_the_ones_used(
    obs_dim: int, action_dim: int, data: st.DataObject, how: str
) -> None:
    """A length-scale the user gives is used: ``auto`` resolves to ``rule``, never to
    an evidence fit that would replace it; ``prior`` still reads the coverage of the
    length-scales in use; ``hyperparameters="evidence"`` asked for is kept."""
    d = obs_dim + action_dim
    kwargs: dict[str, Any] = {}
    if how == "lengthscale":
        kwargs["lengthscale"] = data.draw(LENGTHSCALES)
    elif how == "per_input":
        kwargs["lengthscale"] = tuple(data.draw(st.lists(LENGTHSCALES, min_size=d, max_size=d)))
    if how in ("state", "both"):
        kwargs["state_lengthscale"] = data.draw(LENGTHSCALES.filter(lambda v: v != 0.15))
    if how in ("action", "both"):
        kwargs["action_lengthscale"] = data.draw(LENGTHSCALES.filter(lambda v: v != 0.6))
    config = GPQConfig(**kwargs)
    assert config.lengthscales_given()
    c = config.for_dims(obs_dim, action_dim)
    assert c.hyperparameters == "rule"
    rule = np.broadcast_to(c.rule_lengthscale(obs_dim, action_dim), (d,))
    covered = rule_coverage(rule, default_max_bv(d)) >= 1.0
    assert c.prior == ("optimistic" if covered else "empirical")
    asked = GPQConfig(**kwargs, hyperparameters="evidence").for_dims(obs_dim, action_dim)
    assert asked.hyperparameters == "evidence"


@pytest.mark.parametrize(
    ("kwargs", "lengthscale"),
    [({"lengthscale": 0.05}, [0.05]), ({"state_lengthscale": 0.05}, [0.05, 0.05, 0.6, 0.6]),
     ({"action_lengthscale": 0.05}, [0.15, 0.15, 0.05, 0.05]),
     ({"lengthscale": (0.05, 0.06, 0.3, 0.4)}, [0.05, 0.06, 0.3, 0.4])],
)  # fmt: skip
def test_an_agent_learns_with_the_lengthscales_given(
    kwargs: dict[str, Any], lengthscale: list[float]
) -> None:
    """``GPQAgent("geoq/TwoRooms-v0", lengthscale=0.05)`` resolved ``auto`` to
    ``evidence`` (their coverage is below 1) and learned with fitted length-scales."""
    agent = GPQAgent("geoq/TwoRooms-v0", max_bv=40, seed=0, **kwargs).learn(60)
    assert agent.config.hyperparameters == "rule" and agent.log.fitted_q_sweeps
    assert agent.log.evidence_fits == [] and agent.state.fitted_lengthscale is None
    np.testing.assert_array_equal(np.ravel(agent.gp.kernel.lengthscale), lengthscale)


def test_evidence_fits_see_at_most_evidence_points(tmp_path: Path) -> None:
    """Each fit draws at most ``evidence_points`` of the window, and fewer points move the
    fit; a file saved before the option loads with 300, the number its code used."""
    few, full = (GPQAgent(PointToGoalWithDistractors(extra=4), seed=0, max_bv=60, gamma=0.9,
                          **kw).learn(300)
                 for kw in ({"evidence_points": 40, "evidence_points_blind": 40}, {}))  # fmt: skip
    for agent, most in ((few, 40), (full, 300)):
        fits = agent.log.evidence_fits
        assert len(fits) >= 3 and fits[-1]["transitions"] > 40
        assert [f["points"] for f in fits] == [min(most, f["transitions"]) for f in fits]
    assert few.state.fitted_lengthscale != full.state.fitted_lengthscale
    few.save(tmp_path / "agent.npz")
    with np.load(tmp_path / "agent.npz", allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(str(arrays["meta"]))
    del meta["config"]["evidence_points"], meta["config"]["evidence_points_blind"]
    arrays["meta"] = np.asarray(json.dumps(meta))
    np.savez(tmp_path / "old.npz", **arrays)
    old = GPQAgent.load(tmp_path / "old.npz", env=PointToGoalWithDistractors(extra=4))
    assert old.config.evidence_points == old.config.evidence_points_blind == 300
    for name in ("evidence_points", "evidence_points_blind"):
        for bad in (1, 2001, 40.5, "many"):
            with pytest.raises(ValueError, match=name):
                GPQConfig(**{name: bad})


def test_a_fit_blind_to_an_action_runs_again_on_more_points(tmp_path: Path) -> None:
    """A fit that leaves an action's length-scale at its upper bound (the idle action's,
    here) runs again on ``evidence_points_blind`` points, keeping the first as
    ``first_fit``; the fits before the first rerun are those of an agent without it."""
    off, on = (GPQAgent(PointToGoalWithIdleAction(extra=4), seed=0, max_bv=60, gamma=0.9,
                        evidence_points=20, evidence_points_blind=blind).learn(300)
               for blind in (20, 80))  # fmt: skip
    assert not any("first_fit" in fit for fit in off.log.evidence_fits)
    assert on.log.evidence_fits[0]["first_fit"] == {
        key: off.log.evidence_fits[0][key]
        for key in ("points", "lengthscale", "log_evidence", "at_bound")
    }
    for fit in on.log.evidence_fits:
        first = fit.get("first_fit", fit)
        assert first["points"] == min(20, fit["transitions"])
        if "first_fit" in fit:
            assert blind_actions(first, 2) and fit["points"] == min(80, fit["transitions"])
        else:
            assert not blind_actions(fit, 2)
    assert sum("first_fit" in fit for fit in on.log.evidence_fits) >= 3
    assert on.state.fitted_lengthscale != off.state.fitted_lengthscale
    on.save(tmp_path / "agent.npz")
    loaded = GPQAgent.load(tmp_path / "agent.npz", env=PointToGoalWithIdleAction(extra=4))
    assert loaded.log.evidence_fits == on.log.evidence_fits
    bounds = ["lengthscale[0] upper", "lengthscale[3] lower", "lengthscale[4] upper"]
    assert blind_actions({"lengthscale": [1.0] * 5, "at_bound": bounds}, 2) == [1]
    assert blind_actions({"lengthscale": [1.0] * 5, "at_bound": bounds}, 1) == [0]


def test_auto_with_long_lengthscales_or_a_graph_kernel_keeps_the_rule() -> None:
    long = GPQConfig(lengthscale=0.6).for_dims(4, 1)  # 800 x 0.6^5 = 62
    assert (long.hyperparameters, long.prior) == ("rule", "optimistic")
    graph = GPQConfig(kernel="nearest").for_dims(10, 2)  # no length-scale per input to fit
    assert (graph.hyperparameters, graph.prior) == ("rule", "empirical")


def test_an_agent_resolves_auto_once_and_saves_the_choice(tmp_path: Path) -> None:
    env = PointToGoalWithDistractors(extra=4)  # 5 + 1 inputs: the rule cannot cover them
    agent = GPQAgent(env, seed=0, max_bv=60, gamma=0.9)
    assert (agent.config.hyperparameters, agent.config.prior) == ("evidence", "empirical")
    agent.learn(300)
    assert agent.log.evidence_fits and len(agent.state.fitted_lengthscale) == 6
    agent.save(tmp_path / "agent.npz")
    loaded = GPQAgent.load(tmp_path / "agent.npz", env=PointToGoalWithDistractors(extra=4))
    assert loaded.config == agent.config
    assert GPQAgent(PointToGoal(), max_bv=60).config.hyperparameters == "rule"
    assert agent.config.planner == loaded.config.planner == "policy-net"
    assert GPQAgent(PointToGoal(), max_bv=60).config.planner == "off"


def test_numpy_scalars_become_python_numbers_and_the_agent_saves(tmp_path: Path) -> None:
    agent = GPQAgent(
        PointToGoal(), max_bv=np.int64(20), seed=0, beta=np.float32(0.5),
        n_candidates=np.int32(5), gamma=np.float64(0.9), reward_bounds=np.array([-1.0, 0.0]),
    )  # fmt: skip
    c = agent.config
    assert type(c.max_bv) is int and type(c.n_candidates) is int
    assert type(c.beta) is float and c.beta == 0.5 and type(c.gamma) is float
    assert c.reward_bounds == (-1.0, 0.0)
    agent.learn(20).save(tmp_path / "agent.npz")
    assert GPQAgent.load(tmp_path / "agent.npz", env=PointToGoal()).config == c


@pytest.mark.parametrize("lengthscale", [[0.3, 0.5], np.array([0.3, 0.5]), (0.3, 0.5)])
def test_per_input_lengthscales_as_any_sequence(lengthscale: object) -> None:
    agent = GPQAgent(PointToGoal(), max_bv=10, lengthscale=lengthscale)
    assert agent.config.lengthscale == (0.3, 0.5)
    np.testing.assert_array_equal(agent.gp.kernel.lengthscale, [0.3, 0.5])
    assert GPQConfig.from_dict(agent.config.as_dict()) == agent.config


@pytest.mark.parametrize(
    ("lengthscale", "match"),
    [
        ((0.3, 0.5, 0.7), "lengthscale has 3 entries; expected 1 or 2"),
        ([0.3, -1.0], "lengthscale must be finite and > 0"),
        ("long", "lengthscale must be finite and > 0"),
        ([[0.3, 0.5]], "lengthscale must be one number or a flat sequence"),
        ([], "lengthscale must be one number or a flat sequence"),
    ],
)
def test_bad_lengthscales_say_what_is_expected(lengthscale: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        GPQAgent(PointToGoal(), max_bv=10, lengthscale=lengthscale)


def test_the_replay_strategy_is_chosen_once() -> None:
    kinds = {"none": NoReplay, "uniform": UniformReplay, "graph": GraphReplay}
    for name, kind in kinds.items():
        agent = GPQAgent(PointToGoal(), max_bv=10, replay=name)
        assert type(agent.phase.replay) is kind
    assert not NoReplay.sweeps and UniformReplay.sweeps and GraphReplay.sweeps


def test_state_and_log_round_trip_and_old_files_default() -> None:
    st = LearningState(y_mean=1.5, y_scale=2.0, reward_range=(-1.0, 0.0), num_timesteps=7,
                       scaling_pending=True, fitted_lengthscale=(0.2, 0.4))  # fmt: skip
    assert LearningState.from_dict(st.as_dict()) == st
    old = {"y_mean": 0.0, "y_scale": 1.0, "reward_range": [-1.0, 0.0], "num_timesteps": 9}
    restored = LearningState.from_dict(old)
    assert restored.last_train_timestep == 9 and restored.terminal_reward_range[0] == np.inf
    log = TrainingLog(fitted_q_sweeps=[3, 4], fitted_q_residuals=[0.1, 0.0], rescales=1)
    again = TrainingLog.from_dict(log.as_dict(), log.episodes_array())
    assert again == log
    assert np.isnan(TrainingLog.from_dict({"fitted_q_sweeps": [2]}, np.zeros((0, 4)))
                    .fitted_q_residuals).all()  # fmt: skip


def test_make_kernel_builds_every_kernel_by_name() -> None:
    assert isinstance(make_kernel("euclidean", lengthscale=0.5), SquaredExponential)
    assert isinstance(make_kernel("nearest"), GeodesicKernel)
    assert make_kernel("interpolated", attach_weights=True).graph is not None
    assert isinstance(make_kernel("resistance"), ResistanceKernel)
    with pytest.raises(ValueError, match="kernel must be one of"):
        make_kernel("rbf")  # type: ignore[arg-type]
