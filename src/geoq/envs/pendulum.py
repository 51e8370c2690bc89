"""Pendulum swing-up physics as a pure, vectorised function.

One function, :func:`pendulum_step`, is the single source of truth for the
dynamics: the Gymnasium shell (:mod:`geoq.envs.swing_up`), the roll-outs, the
Monte-Carlo ground truth and the tabular TD baseline all call it. It follows
Gymnasium's functional ``phys2d/pendulum.py`` twin: no state, no randomness,
any leading batch shape.

Dynamics (Doya 2000, the usual ``[-5, 5]`` swing-up; ``theta = 0`` upright,
semi-implicit Euler)::

    u      = clip(torque, -max_torque, max_torque)
    r      = cos(theta)                                     # of the state BEFORE the step
    omega' = clip(omega + dt * (g/l sin(theta) - mu omega/(m l^2) + u/(m l^2)),
                  -max_speed, max_speed)
    theta' = wrap(theta + dt * omega')                      # to [-pi, pi)

With the defaults gravity's largest torque ``m g l = 9.81`` exceeds the torque
limit 5, so the pendulum cannot be lifted directly: it has to pump energy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import check_nonnegative, check_positive

__all__ = [
    "HANGING_DOWN",
    "START_NOISE",
    "PendulumParams",
    "pendulum_energy",
    "pendulum_step",
    "sample_hanging_states",
    "wrap_angle",
]

#: The hanging-down rest state ``[theta, omega] = [-pi, 0]`` (``theta = pi`` wrapped).
HANGING_DOWN: tuple[float, float] = (-np.pi, 0.0)

#: Half-width of the uniform noise on the hanging-down start state (rad and rad/s).
START_NOISE = 0.05


@dataclass(frozen=True)
class PendulumParams:
    """Physical constants of the pendulum (SI units)."""

    mass: float = 1.0
    """Point mass ``m`` at the end of the rod, kg."""
    length: float = 1.0
    """Rod length ``l``, m."""
    gravity: float = 9.81
    """Gravitational acceleration ``g``, m s^-2."""
    friction: float = 0.01
    """Viscous friction coefficient ``mu``, N m s rad^-1."""
    dt: float = 0.05
    """Integration time step, s."""
    max_torque: float = 5.0
    """Torques are clipped to ``[-max_torque, max_torque]``, N m."""
    max_speed: float = 8.0
    """Angular speed is clipped to ``[-max_speed, max_speed]``, rad s^-1."""

    def __post_init__(self) -> None:
        for name in ("mass", "length", "gravity", "dt", "max_torque", "max_speed"):
            check_positive(getattr(self, name), f"PendulumParams.{name}")
        check_nonnegative(self.friction, "PendulumParams.friction")

    @property
    def inertia(self) -> float:
        """Moment of inertia ``m l^2``."""
        return self.mass * self.length**2


def wrap_angle(theta: ArrayLike) -> FloatArray:
    """Map angles to ``[-pi, pi)``, elementwise (``pi`` maps to ``-pi``).

    Angles already in ``[-pi, pi)`` are returned unchanged, bit for bit.
    """
    th = np.asarray(theta, dtype=np.float64)
    wrapped = np.mod(th + np.pi, 2.0 * np.pi) - np.pi
    # np.mod can round up to exactly 2 pi for tiny negative arguments.
    wrapped = np.where(wrapped >= np.pi, wrapped - 2.0 * np.pi, wrapped)
    return np.where((th >= -np.pi) & (th < np.pi), th, wrapped)


def pendulum_energy(states: ArrayLike, params: PendulumParams | None = None) -> FloatArray:
    """Mechanical energy relative to the upright rest state, shape ``states.shape[:-1]``.

    ``E = m l^2 omega^2 / 2 + m g l (cos(theta) - 1)``: ``0`` upright at rest,
    ``-2 m g l`` hanging down at rest.
    """
    p = params if params is not None else PendulumParams()
    s = np.asarray(states, dtype=np.float64)
    theta, omega = s[..., 0], s[..., 1]
    return 0.5 * p.inertia * omega**2 + p.mass * p.gravity * p.length * (np.cos(theta) - 1.0)


def pendulum_step(
    states: ArrayLike, torques: ArrayLike, params: PendulumParams | None = None
) -> tuple[FloatArray, FloatArray]:
    """Advance a batch of pendulums by one time step.

    Parameters
    ----------
    states : ``[..., 2]`` rows ``[theta, omega]`` (any angle; it is used through
        ``sin``/``cos`` and the result is wrapped).
    torques : ``[...]`` torques, broadcast against ``states[..., 0]``; clipped
        to ``[-max_torque, max_torque]``.
    params : physical constants; default :class:`PendulumParams()`.

    Returns
    -------
    next_states : ``[..., 2]`` with ``theta'`` in ``[-pi, pi)`` and ``|omega'| <= max_speed``.
    rewards : ``[...]``, ``cos(theta)`` of the state *before* the step.
    """
    p = params if params is not None else PendulumParams()
    s = np.asarray(states, dtype=np.float64)
    if s.ndim == 0 or s.shape[-1] != 2:
        raise ValueError(f"states has shape {s.shape}; expected (..., 2) rows [theta, omega]")
    theta, omega = s[..., 0], s[..., 1]
    u = np.clip(np.asarray(torques, dtype=np.float64), -p.max_torque, p.max_torque)
    rewards = np.cos(theta)
    accel = p.gravity / p.length * np.sin(theta) - p.friction * omega / p.inertia + u / p.inertia
    omega_next = np.clip(omega + p.dt * accel, -p.max_speed, p.max_speed)
    theta_next = wrap_angle(theta + p.dt * omega_next)
    next_states = np.stack(np.broadcast_arrays(theta_next, omega_next), axis=-1)
    return next_states, np.broadcast_to(rewards, theta_next.shape).copy()


def sample_hanging_states(
    rng: np.random.Generator, n: int, noise: float = START_NOISE
) -> FloatArray:
    """Draw ``n`` start states near hanging down, shape ``[n, 2]``.

    ``theta = wrap(pi + U(-noise, noise))`` and ``omega = U(-noise, noise)``,
    drawn as one ``rng.uniform(-noise, noise, size=(n, 2))`` call. This is the
    start-state distribution of the environment and of every roll-out that is
    not given an explicit start.
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    if not np.isfinite(noise) or noise < 0:
        raise ValueError(f"noise must be finite and >= 0, got {noise!r}")
    offsets = rng.uniform(-noise, noise, size=(n, 2))
    theta = wrap_angle(np.pi + offsets[:, 0])
    return np.stack([theta, offsets[:, 1]], axis=-1)
