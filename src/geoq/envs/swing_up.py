"""Gymnasium shell around :func:`geoq.envs.pendulum.pendulum_step`."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from geoq._typing import FloatArray
from geoq.envs._render import check_render_mode, pendulum_frame, state_to_render
from geoq.envs._reset import episode_horizon, numeric_start_state, start_option
from geoq.envs.pendulum import (
    START_NOISE,
    PendulumParams,
    pendulum_step,
    sample_hanging_states,
    wrap_angle,
)

__all__ = ["SUCCESS_ANGLE", "SUCCESS_WINDOW", "PendulumSwingUpEnv"]

#: Success on the swing-up: ``|theta| < SUCCESS_ANGLE`` rad in every one of the
#: episode's last ``SUCCESS_WINDOW`` steps (the states after each step).
SUCCESS_ANGLE = 0.3
SUCCESS_WINDOW = 50
#: Episode length used for the success report when the env was made without a
#: time limit (``gymnasium.make`` sets 250, see ``geoq.envs``).
_DEFAULT_HORIZON = 250


class PendulumSwingUpEnv(gymnasium.Env[FloatArray, FloatArray]):
    """
    ## Description

    Swing a pendulum up from hanging down and balance it upright, with a torque
    too weak to lift it directly (Doya 2000; the task of Jakab & Csató, ESANN
    2012, §5). Gravity's largest torque ``m g l = 9.81 N m`` exceeds the torque
    limit ``5 N m``, so the pendulum has to pump energy before it can be
    balanced. The physics is the pure function
    `geoq.envs.pendulum.pendulum_step`, shared with the roll-outs, the
    Monte-Carlo ground truth and the tabular TD baseline; this class is a thin,
    stateful shell around it.

    - `theta`: angle in rad, `0` upright, wrapped to `[-pi, pi)`.
    - `omega`: angular velocity in rad/s.
    - `u`: torque in N m, positive in the direction of increasing `theta`.

    ## Action Space

    The action is an `ndarray` of shape `(1,)` (a scalar array of shape `()` is
    also accepted): the torque. Values outside the range are clipped; actions of
    another shape or with NaN/inf raise `ValueError`.

    | Num | Action | Min  | Max |
    |-----|--------|------|-----|
    | 0   | Torque | -5.0 | 5.0 |

    ## Observation Space

    The observation is the state itself, an `ndarray` of shape `(2,)`, float64.

    | Num | Observation      | Min  | Max |
    |-----|------------------|------|-----|
    | 0   | theta            | -pi  | pi  |
    | 1   | Angular velocity | -8.0 | 8.0 |

    ## Transition

    With `m = l = 1`, `g = 9.81`, friction `mu = 0.01`, `dt = 0.05` (semi-implicit Euler):

    *omega' = clip(omega + dt (g/l sin(theta) - mu omega/(m l<sup>2</sup>)
    + u/(m l<sup>2</sup>)), -8, 8)*,
    *theta' = wrap(theta + dt omega')*.

    ## Rewards

    *r = cos(theta)* of the state **before** the step: `1` upright, `-1` hanging down.

    ## Starting State

    Hanging down: `theta = wrap(pi + U(-0.05, 0.05))`, `omega = U(-0.05, 0.05)`,
    drawn from the env's seeded generator (`reset(seed=...)`). An exact start
    state is given by `reset(options={"state": [theta, omega]})`; it must be
    finite with `|theta| <= pi` and `|omega| <= 8`, else `ValueError`.

    ## Episode End

    The task is continuing: `terminated` is always `False`. Registered as
    `geoq/PendulumSwingUp-v0` with a time limit of 250 steps (12.5 s, the length
    of the paper's GP training roll-outs), after which `truncated` is `True`.

    ## Success

    At the episode's last step (the time limit of the env's spec, 250 when made
    directly) `info["is_success"]` is `True` when `|theta| < 0.3` rad in each of
    the last 50 states reached (Stable-Baselines3's convention). The hand-made
    controller of `geoq.policies` succeeds in every episode by this measure.

    ## Rendering

    `render_mode="rgb_array"`: `render()` returns the current state as a
    400 x 400 x 3 uint8 image (numpy drawing, no display needed): the rod (red)
    from the pivot at the angle `theta` (`0` up, positive clockwise), the
    success zone `|theta| < 0.3` (light green) and the last torque as a bar
    under the pivot (right = positive). `render_fps` is 20, the env's `1 / dt`.

    ## Arguments

    - `render_mode`: `None` or `"rgb_array"`.
    - `params`: a `geoq.envs.PendulumParams` (defaults above); the spaces follow
      its `max_torque` and `max_speed`.
    - `start_noise`: half-width of the uniform start noise (default `0.05`, at most
      the speed limit so that every start state is in the observation space).

    ```python
    >>> import gymnasium as gym, numpy as np, geoq
    >>> env = gym.make("geoq/PendulumSwingUp-v0")
    >>> obs, info = env.reset(seed=0)
    >>> obs, reward, terminated, truncated, info = env.step(np.array([3.0]))

    ```

    ## Version History

    * v0: Initial version.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 20}  # noqa: RUF012

    def __init__(
        self,
        render_mode: str | None = None,
        params: PendulumParams | None = None,
        start_noise: float = START_NOISE,
    ) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        if not np.isfinite(start_noise) or start_noise < 0:
            raise ValueError(f"start_noise must be finite and >= 0, got {start_noise!r}")
        self.render_mode = render_mode
        self.params = params if params is not None else PendulumParams()
        if start_noise > self.params.max_speed:
            raise ValueError(
                f"start_noise {start_noise!r} exceeds the speed limit {self.params.max_speed}: "
                "start states would lie outside the observation space"
            )
        self.start_noise = float(start_noise)
        p = self.params
        self.action_space = spaces.Box(
            low=-p.max_torque, high=p.max_torque, shape=(1,), dtype=np.float64
        )
        high = np.array([np.pi, p.max_speed], dtype=np.float64)
        self.observation_space = spaces.Box(low=-high, high=high, dtype=np.float64)
        self.state: FloatArray | None = None
        self._steps = 0
        self._upright_run = 0  # consecutive steps ending with |theta| < SUCCESS_ANGLE
        self._last_torque = 0.0  # shown by render()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[FloatArray, dict[str, Any]]:
        """Start an episode hanging down (seeded noise) or at ``options["state"]``."""
        super().reset(seed=seed)
        start = start_option(options)
        if start is None:
            self.state = sample_hanging_states(self.np_random, 1, self.start_noise)[0]
        else:
            self.state = self._check_state(start)
        self._steps = 0
        self._upright_run = 0
        self._last_torque = 0.0
        return self.state.copy(), {}

    def step(self, action: Any) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        """Apply one torque; return ``(obs, cos(theta_before), False, False, info)``.

        ``info`` is empty except at the episode's last step, where it holds
        ``is_success`` (see the class docstring).
        """
        if self.state is None:
            raise RuntimeError("call reset() before step()")
        raw = np.asarray(action)
        if np.iscomplexobj(raw) or raw.dtype.kind not in "biuf":
            raise ValueError(f"action has dtype {raw.dtype}; expected a real torque in [-5, 5]")
        u = raw.astype(np.float64)
        if u.shape not in ((1,), ()):
            raise ValueError(f"action has shape {u.shape}; expected (1,) (one torque)")
        if not np.isfinite(u).all():
            raise ValueError(f"action {u!r} is not finite; pass a torque in [-5, 5]")
        next_state, reward = pendulum_step(self.state, u.reshape(()), self.params)
        self._last_torque = float(np.clip(u.reshape(()), -self.params.max_torque,
                                          self.params.max_torque))  # fmt: skip
        self.state = next_state
        self._steps += 1
        upright = abs(float(next_state[0])) < SUCCESS_ANGLE
        self._upright_run = self._upright_run + 1 if upright else 0
        info: dict[str, Any] = {}
        if self._steps == self._horizon():
            info["is_success"] = self._upright_run >= SUCCESS_WINDOW
        return next_state.copy(), float(reward), False, False, info

    def render(self) -> np.ndarray | None:
        """The current state as an ``[400, 400, 3]`` uint8 image (``render_mode="rgb_array"``).

        Without a render mode: a warning (Gymnasium's convention) and ``None``.
        """
        state = state_to_render(self, self.state)
        if state is None:
            return None
        return pendulum_frame(
            float(state[0]), self._last_torque, self.params.max_torque, SUCCESS_ANGLE
        )

    def _horizon(self) -> int:
        return episode_horizon(self.spec, _DEFAULT_HORIZON)

    def _check_state(self, state: Any) -> FloatArray:
        s = numeric_start_state(state, ("theta", "omega"))
        theta, omega = s
        if abs(theta) > np.pi or abs(omega) > self.params.max_speed:
            raise ValueError(
                f"options['state'] = {s.tolist()} is out of bounds; expected |theta| <= pi "
                f"and |omega| <= {self.params.max_speed}"
            )
        return np.array([wrap_angle(theta), omega], dtype=np.float64)
