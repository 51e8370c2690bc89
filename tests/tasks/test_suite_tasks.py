"""The suite's task registry: every task runs, and bad task input is refused clearly."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import pytest
from gymnasium import spaces

from geoq.rollouts import collect_rollouts
from geoq.tasks.suite import SUITE_TASK_IDS, check_box_spaces, observe_rollouts, suite_task


@pytest.mark.parametrize("task_id", SUITE_TASK_IDS)
def test_every_task_rolls_out_and_observes(task_id: str) -> None:
    task = suite_task(task_id)
    rollouts = collect_rollouts(
        2,
        30,
        task.policy,
        np.random.default_rng(0),
        gamma=task.gamma,
        start=task.sample_starts,
        step=task.step,
    )
    observed = observe_rollouts(task, rollouts)
    d_obs = task.scaling.dim - (
        1 if rollouts[0].actions.ndim == 1 else rollouts[0].actions.shape[1]
    )
    for ro in observed:
        assert ro.inputs.shape == (len(ro), task.scaling.dim)
        assert ro.states.shape[1] == d_obs
    env = gymnasium.make(task_id)
    assert env.observation_space.shape == (d_obs,)
    assert task.mean_action(rollouts[0].states).shape[0] == len(rollouts[0])


def test_pendulum_v1_scaling_has_no_period() -> None:
    scaling = suite_task("Pendulum-v1").scaling
    assert scaling.periods == (0.0, 0.0, 0.0, 0.0)
    assert scaling.scale == (1.0, 1.0, 8.0, 2.0)
    assert suite_task("geoq/PendulumSwingUp-v0").scaling.periods[0] == pytest.approx(2 * np.pi)


def test_unknown_and_discrete_tasks_are_value_errors() -> None:
    with pytest.raises(ValueError, match=r"unknown task 'NoSuchTask-v0'.*suite tasks"):
        suite_task("NoSuchTask-v0")
    with pytest.raises(ValueError, match="Discrete action spaces are not supported"):
        suite_task("CartPole-v1")
    if "geoq-test/BoxBox-v0" not in gymnasium.registry:
        gymnasium.register("geoq-test/BoxBox-v0", entry_point=_BoxEnv)
    with pytest.raises(ValueError, match="not in the task suite: it needs a pure vectorised step"):
        suite_task("geoq-test/BoxBox-v0")


class _DictObsEnv(gymnasium.Env[Any, Any]):
    observation_space = spaces.Dict({"a": spaces.Box(-1.0, 1.0, (2,))})
    action_space = spaces.Box(-1.0, 1.0, (1,))


class _BoxEnv(gymnasium.Env[Any, Any]):
    observation_space = spaces.Box(-1.0, 1.0, (2,))
    action_space = spaces.Box(-1.0, 1.0, (1,))


class _DiscreteEnv(gymnasium.Env[Any, Any]):
    observation_space = spaces.Box(-1.0, 1.0, (2,))
    action_space = spaces.Discrete(3)


def test_check_box_spaces_names_the_bad_space() -> None:
    with pytest.raises(ValueError, match=r"1-D Box observation space.*FlattenObservation"):
        check_box_spaces(_DictObsEnv())
    with pytest.raises(ValueError, match="Discrete action spaces are not supported"):
        check_box_spaces(_DiscreteEnv())
