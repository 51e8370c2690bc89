"""Environments: pure vectorised physics and their Gymnasium shells.

Importing this package (which ``import geoq`` does) registers
``geoq/PendulumSwingUp-v0`` (entry point
:class:`geoq.envs.swing_up.PendulumSwingUpEnv`) and ``geoq/TwoRooms-v0``
(entry point :class:`geoq.envs.two_rooms_env.TwoRoomsEnv`) with Gymnasium.

* :mod:`geoq.envs.pendulum`: the pure vectorised pendulum physics.
* :mod:`geoq.envs.swing_up`: its Gymnasium shell.
* :mod:`geoq.envs.two_rooms`: the pure vectorised two-rooms dynamics.
* :mod:`geoq.envs.two_rooms_env`: its Gymnasium shell.
* :mod:`geoq.envs.chain`: a chain MDP with closed-form ``Q^pi``, for checking estimators.
"""

from __future__ import annotations

import gymnasium

from geoq.envs.chain import ChainMDP
from geoq.envs.pendulum import (
    HANGING_DOWN,
    START_NOISE,
    PendulumParams,
    pendulum_energy,
    pendulum_step,
    sample_hanging_states,
    wrap_angle,
)
from geoq.envs.swing_up import PendulumSwingUpEnv
from geoq.envs.two_rooms import (
    DOOR,
    GOAL,
    GOAL_RADIUS,
    STEP_SIZE,
    TWO_ROOMS_START,
    TWO_ROOMS_START_NOISE,
    WALL_X,
    sample_two_rooms_starts,
    two_rooms_blocked,
    two_rooms_step,
)
from geoq.envs.two_rooms_env import TwoRoomsEnv

__all__ = [
    "DOOR",
    "GOAL",
    "GOAL_RADIUS",
    "HANGING_DOWN",
    "PENDULUM_SWING_UP_ID",
    "PENDULUM_SWING_UP_MAX_STEPS",
    "START_NOISE",
    "STEP_SIZE",
    "TWO_ROOMS_ID",
    "TWO_ROOMS_MAX_STEPS",
    "TWO_ROOMS_START",
    "TWO_ROOMS_START_NOISE",
    "WALL_X",
    "ChainMDP",
    "PendulumParams",
    "PendulumSwingUpEnv",
    "TwoRoomsEnv",
    "pendulum_energy",
    "pendulum_step",
    "register_envs",
    "sample_hanging_states",
    "sample_two_rooms_starts",
    "two_rooms_blocked",
    "two_rooms_step",
    "wrap_angle",
]

#: Gymnasium id of the pendulum swing-up task.
PENDULUM_SWING_UP_ID = "geoq/PendulumSwingUp-v0"

#: Time limit of ``geoq/PendulumSwingUp-v0``: 250 steps (12.5 s), the length of
#: the paper's GP training roll-outs.
PENDULUM_SWING_UP_MAX_STEPS = 250

#: Gymnasium id of the two-rooms navigation task.
TWO_ROOMS_ID = "geoq/TwoRooms-v0"

#: Time limit of ``geoq/TwoRooms-v0``: 200 steps.
TWO_ROOMS_MAX_STEPS = 200


def register_envs() -> None:
    """Register geoq's environments with Gymnasium (idempotent)."""
    if PENDULUM_SWING_UP_ID not in gymnasium.registry:
        gymnasium.register(
            id=PENDULUM_SWING_UP_ID,
            entry_point="geoq.envs.swing_up:PendulumSwingUpEnv",
            max_episode_steps=PENDULUM_SWING_UP_MAX_STEPS,
        )
    if TWO_ROOMS_ID not in gymnasium.registry:
        gymnasium.register(
            id=TWO_ROOMS_ID,
            entry_point="geoq.envs.two_rooms_env:TwoRoomsEnv",
            max_episode_steps=TWO_ROOMS_MAX_STEPS,
        )


register_envs()
