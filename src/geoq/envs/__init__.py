"""Environments: pure vectorised physics and their Gymnasium shells.

Importing this package (which ``import geoq`` does) registers
``geoq/PendulumSwingUp-v0`` with Gymnasium (entry point
:class:`geoq.envs.swing_up.PendulumSwingUpEnv`).

* :mod:`geoq.envs.pendulum`: the pure vectorised physics.
* :mod:`geoq.envs.swing_up`: the Gymnasium shell.
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

__all__ = [
    "HANGING_DOWN",
    "PENDULUM_SWING_UP_ID",
    "PENDULUM_SWING_UP_MAX_STEPS",
    "START_NOISE",
    "ChainMDP",
    "PendulumParams",
    "PendulumSwingUpEnv",
    "pendulum_energy",
    "pendulum_step",
    "register_envs",
    "sample_hanging_states",
    "wrap_angle",
]

#: Gymnasium id of the pendulum swing-up task.
PENDULUM_SWING_UP_ID = "geoq/PendulumSwingUp-v0"

#: Time limit of ``geoq/PendulumSwingUp-v0``: 250 steps (12.5 s), the length of
#: the paper's GP training roll-outs.
PENDULUM_SWING_UP_MAX_STEPS = 250


def register_envs() -> None:
    """Register geoq's environments with Gymnasium (idempotent)."""
    if PENDULUM_SWING_UP_ID not in gymnasium.registry:
        gymnasium.register(
            id=PENDULUM_SWING_UP_ID,
            entry_point="geoq.envs.swing_up:PendulumSwingUpEnv",
            max_episode_steps=PENDULUM_SWING_UP_MAX_STEPS,
        )


register_envs()
