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


class PointToGoalWithIdleAction(PointToGoalWithDistractors):
    """:class:`PointToGoalWithDistractors` with a second action that does nothing: ``Q``
    is flat along it, so an evidence fit should leave its length-scale at the bound."""

    def __init__(self, extra: int = 4) -> None:
        super().__init__(extra)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float64)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        return super().step(np.asarray(action).reshape(2)[:1])


def steps_to_goal(policy: Any, start: float, limit: int = 40) -> int:
    """Steps a policy ``obs -> action`` needs from ``start`` (``limit + 1`` if it never arrives)."""
    env = PointToGoal()
    obs, _ = env.reset(seed=0, options={"state": [start]})
    for t in range(1, limit + 1):
        obs, _, terminated, _, _ = env.step(policy(obs))
        if terminated:
            return t
    return limit + 1


class MovingPoint(gymnasium.Env[np.ndarray, np.ndarray]):
    """A point in ``[-1, 1]^d`` moved by ``x' = clip(x + step u)``, ``u`` the action in its
    box's own centred, scaled coordinates (``[-1, 1]^d`` whatever the box), for hostile
    tests of the exploration map.

    Reward ``-1`` per step. The episode terminates at the goal (within ``radius`` of
    ``goal``, reward ``-1``) and in the pit (within ``radius`` of ``pit``, reward
    ``pit_reward``); time limit ``limit`` steps. Starts at ``start`` (default: uniform in
    ``[-1, -0.5]^d``). The observation is the point followed by ``constant`` features
    fixed at ``constant_value``; its space declares ``obs_low, obs_high`` (the world's
    ``[-1, 1]`` by default) whatever the world is.
    """

    def __init__(
        self, d: int = 2, *, step: float = 0.05, goal: Any = None, pit: Any = None,
        radius: float = 0.15, pit_reward: float = -100.0, limit: int = 100,
        start: Any = None, obs_low: Any = -1.0, obs_high: Any = 1.0, constant: int = 0,
        constant_value: float = 0.0, action_low: Any = -1.0, action_high: Any = 1.0,
    ) -> None:  # fmt: skip
        self.d, self.step_size, self.radius, self.limit = d, step, radius, limit
        self.goal = None if goal is None else np.asarray(goal, dtype=np.float64)
        self.pit = None if pit is None else np.asarray(pit, dtype=np.float64)
        self.pit_reward = pit_reward
        self.start = None if start is None else np.asarray(start, dtype=np.float64)
        self.constants = np.full(constant, constant_value, dtype=np.float64)
        n = d + constant
        self.observation_space = spaces.Box(
            np.broadcast_to(np.asarray(obs_low, dtype=np.float64), (n,)).copy(),
            np.broadcast_to(np.asarray(obs_high, dtype=np.float64), (n,)).copy(),
            dtype=np.float64,
        )
        self.action_space = spaces.Box(
            np.broadcast_to(np.asarray(action_low, dtype=np.float64), (d,)).copy(),
            np.broadcast_to(np.asarray(action_high, dtype=np.float64), (d,)).copy(),
            dtype=np.float64,
        )
        self._x, self._t = np.zeros(d), 0

    def _obs(self) -> np.ndarray:
        return np.concatenate([self._x, self.constants])

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        start = self.start
        self._x = (self.np_random.uniform(-1.0, -0.5, self.d) if start is None
                   else start.copy())  # fmt: skip
        self._t = 0
        return self._obs(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        low, high = self.action_space.low, self.action_space.high
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(self.d), low, high)
        u = (a - 0.5 * (low + high)) / (0.5 * (high - low))
        self._x = np.clip(self._x + self.step_size * u, -1.0, 1.0)
        self._t += 1
        reward, terminated, success = -1.0, False, False
        if self.goal is not None and np.linalg.norm(self._x - self.goal) < self.radius:
            terminated = success = True
        elif self.pit is not None and np.linalg.norm(self._x - self.pit) < self.radius:
            reward, terminated = self.pit_reward, True
        truncated = self._t >= self.limit and not terminated
        info = {"is_success": success} if terminated or truncated else {}
        return self._obs(), reward, terminated, truncated, info


class TwoRoomsWithPit(gymnasium.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray]):
    """``geoq/TwoRooms-v0`` with a pit off the route: within ``radius`` of ``pit`` the
    episode ends with reward ``pit_reward`` (a failure, ``is_success`` False)."""

    def __init__(self, pit: tuple[float, float] = (0.1, 0.5), radius: float = 0.1,
                 pit_reward: float = -100.0) -> None:  # fmt: skip
        super().__init__(gymnasium.make("geoq/TwoRooms-v0"))
        self.pit, self.radius, self.pit_reward = np.asarray(pit), radius, pit_reward

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if not terminated and np.linalg.norm(obs - self.pit) <= self.radius:
            return obs, self.pit_reward, True, False, {"is_success": False}
        return obs, float(reward), terminated, truncated, info
