"""Fixed evaluation policies: the swing-up controller and Gaussian policy of the
paper's experiments, and the two-rooms waypoint policy.

The paper (JC12 §5) evaluates a *fixed* stochastic policy
``pi(a | s) = f(s) + N(0, sigma^2)`` whose deterministic part ``f`` "provides
close to optimal actions only when the pendulum approaches the target region
with a fairly low speed". :class:`SwingUpController` is such an ``f``:

* **Energy pumping** everywhere outside a capture region: with the energy
  ``E = m l^2 omega^2 / 2 + m g l (cos(theta) - 1)`` (``0`` upright at rest),
  ``dE/dt = omega (u - mu omega)``, so the torque
  ``u = clip(-k_energy * E * sgn(omega), -u_max, u_max)`` (``sgn(0) := +1``)
  drives ``E`` to ``0``, the energy of the upright rest state. The pendulum
  then approaches the top along the homoclinic orbit, whose tangent at the
  top is the stable manifold ``omega = -sqrt(g/l) theta``.
* **Stabilising feedback** ``u = clip(-(k_p theta + k_d omega), -u_max, u_max)``
  inside the capture region, a band around that stable manifold,
  ``|theta| <= capture_angle`` and ``|omega + sqrt(g/l) theta| <= capture_speed``
  (defaults 0.6 rad and 1.0 rad/s). The band lies inside the basin of
  attraction of the saturated feedback, so a state inside it is balanced.

**Why Q^pi is discontinuous.** ``f`` switches discontinuously on the boundary
of the capture region, and the two sides lead to qualitatively different
futures. Just inside the band the feedback catches the pendulum and it
collects ``cos(theta) ~ 1`` forever (``V ~ 1 / (1 - gamma) = 20``). Just
outside, e.g. at ``theta = 0`` with ``omega`` slightly above
``capture_speed``, the energy controller sees ``E > 0``, merely brakes, and
the pendulum falls over the top, swings through the bottom (rewards down to
``-1``) and comes back only after a full revolution, seconds later, when the
discount has eaten most of the value. The policy noise perturbs the *action*,
not which side of the boundary the *state* is on, so the noise does not
smooth this jump away. (The jump is largest where leaving the band means
moving away from the top; where the outside flow re-enters the band, as for
``theta < 0`` on the upper edge, braking still catches part of the
roll-outs and the jump is smaller.) Hence ``Q^pi(s, a)`` jumps across the capture
boundary, as the paper's policy was designed to; ``tests/test_policies.py``
measures the jump by Monte Carlo.

Every policy here maps a batch of states ``[N, 2]`` and a
:class:`numpy.random.Generator` to actions: ``[N]`` torques for the pendulum,
``[N, 2]`` moves for the two rooms (:class:`TwoRoomsWaypointPolicy`). This is
the :class:`Policy` protocol; :mod:`geoq.rollouts` and :mod:`geoq.evaluation`
take its scalar-action form (the pendulum's) today.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import check_nonnegative, check_positive
from geoq.envs.pendulum import PendulumParams, pendulum_energy
from geoq.envs.two_rooms import DOOR, GOAL, WALL_X

__all__ = [
    "DEFAULT_POLICY_SIGMA",
    "TWO_ROOMS_POLICY_SIGMA",
    "GaussianPolicy",
    "Policy",
    "SwingUpController",
    "TwoRoomsWaypointPolicy",
    "default_policy",
]

#: Default standard deviation of the policy's torque noise, N m (30% of the torque limit).
#: With it about 80% of roll-outs from hanging down are caught on the first approach
#: (about 45 steps) and the rest go round once more, so held-out and training
#: roll-outs contain both sides of the capture boundary.
DEFAULT_POLICY_SIGMA = 1.5


#: Default standard deviation of the two-rooms policy's noise, per action component.
TWO_ROOMS_POLICY_SIGMA = 0.3


class Policy(Protocol):
    """A (stochastic) policy: ``actions [N] or [N, d_a] = policy(states [N, d], rng)``."""

    def __call__(self, states: FloatArray, rng: np.random.Generator) -> FloatArray: ...


def _as_states(states: ArrayLike) -> FloatArray:
    s = np.asarray(states, dtype=np.float64)
    if s.ndim == 0 or s.shape[-1] != 2:
        raise ValueError(f"states has shape {s.shape}; expected (..., 2) rows [theta, omega]")
    return s


@dataclass(frozen=True)
class SwingUpController:
    """Deterministic swing-up controller ``f(s)``: energy pumping + capture-region feedback.

    See the module docstring for the control law and why it makes ``Q^pi``
    discontinuous. Calling it maps states ``[..., 2]`` to torques ``[...]`` in
    ``[-max_torque, max_torque]``.
    """

    params: PendulumParams = field(default_factory=PendulumParams)
    """Physics the controller is designed for (energy, ``sqrt(g/l)``, torque limit)."""
    k_energy: float = 2.0
    """Energy-pumping gain, N m per J."""
    k_p: float = 20.0
    """Proportional gain of the stabilising feedback, N m rad^-1 (must exceed ``m g l``)."""
    k_d: float = 5.0
    """Derivative gain of the stabilising feedback, N m s rad^-1."""
    capture_angle: float = 0.6
    """Half-width of the capture band in ``theta``, rad."""
    capture_speed: float = 1.0
    """Half-width of the capture band in ``omega + sqrt(g/l) theta``, rad s^-1."""

    def __post_init__(self) -> None:
        for name in ("k_energy", "k_p", "k_d", "capture_angle", "capture_speed"):
            check_positive(getattr(self, name), f"SwingUpController.{name}")

    @property
    def manifold_slope(self) -> float:
        """``sqrt(g/l)``: the stable manifold of the upright state is ``omega = -slope * theta``."""
        return float(np.sqrt(self.params.gravity / self.params.length))

    def in_capture_region(self, states: ArrayLike) -> np.ndarray:
        """Boolean mask ``[...]``: is the state inside the capture band?"""
        s = _as_states(states)
        theta, omega = s[..., 0], s[..., 1]
        return (np.abs(theta) <= self.capture_angle) & (
            np.abs(omega + self.manifold_slope * theta) <= self.capture_speed
        )

    def __call__(self, states: ArrayLike) -> FloatArray:
        """Torques ``[...]`` for states ``[..., 2]``."""
        s = _as_states(states)
        theta, omega = s[..., 0], s[..., 1]
        u_max = self.params.max_torque
        direction = np.where(omega >= 0.0, 1.0, -1.0)
        pump = -self.k_energy * pendulum_energy(s, self.params) * direction
        feedback = -(self.k_p * theta + self.k_d * omega)
        u = np.where(self.in_capture_region(s), feedback, pump)
        return np.clip(u, -u_max, u_max)


@dataclass(frozen=True)
class GaussianPolicy:
    """The paper's fixed Gaussian policy ``a = clip(f(s) + N(0, sigma^2), -u_max, u_max)``.

    ``sigma = 0`` gives the deterministic controller and draws nothing from the
    generator. Otherwise noise is drawn from the generator passed to each call,
    one standard normal per state, in row order, so the same generator state
    gives the same actions.
    """

    controller: SwingUpController = field(default_factory=SwingUpController)
    """The deterministic part ``f``."""
    sigma: float = DEFAULT_POLICY_SIGMA
    """Standard deviation of the torque noise, N m."""

    def __post_init__(self) -> None:
        check_nonnegative(self.sigma, "GaussianPolicy.sigma")

    @property
    def max_torque(self) -> float:
        """Actions are clipped to ``[-max_torque, max_torque]``."""
        return self.controller.params.max_torque

    def mean_action(self, states: ArrayLike) -> FloatArray:
        """The deterministic part ``f(s)``, shape ``[...]``."""
        return self.controller(states)

    def __call__(self, states: ArrayLike, rng: np.random.Generator) -> FloatArray:
        """Sample actions ``[...]`` for states ``[..., 2]``."""
        mean = self.controller(states)
        if self.sigma == 0.0:
            return mean
        noise = rng.standard_normal(mean.shape)
        return np.clip(mean + self.sigma * noise, -self.max_torque, self.max_torque)


def default_policy(sigma: float = DEFAULT_POLICY_SIGMA) -> GaussianPolicy:
    """The fixed Gaussian policy used by the experiments (default controller, ``sigma``)."""
    return GaussianPolicy(SwingUpController(), sigma)


@dataclass(frozen=True)
class TwoRoomsWaypointPolicy:
    """Fixed evaluation policy of ``geoq/TwoRooms-v0``: through the door, then to the goal.

    The deterministic part heads at unit speed (an action of Euclidean norm 1)
    for ``waypoint`` while the point is in the left room (``x < WALL_X``) and
    for ``goal`` otherwise; at its target exactly it stays (action ``0``).
    Sampled actions add ``N(0, sigma^2)`` to each component and are clipped to
    ``[-1, 1]^2``. ``sigma = 0`` draws nothing from the generator; otherwise
    ``rng.standard_normal((..., 2))`` is drawn once per call, in row order, so
    the same generator state gives the same actions.

    From the default start the deterministic policy reaches the goal in 27-31
    steps. With ``sigma = 0.3`` every one of 2,000 seeded episodes reached it
    (median 31 steps, at most 41), and about 15% of them hit the wall at least
    once (the move is blocked and retried), so ``Q^pi`` also sees the wall.
    """

    waypoint: tuple[float, float] = (WALL_X, 0.5 * (DOOR[0] + DOOR[1]))
    """Target while in the left room: the middle of the door."""
    goal: tuple[float, float] = GOAL
    """Target in the right room."""
    sigma: float = TWO_ROOMS_POLICY_SIGMA
    """Standard deviation of the noise on each action component."""

    def __post_init__(self) -> None:
        check_nonnegative(self.sigma, "TwoRoomsWaypointPolicy.sigma")
        for name in ("waypoint", "goal"):
            point = getattr(self, name)
            if len(point) != 2 or not all(np.isfinite(v) for v in point):
                raise ValueError(
                    f"TwoRoomsWaypointPolicy.{name} must be finite (x, y), got {point}"
                )

    def mean_action(self, states: ArrayLike) -> FloatArray:
        """The deterministic moves ``[..., 2]`` (unit norm, or 0 at the target) for ``[..., 2]``."""
        s = np.asarray(states, dtype=np.float64)
        if s.ndim == 0 or s.shape[-1] != 2:
            raise ValueError(f"states has shape {s.shape}; expected (..., 2) rows [x, y]")
        left = s[..., :1] < WALL_X  # [..., 1]
        target = np.where(left, np.asarray(self.waypoint), np.asarray(self.goal))  # [..., 2]
        delta = target - s
        norm = np.linalg.norm(delta, axis=-1, keepdims=True)
        return np.divide(delta, norm, out=np.zeros_like(delta), where=norm > 0.0)

    def __call__(self, states: ArrayLike, rng: np.random.Generator) -> FloatArray:
        """Sample moves ``[..., 2]`` in ``[-1, 1]^2`` for states ``[..., 2]``."""
        mean = self.mean_action(states)
        if self.sigma == 0.0:
            return mean
        noise = rng.standard_normal(mean.shape)
        return np.clip(mean + self.sigma * noise, -1.0, 1.0)
