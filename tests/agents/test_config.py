"""GPQConfig: every setting resolved and validated once, with one message per rule."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from tests.agents._tasks import PointToGoal, PointToGoalWithDistractors

from geoq.agents import GPQAgent, GPQConfig
from geoq.agents.config import rule_coverage
from geoq.agents.replay import GraphReplay, NoReplay, UniformReplay
from geoq.agents.state import LearningState, TrainingLog
from geoq.kernels import GeodesicKernel, ResistanceKernel, SquaredExponential, make_kernel


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
