"""A cart-pole swing-up held out from every choice of issue 46: PILCO's cart-pole.

The task a new user would bring to a model-based GP agent: the benchmark of PILCO
(Deisenroth & Rasmussen 2011; Deisenroth's thesis, 2010, §6.1), with a dense reward and
a rail. Nothing in geoq was chosen on it; it checks goal 6 ("swing-ups and locomotion
among them") on a swing-up past four inputs.

- State ``(x, v, theta, omega)``: cart position (m) and velocity, pole angle (rad, ``0``
  upright, ``pi`` hanging) and angular velocity. PILCO's dynamics (``dynamics_cp.m``):
  cart 0.5 kg, pole 0.5 kg of length 0.5 m, friction 0.1 N s/m, g = 9.82, integrated by
  RK4 over ``DT = 0.05`` s.
- Observation ``(x, v, cos theta, sin theta, omega)``: 5 dimensions; action: the force,
  ``[-10, 10]`` N. 6 inputs in all.
- Reward ``(1 + cos theta) / 2 * (1 + exp(-x**2)) / 2`` per step, in ``[0, 1]``: about 0
  hanging, 1 upright at the centre. The episode ends (terminated) where the cart leaves
  the rail, ``|x| > 2.4``; it is truncated after 200 steps (10 s).
- Starts hanging, ``theta = pi``, with N(0, 0.05^2) noise on all four coordinates.

Registered on import as ``heldout/CartPoleSwingUp-v0``. geoq's CLI takes it as
``gymnasium.make`` does, by the module that registers it (imported again by a sweep's
workers), with this folder on ``PYTHONPATH``:

    PYTHONPATH=research/heldout geoq bench-control \\
        --env cartpole_swingup:heldout/CartPoleSwingUp-v0 \\
        --seeds 5 --timesteps 5000 --eval-every 500 --eval-episodes 10 --out DIR -j 2

(Part thirteen's runs, before geoq took ``module:Id``, imported it from a
``sitecustomize.py`` on ``PYTHONPATH`` instead: the same task, the same numbers.)

``python research/heldout/cartpole_swingup.py --help`` checks that it loads; with
``--steps N`` it runs one ``GPQAgent`` with defaults for ``N`` steps and prints its greedy
return.
"""

from __future__ import annotations

import argparse
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

CARTPOLE_SWING_UP_ID = "heldout/CartPoleSwingUp-v0"
MAX_STEPS = 200
DT = 0.05
FORCE = 10.0
RAIL = 2.4
_CART, _POLE, _LENGTH, _FRICTION, _G = 0.5, 0.5, 0.5, 0.1, 9.82


def _derivative(z: np.ndarray, force: float) -> np.ndarray:
    """PILCO's cart-pole, angle from hanging (``phi = theta + pi``): d/dt (x, v, theta, omega)
    of states ``[..., 4]`` under forces broadcast against ``[...]``."""
    _, v, theta, omega = np.moveaxis(z, -1, 0)
    phi = theta + np.pi
    m, big_m, ell, b, g = _POLE, _CART, _LENGTH, _FRICTION, _G
    s, c = np.sin(phi), np.cos(phi)
    dv = (2 * m * ell * omega**2 * s + 3 * m * g * s * c + 4 * force - 4 * b * v) / (
        4 * (big_m + m) - 3 * m * c**2
    )
    domega = (
        -3 * m * ell * omega**2 * s * c - 6 * (big_m + m) * g * s - 6 * (force - b * v) * c
    ) / (4 * ell * (big_m + m) - 3 * m * ell * c**2)
    return np.stack([v, dv, omega, domega], axis=-1)


def cartpole_step(z: np.ndarray, force: float | np.ndarray) -> np.ndarray:
    """One RK4 step of ``DT`` seconds of states ``[..., 4]``, the force held."""
    k1 = _derivative(z, force)
    k2 = _derivative(z + 0.5 * DT * k1, force)
    k3 = _derivative(z + 0.5 * DT * k2, force)
    k4 = _derivative(z + DT * k3, force)
    return z + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def observe(z: np.ndarray) -> np.ndarray:
    """The observation ``(x, v, cos theta, sin theta, omega)`` ``[..., 5]`` of states
    ``[..., 4]``."""
    x, v, theta, omega = np.moveaxis(z, -1, 0)
    return np.stack([x, v, np.cos(theta), np.sin(theta), omega], axis=-1)


def reward(z: np.ndarray) -> np.ndarray:
    """The reward ``[...]`` on reaching states ``[..., 4]``: the pole up, the cart centred."""
    x, theta = z[..., 0], z[..., 2]
    return (1 + np.cos(theta)) / 2 * (1 + np.exp(-(x**2))) / 2


class CartPoleSwingUpEnv(gymnasium.Env):
    """Swing the pole up from hanging and balance it, the cart kept on its rail."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(self) -> None:
        high = np.array([np.inf, np.inf, 1.0, 1.0, np.inf])
        self.observation_space = spaces.Box(-high, high, dtype=np.float64)
        self.action_space = spaces.Box(-FORCE, FORCE, shape=(1,), dtype=np.float64)
        self._z = np.zeros(4)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self._z = np.array([0.0, 0.0, np.pi, 0.0]) + self.np_random.normal(0.0, 0.05, 4)
        return observe(self._z), {}

    def step(self, action):
        force = float(np.clip(np.asarray(action, dtype=np.float64).reshape(-1)[0], -FORCE, FORCE))
        self._z = cartpole_step(self._z, force)
        return observe(self._z), float(reward(self._z)), bool(abs(self._z[0]) > RAIL), False, {}


if CARTPOLE_SWING_UP_ID not in gymnasium.registry:
    gymnasium.register(
        id=CARTPOLE_SWING_UP_ID,
        entry_point=CartPoleSwingUpEnv,
        max_episode_steps=MAX_STEPS,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=0, help="learning steps (0: load only)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.steps <= 0:
        return
    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent

    agent = GPQAgent(CARTPOLE_SWING_UP_ID, seed=args.seed)
    agent.learn(args.steps)
    print(evaluate_agent(agent, CARTPOLE_SWING_UP_ID, 10, 1_000).summary())


if __name__ == "__main__":
    main()
