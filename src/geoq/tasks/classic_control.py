"""Gymnasium's ``MountainCarContinuous-v0`` and ``Pendulum-v1`` as pure, vectorised functions.

Each step function follows ``gymnasium/envs/classic_control/continuous_mountain_car.py``
and ``pendulum.py`` (Gymnasium 1.x) operation by operation, with NumPy 2's
promotion rules (NEP 50) giving the same precision as the env's scalar code (the
pendulum's torque terms are float32 arithmetic, as ``0.001 * u**2`` is on the
float32 torque) and the env's scalar squares computed by the C library's ``pow``,
as scalars are (:mod:`geoq.tasks._libm`: NumPy's array power differs in the last
bit, by CPU), so ``tests/tasks/test_classic_control.py`` finds them equal to
``env.step``, bit for bit, step after step. Under NumPy 1.x's value-based casting
the env computes those float32 terms in float64: the twins then differ from it
in the last bits (relative 1e-7 at most). They take the env's *internal* state (what
``env.unwrapped.state`` holds), not its float32 observation:

* **MountainCarContinuous-v0**: state ``[position, velocity]``; the env stores it
  as float32 after every step and computes in float32, so the function does too
  (its inputs are rounded to float32, its outputs are float32 values in
  float64 arrays). Actions are rounded to float32, the action space's dtype, as
  ``env.step`` receives them from an agent that respects the space.
  Terminates at ``position >= 0.45`` with ``velocity >= 0``.
* **Pendulum-v1**: state ``[theta, theta_dot]`` in float64, the angle not
  wrapped; the observation ``[cos, sin, theta_dot]`` (float32) is
  :func:`gym_pendulum_observe` of it. Actions are rounded to float32 likewise.
  Never terminates (200-step time limit).

The start samplers draw what ``reset`` draws (``np_random.uniform`` with the
env's bounds), in the same generator calls; the mountain car's start position is
rounded to float32, as its observation (the env's own first step uses the
unrounded float64 draw: a difference below 3e-8).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import check_nonnegative
from geoq.envs.pendulum import PendulumParams
from geoq.policies import SwingUpController
from geoq.tasks._libm import libm_square

__all__ = [
    "GYM_PENDULUM_DT",
    "GYM_PENDULUM_G",
    "GYM_PENDULUM_MAX_SPEED",
    "GYM_PENDULUM_MAX_TORQUE",
    "GYM_PENDULUM_PARAMS",
    "GYM_PENDULUM_POLICY_SIGMA",
    "MOUNTAIN_CAR_GOAL_POSITION",
    "MOUNTAIN_CAR_MAX_POSITION",
    "MOUNTAIN_CAR_MAX_SPEED",
    "MOUNTAIN_CAR_MIN_POSITION",
    "MOUNTAIN_CAR_POLICY_SIGMA",
    "GymPendulumPolicy",
    "MountainCarEnergyPolicy",
    "gym_pendulum_observe",
    "gym_pendulum_step",
    "mountain_car_step",
    "sample_gym_pendulum_starts",
    "sample_mountain_car_starts",
]

MOUNTAIN_CAR_MIN_POSITION = -1.2
MOUNTAIN_CAR_MAX_POSITION = 0.6
MOUNTAIN_CAR_MAX_SPEED = 0.07
MOUNTAIN_CAR_GOAL_POSITION = 0.45
_MOUNTAIN_CAR_POWER = 0.0015

GYM_PENDULUM_MAX_SPEED = 8.0
GYM_PENDULUM_MAX_TORQUE = 2.0
GYM_PENDULUM_DT = 0.05
GYM_PENDULUM_G = 10.0

#: Noise of the mountain car's evaluation policy (force units; the force limit is 1).
MOUNTAIN_CAR_POLICY_SIGMA = 0.3
#: Noise of Pendulum-v1's evaluation policy, N m (30% of the torque limit 2, as the swing-up's).
GYM_PENDULUM_POLICY_SIGMA = 0.6


def _pairs(x: ArrayLike, name: str) -> FloatArray:
    a = np.asarray(x)
    if a.ndim == 0 or a.shape[-1] != 2:
        raise ValueError(f"{name} has shape {a.shape}; expected (..., 2)")
    return a


def _first_action(actions: ArrayLike) -> np.ndarray:
    """Actions ``[...]`` or ``[..., 1]`` as float32 ``[...]`` (the action space's dtype)."""
    a = np.asarray(actions, dtype=np.float32)
    return a[..., 0] if a.ndim >= 1 and a.shape[-1] == 1 else a


def mountain_car_step(
    states: ArrayLike, actions: ArrayLike
) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """One step of ``MountainCarContinuous-v0`` for a batch: ``(next [..., 2], r [...], done)``.

    ``states [..., 2]`` are ``[position, velocity]``, ``actions [...]`` or
    ``[..., 1]`` forces (clipped to ``[-1, 1]``). Gymnasium's ``step``::

        force = min(max(action[0], -1), 1)
        velocity += force * 0.0015 - 0.0025 * cos(3 * position)   # clipped to +-0.07
        position += velocity                                       # clipped to [-1.2, 0.6]
        if position == -1.2 and velocity < 0: velocity = 0
        terminated = position >= 0.45 and velocity >= 0
        reward = (100 if terminated else 0) - 0.1 * action[0] ** 2
    """
    s = _pairs(states, "states").astype(np.float32)
    position, velocity = s[..., 0], s[..., 1]
    action = _first_action(actions)
    # math.cos of the float32 3 * position, in double precision, as the env computes it.
    slope = 0.0025 * np.cos((3 * position).astype(np.float64))  # a Python float in the env
    # min(max(action[0], -1.0), 1.0) keeps the float32 action when it is inside [-1, 1]:
    # then force * power is float32 and the Python-float slope is rounded to float32 before
    # the float32 subtraction (NEP 50). A clipped force is the Python float +-1.0: the whole
    # increment is computed in double and rounded to float32 when added to the velocity.
    inside = (action >= -1.0) & (action <= 1.0)
    unclipped = action * np.float32(_MOUNTAIN_CAR_POWER) - slope.astype(np.float32)
    clipped = (np.where(action > 1.0, 1.0, -1.0) * _MOUNTAIN_CAR_POWER - slope).astype(np.float32)
    velocity = velocity + np.where(inside, unclipped, clipped)
    velocity = np.clip(velocity, -MOUNTAIN_CAR_MAX_SPEED, MOUNTAIN_CAR_MAX_SPEED)
    position = np.clip(position + velocity, MOUNTAIN_CAR_MIN_POSITION, MOUNTAIN_CAR_MAX_POSITION)
    velocity = np.where((position == MOUNTAIN_CAR_MIN_POSITION) & (velocity < 0), 0, velocity)
    position, velocity = np.broadcast_arrays(position, velocity)
    terminated = (position >= MOUNTAIN_CAR_GOAL_POSITION) & (velocity >= 0)
    # math.pow(action[0], 2) * 0.1 on the float32 action, in double precision.
    reward = np.where(terminated, 100.0, 0.0) - libm_square(action.astype(np.float64)) * 0.1
    next_states = np.stack([position, velocity], axis=-1).astype(np.float32).astype(np.float64)
    return next_states, np.broadcast_to(reward, terminated.shape).copy(), terminated


def sample_mountain_car_starts(rng: np.random.Generator, n: int) -> FloatArray:
    """``n`` start states ``[n, 2]``: ``position ~ U(-0.6, -0.4)`` (rounded to float32), 0.

    One ``rng.uniform(-0.6, -0.4, size=n)`` call: for ``n = 1`` the draw of ``reset``.
    """
    position = rng.uniform(low=-0.6, high=-0.4, size=n).astype(np.float32).astype(np.float64)
    return np.stack([position, np.zeros(n)], axis=-1)


def _angle_normalize(x: FloatArray) -> FloatArray:
    return ((x + np.pi) % (2 * np.pi)) - np.pi


def gym_pendulum_step(
    states: ArrayLike, actions: ArrayLike
) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """One step of ``Pendulum-v1`` (``g = 10``) for a batch: ``(next [..., 2], r [...], done)``.

    ``states [..., 2]`` are the internal ``[theta, theta_dot]`` (float64, theta not
    wrapped), ``actions [...]`` or ``[..., 1]`` torques (clipped to ``[-2, 2]``).
    Gymnasium's ``step``::

        u = clip(u, -2, 2)
        costs = angle_normalize(th) ** 2 + 0.1 * thdot ** 2 + 0.001 * u ** 2
        newthdot = clip(thdot + (3 g / (2 l) sin(th) + 3 / (m l^2) u) dt, -8, 8)
        newth = th + newthdot dt
        reward = -costs;  terminated = False
    """
    s = np.asarray(_pairs(states, "states"), dtype=np.float64)
    th, thdot = s[..., 0], s[..., 1]
    u = np.clip(_first_action(actions), -GYM_PENDULUM_MAX_TORQUE, GYM_PENDULUM_MAX_TORQUE)
    g, m, length, dt = GYM_PENDULUM_G, 1.0, 1.0, GYM_PENDULUM_DT
    # u is float32: 0.001 * u**2 and 3 * u are float32 arithmetic (powf, then a float32
    # product), as on the env's float32 scalar torque; the rest is float64.
    costs = libm_square(_angle_normalize(th)) + 0.1 * libm_square(thdot) + 0.001 * libm_square(u)
    newthdot = thdot + (3 * g / (2 * length) * np.sin(th) + 3.0 / (m * length**2) * u) * dt
    newthdot = np.clip(newthdot, -GYM_PENDULUM_MAX_SPEED, GYM_PENDULUM_MAX_SPEED)
    newth = th + newthdot * dt
    newth, newthdot = np.broadcast_arrays(newth, newthdot)
    next_states = np.stack([newth, newthdot], axis=-1).astype(np.float64)
    reward = np.asarray(-costs, dtype=np.float64)
    return next_states, np.broadcast_to(reward, newth.shape).copy(), np.zeros(newth.shape, bool)


def gym_pendulum_observe(states: ArrayLike) -> FloatArray:
    """The observation ``[cos, sin, theta_dot]`` ``[..., 3]`` of internal states ``[..., 2]``
    (float32 values, as the env returns them, in a float64 array)."""
    s = np.asarray(_pairs(states, "states"), dtype=np.float64)
    obs = np.stack([np.cos(s[..., 0]), np.sin(s[..., 0]), s[..., 1]], axis=-1)
    return obs.astype(np.float32).astype(np.float64)


def sample_gym_pendulum_starts(rng: np.random.Generator, n: int) -> FloatArray:
    """``n`` internal start states ``[n, 2]``: ``theta ~ U(-pi, pi)``, ``theta_dot ~ U(-1, 1)``.

    One ``rng.uniform(low=[-pi, -1], high=[pi, 1], size=(n, 2))`` call: for ``n = 1`` the
    draw of ``reset``.
    """
    high = np.array([np.pi, 1.0])
    return rng.uniform(low=-high, high=high, size=(n, 2))


@dataclass(frozen=True)
class MountainCarEnergyPolicy:
    """Fixed evaluation policy of ``MountainCarContinuous-v0``: energy pumping plus noise.

    The deterministic part pushes with full force in the direction of motion,
    ``f(s) = sign(velocity)`` (``sign(0) := +1``): the force then always does
    positive work, so the car swings higher each time and reaches the goal.
    Sampled actions are ``clip(f(s) + N(0, sigma^2), -1, 1)``, shape ``[N, 1]``;
    ``sigma = 0`` draws nothing from the generator.

    ``Q^pi`` jumps where one more swing is needed: a state with just enough
    energy to crest the hill is tens of steps (and, at ``gamma = 0.99``, a large
    share of the +100) from one that falls back.
    """

    sigma: float = MOUNTAIN_CAR_POLICY_SIGMA
    """Standard deviation of the force noise."""

    def __post_init__(self) -> None:
        check_nonnegative(self.sigma, "MountainCarEnergyPolicy.sigma")

    def mean_action(self, states: ArrayLike) -> FloatArray:
        """``f(s)`` ``[..., 1]`` for states ``[..., 2]`` (``[position, velocity]``)."""
        s = _pairs(states, "states")
        return np.where(s[..., 1:2] >= 0.0, 1.0, -1.0)

    def __call__(self, states: ArrayLike, rng: np.random.Generator) -> FloatArray:
        mean = self.mean_action(states)
        if self.sigma == 0.0:
            return mean
        return np.clip(mean + self.sigma * rng.standard_normal(mean.shape), -1.0, 1.0)


#: Physics of ``Pendulum-v1`` in :class:`PendulumParams` form, for the swing-up controller:
#: ``theta_ddot = 15 sin(theta) + 3 u`` is ``g/l sin + u / (m l^2)`` with ``g/l = 15``,
#: ``m l^2 = 1/3``; no friction; torque limit 2.
GYM_PENDULUM_PARAMS = PendulumParams(
    mass=1.0 / 3.0,
    length=1.0,
    gravity=1.5 * GYM_PENDULUM_G,
    friction=0.0,
    dt=GYM_PENDULUM_DT,
    max_torque=GYM_PENDULUM_MAX_TORQUE,
    max_speed=GYM_PENDULUM_MAX_SPEED,
)


@dataclass(frozen=True)
class GymPendulumPolicy:
    """Fixed evaluation policy of ``Pendulum-v1``: geoq's swing-up controller, re-targeted.

    It acts on the *observation* ``[cos, sin, theta_dot]`` (internal states
    ``[theta, theta_dot]`` are observed first, :func:`gym_pendulum_observe`), takes
    ``theta = atan2(sin, cos)`` and applies :class:`geoq.policies.SwingUpController`
    with Pendulum-v1's physics (:data:`GYM_PENDULUM_PARAMS`): energy pumping
    outside a capture band around the upright state's stable manifold, PD feedback
    inside it. Sampled actions are ``clip(f + N(0, sigma^2), -2, 2)``, shape ``[N, 1]``.
    """

    controller: SwingUpController = field(
        default_factory=lambda: SwingUpController(
            params=GYM_PENDULUM_PARAMS,
            k_energy=2.0,
            k_p=10.0,
            k_d=2.0,
            capture_angle=0.5,
            capture_speed=1.0,
        )
    )
    sigma: float = GYM_PENDULUM_POLICY_SIGMA
    """Standard deviation of the torque noise, N m."""

    def __post_init__(self) -> None:
        check_nonnegative(self.sigma, "GymPendulumPolicy.sigma")

    def mean_action(self, states: ArrayLike) -> FloatArray:
        """``f`` ``[..., 1]`` for internal states ``[..., 2]``."""
        obs = gym_pendulum_observe(states)
        theta = np.arctan2(obs[..., 1], obs[..., 0])
        return self.controller(np.stack([theta, obs[..., 2]], axis=-1))[..., None]

    def __call__(self, states: ArrayLike, rng: np.random.Generator) -> FloatArray:
        mean = self.mean_action(states)
        if self.sigma == 0.0:
            return mean
        limit = GYM_PENDULUM_MAX_TORQUE
        return np.clip(mean + self.sigma * rng.standard_normal(mean.shape), -limit, limit)
