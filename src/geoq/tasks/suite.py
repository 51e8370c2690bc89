"""The policy-evaluation task suite: one :class:`SuiteTask` record per task.

A suite task is everything the Fig. 3 protocol needs to run on a task with no
per-task code elsewhere: a pure vectorised step function on the task's
*internal* state (the Monte-Carlo ground truth runs it), a start sampler
matching the env's reset distribution, the map from internal states to the
observation the policy and the GP see, a fixed evaluation policy, the discount,
the roll-out length, the number of training roll-outs and the input scaling
(the env's space bounds, :func:`geoq.tasks.box_scaling`, with the task's periods).

=========================== ====================================== ======= =========== ==========
task                        evaluation policy (fixed, documented)  gamma   roll-out    training
=========================== ====================================== ======= =========== ==========
geoq/PendulumSwingUp-v0     energy pumping + capture-band PD,       0.95    250 steps   3 roll-outs
                            noise 1.5 N m (:func:`default_policy`)
geoq/TwoRooms-v0            waypoint through the door, then the     0.95    <= 200      10 episodes
                            goal, noise 0.3 per component                   (ends at goal)
MountainCarContinuous-v0    ``sign(velocity)`` energy pumping,      0.99    <= 999      3 episodes
                            noise 0.3                                       (ends at goal)
Pendulum-v1                 the swing-up controller re-targeted     0.95    200 steps   3 roll-outs
                            to Pendulum-v1's physics, noise 0.6
=========================== ====================================== ======= =========== ==========

Why these numbers: ``gamma = 0.95`` is the swing-up's (an effective horizon of
20 steps); the mountain car's +100 arrives after about 107 steps, so at 0.95 it
would be worth 0.4 and ``Q^pi`` would be the action cost alone: 0.99 keeps the
goal in view (``0.99^107 = 0.34``). Two-rooms episodes take about 31 steps, so
10 of them give about as many training pairs as the mountain car's 3.
Roll-out lengths are the envs' time limits.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial

import gymnasium
import numpy as np

from geoq._typing import FloatArray
from geoq.envs import (
    DOOR,
    PENDULUM_SWING_UP_ID,
    TWO_ROOMS_ID,
    WALL_X,
    PendulumParams,
    pendulum_step,
    sample_hanging_states,
    sample_two_rooms_starts,
    two_rooms_step,
)
from geoq.learners.scaling import InputScaling
from geoq.policies import Policy, TwoRoomsWaypointPolicy, default_policy
from geoq.rollouts import Rollout, StepFn
from geoq.tasks import box_scaling, check_box_spaces, task_info
from geoq.tasks.classic_control import (
    GymPendulumPolicy,
    MountainCarEnergyPolicy,
    gym_pendulum_observe,
    gym_pendulum_step,
    mountain_car_step,
    sample_gym_pendulum_starts,
    sample_mountain_car_starts,
)

__all__ = [
    "SUITE_TASK_IDS",
    "SuiteTask",
    "check_box_spaces",
    "near_closed_wall",
    "observe_rollouts",
    "suite_task",
]

MOUNTAIN_CAR_ID = "MountainCarContinuous-v0"
GYM_PENDULUM_ID = "Pendulum-v1"

#: The suite's tasks, in report order.
SUITE_TASK_IDS: tuple[str, ...] = (
    PENDULUM_SWING_UP_ID,
    TWO_ROOMS_ID,
    MOUNTAIN_CAR_ID,
    GYM_PENDULUM_ID,
)


@dataclass(frozen=True)
class SuiteTask:
    """Everything the suite needs to know about one task.

    Attributes
    ----------
    env_id : the Gymnasium id.
    step : pure vectorised dynamics on internal states (:data:`geoq.rollouts.StepFn`).
    sample_starts : ``(rng, n) -> [n, d]`` internal start states, the env's reset draw.
    policy : the fixed evaluation policy, on internal states; ``policy.mean_action(states)``
        is its deterministic part (value maps).
    observe : internal states ``[..., d]`` -> observations ``[..., d_obs]`` (what the
        policy and the GP see); ``None`` when they are the same.
    gamma : discount of targets and ground truth.
    rollout_steps : steps per roll-out (the env's time limit).
    train_rollouts : roll-outs the GP learns from (and held-out ones for the
        evaluation pairs, separately drawn).
    scaling : input scaling of ``[observation, action]``: each dimension's half-range.
    state_names : names of the internal state dimensions (value maps).
    map_box : ``((lo_0, hi_0), (lo_1, hi_1))`` of the internal state for a value map, or
        ``None`` (no map: the state is not 2-D and observed as is).
    policy_doc : one line on the evaluation policy, for reports.
    focus : internal states ``[N, d]`` -> boolean mask ``[N]`` of the states where the
        task's value function is discontinuous between near neighbours (TwoRooms: within
        0.1 of the wall's closed part), scored separately; ``None``: no such region.
    focus_doc : what ``focus`` selects, for reports.
    """

    env_id: str
    step: StepFn
    sample_starts: Callable[[np.random.Generator, int], FloatArray]
    policy: Policy
    observe: Callable[[FloatArray], FloatArray] | None
    gamma: float
    rollout_steps: int
    train_rollouts: int
    scaling: InputScaling
    state_names: tuple[str, ...]
    map_box: tuple[tuple[float, float], tuple[float, float]] | None
    policy_doc: str
    focus: Callable[[FloatArray], np.ndarray] | None = None
    focus_doc: str = ""

    def mean_action(self, states: FloatArray) -> FloatArray:
        """The deterministic part of the evaluation policy at internal states."""
        mean: FloatArray = self.policy.mean_action(states)  # type: ignore[attr-defined]
        return mean

    def observed(self, states: FloatArray) -> FloatArray:
        """Observations of internal states (the states themselves when ``observe`` is None)."""
        return states if self.observe is None else self.observe(states)


def _scaling(env_id: str) -> InputScaling:
    env = gymnasium.make(env_id)
    try:
        obs, act = check_box_spaces(env)
        return box_scaling(obs, act, task_info(env))
    finally:
        env.close()


def _build(env_id: str) -> SuiteTask:
    if env_id == PENDULUM_SWING_UP_ID:
        return SuiteTask(
            env_id,
            partial(pendulum_step, params=PendulumParams()),
            sample_hanging_states,
            default_policy(),
            None,
            0.95,
            250,
            3,
            _scaling(env_id),
            ("theta", "omega"),
            ((-np.pi, np.pi), (-8.0, 8.0)),
            "geoq.policies.default_policy(): energy pumping + capture-band PD, noise 1.5 N m",
        )
    if env_id == TWO_ROOMS_ID:
        return SuiteTask(
            env_id,
            two_rooms_step,
            sample_two_rooms_starts,
            TwoRoomsWaypointPolicy(),
            None,
            0.95,
            200,
            10,
            _scaling(env_id),
            ("x", "y"),
            ((0.0, 1.0), (0.0, 1.0)),
            "geoq.policies.TwoRoomsWaypointPolicy(): unit moves to the door's middle, then to "
            "the goal, noise 0.3 per component",
            focus=near_closed_wall,
            focus_doc="within 0.1 of the wall's closed part (|x - 0.5| < 0.1, y < 0.8)",
        )
    if env_id == MOUNTAIN_CAR_ID:
        return SuiteTask(
            env_id,
            mountain_car_step,
            sample_mountain_car_starts,
            MountainCarEnergyPolicy(),
            None,
            0.99,
            999,
            3,
            _scaling(env_id),
            ("position", "velocity"),
            ((-1.2, 0.6), (-0.07, 0.07)),
            "geoq.tasks.classic_control.MountainCarEnergyPolicy(): force sign(velocity), noise 0.3",
        )
    if env_id == GYM_PENDULUM_ID:
        return SuiteTask(
            env_id,
            gym_pendulum_step,
            sample_gym_pendulum_starts,
            GymPendulumPolicy(),
            gym_pendulum_observe,
            0.95,
            200,
            3,
            _scaling(env_id),
            ("theta", "theta_dot"),
            None,
            "geoq.tasks.classic_control.GymPendulumPolicy(): the swing-up controller on "
            "theta = atan2(sin, cos) with Pendulum-v1's physics, noise 0.6 N m",
        )
    raise AssertionError(env_id)  # pragma: no cover - guarded by suite_task


def near_closed_wall(states: FloatArray) -> np.ndarray:
    """TwoRooms states within 0.1 of the wall's closed part: ``|x - 0.5| < 0.1``, ``y < 0.8``,
    where neighbours on the two sides of the wall are far apart along the dynamics."""
    s = np.asarray(states, dtype=np.float64)
    return (np.abs(s[:, 0] - WALL_X) < 0.1) & (s[:, 1] < DOOR[0])


_CACHE: dict[str, SuiteTask] = {}


def suite_task(env_id: str) -> SuiteTask:
    """The :class:`SuiteTask` of ``env_id``; a clear ``ValueError`` for anything else.

    A registered Gymnasium id outside the suite is checked first, so that a
    Discrete action space or a Dict observation is named as the reason.
    """
    if env_id in _CACHE:
        return _CACHE[env_id]
    if env_id not in SUITE_TASK_IDS:
        if isinstance(env_id, str) and env_id in gymnasium.registry:
            try:
                env = gymnasium.make(env_id)
            except Exception as exc:  # a missing optional dependency, say
                raise ValueError(
                    f"{env_id} is not in the task suite (and cannot be made here: {exc}); "
                    f"suite tasks: {list(SUITE_TASK_IDS)}"
                ) from exc
            try:
                check_box_spaces(env)
            finally:
                env.close()
            raise ValueError(
                f"{env_id} is not in the task suite: it needs a pure vectorised step "
                f"function and a fixed evaluation policy; suite tasks: {list(SUITE_TASK_IDS)}"
            )
        raise ValueError(f"unknown task {env_id!r}; suite tasks: {list(SUITE_TASK_IDS)}")
    _CACHE[env_id] = _build(env_id)
    return _CACHE[env_id]


def observe_rollouts(task: SuiteTask, rollouts: list[Rollout]) -> list[Rollout]:
    """Roll-outs with their internal states replaced by observations (what the GP sees)."""
    if task.observe is None:
        return rollouts
    return [
        Rollout(
            task.observed(ro.states),
            ro.actions,
            ro.rewards,
            task.observed(ro.next_states),
            ro.returns,
            ro.gamma,
            ro.terminated,
        )
        for ro in rollouts
    ]


#: Read-only view for reports: the suite's task ids -> one-line policy description.
def policy_docs() -> Mapping[str, str]:
    """One line per suite task describing its evaluation policy."""
    return {t: suite_task(t).policy_doc for t in SUITE_TASK_IDS}
