"""Tiny continuous tasks with a known optimal policy, for testing agents."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces


class PointToGoal(gymnasium.Env[np.ndarray, np.ndarray]):
    """A point on ``[-1, 1]`` moved by ``x' = clip(x + 0.1 a)``, ``a`` in ``[-1, 1]``.

    Reward ``-1`` per step; the episode terminates when ``|x' - 0.8| < 0.1``;
    time limit 40 steps. Start uniform on ``[-1, 0]``. The optimal policy moves
    right at full speed (``a = 1``) everywhere left of the goal.
    """

    GOAL = 0.8

    def __init__(self) -> None:
        self.observation_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float64)
        self._x = 0.0
        self._t = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self._x = float(self.np_random.uniform(-1.0, 0.0))
        if options and "state" in options:
            self._x = float(options["state"][0])
        self._t = 0
        return np.array([self._x]), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        a = float(np.clip(np.asarray(action).reshape(()), -1.0, 1.0))
        self._x = float(np.clip(self._x + 0.1 * a, -1.0, 1.0))
        self._t += 1
        terminated = abs(self._x - self.GOAL) < 0.1
        truncated = self._t >= 40 and not terminated
        info = {"is_success": terminated} if terminated or truncated else {}
        return np.array([self._x]), -1.0, terminated, truncated, info


class PointToGoalWithDistractors(PointToGoal):
    """:class:`PointToGoal` observed with ``extra`` more coordinates in ``[-1, 1]``, drawn
    at each reset and constant within an episode: the same task in ``1 + extra`` inputs."""

    def __init__(self, extra: int = 4) -> None:
        super().__init__()
        self.extra = extra
        self.observation_space = spaces.Box(-1.0, 1.0, shape=(1 + extra,), dtype=np.float64)
        self._distractors = np.zeros(extra)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = super().reset(seed=seed, options=options)
        self._distractors = self.np_random.uniform(-1.0, 1.0, self.extra)
        return np.concatenate([obs, self._distractors]), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = super().step(action)
        return np.concatenate([obs, self._distractors]), reward, terminated, truncated, info


def steps_to_goal(policy: Any, start: float, limit: int = 40) -> int:
    """Steps a policy ``obs -> action`` needs from ``start`` (``limit + 1`` if it never arrives)."""
    env = PointToGoal()
    obs, _ = env.reset(seed=0, options={"state": [start]})
    for t in range(1, limit + 1):
        obs, _, terminated, _, _ = env.step(policy(obs))
        if terminated:
            return t
    return limit + 1
