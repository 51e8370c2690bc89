"""``GPQAgent``: online GP Q-learning for continuous control (beyond the paper).

The paper's future work (§6): "applying the presented method in a policy
iteration framework, while exploiting the probabilistic nature of GPs to
facilitate exploration". The agent, in Stable-Baselines3's vocabulary::

    agent = GPQAgent(env, kernel="euclidean", max_bv=200, seed=0)
    agent.learn(total_timesteps=3_000)
    action, _ = agent.predict(obs, deterministic=True)

How it learns (every choice is a field of :class:`GPQConfig`):

1. **Inputs.** ``x = [s, a] / scale`` with ``scale`` the half-range of each
   space's bounds (:func:`geoq.tasks.box_scaling`); angles wrap (known for
   the bundled tasks, declared with ``periods=`` otherwise).
2. **Acting.** One batched GP call per step gives the posterior mean and std
   of ``Q(s, a_k)`` at ``K`` candidate actions (a grid in 1-D, refined by
   parabolic interpolation; a Sobol' set in more dimensions); the action
   maximises the acquisition (:mod:`geoq.agents.acquisition`): UCB
   ``mean + beta std`` (GP-UCB), Thompson-style samples, or the greedy action
   plus Gaussian noise.
3. **Online update** (Q-learning with a GP, Engel et al. 2005 in spirit):
   every environment step streams ``(x_t, y_t)`` into the sparse online GP with
   the bootstrapped target ``y_t = r_t + gamma (1 - terminated) max_k Q(s_{t+1},
   a_k)`` (the same call that chooses the next action gives the max). Graph
   kernels grow and shrink their graph with the basis set, as in the paper.
4. **Fitted-Q phases** every ``train_every`` steps and at each episode's end:
   targets of every stored transition are re-bootstrapped to convergence on the
   current basis set and kernel (:mod:`geoq.agents.fitted_q`), then the
   posterior is refit to them (DTC, :meth:`SparseOnlineGP.refit`).
5. **Standardisation.** The GP sees ``z = (y - y_mean) / y_scale``; after each
   phase ``y_mean, y_scale`` become the mean and standard deviation of the
   targets, so the prior mean (the value of what was never tried) is the
   average value seen and the prior std is the spread of values.
6. **Threads.** ``learn`` and ``train`` run on one BLAS thread (the library's
   policy, :mod:`geoq._threads`): their matrices have a few hundred rows.
7. **Bounded targets.** Targets are clipped to ``[r_min, r_max] / (1 - gamma)``
   of the rewards observed so far: every discounted return lies there, and
   without it regression + max diverged (targets of 3e5 after 9 episodes on the
   swing-up).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, fields
from os import PathLike
from typing import Any, Literal

import gymnasium
import numpy as np
import scipy.linalg
from gymnasium import spaces

from geoq._io import ArchiveError, load_archive, save_archive
from geoq._threads import single_blas_thread
from geoq._typing import FloatArray
from geoq.agents.acquisition import (
    EXPLORATION_MODES,
    Exploration,
    candidate_actions,
    choose_actions,
)
from geoq.agents.buffer import TransitionBuffer
from geoq.agents.fitted_q import fitted_q_sweeps
from geoq.agents.graph_replay import imagine_transitions
from geoq.gp import SparseOnlineGP
from geoq.kernels.geodesic import GraphKernel
from geoq.learners.q_gp import KERNEL_NAMES, KernelName, QGPConfig, make_kernel
from geoq.learners.scaling import InputScaling
from geoq.tasks import TaskInfo, box_scaling, data_scaling, has_finite_bounds, task_info

__all__ = ["EpisodeRecord", "GPQAgent", "GPQConfig"]

Prior = Literal["midrange", "optimistic", "empirical"]
PRIORS: tuple[str, ...] = ("midrange", "optimistic", "empirical")
Replay = Literal["uniform", "none", "graph"]
REPLAYS: tuple[str, ...] = ("uniform", "none", "graph")

#: A data-driven input scale is refreshed when the states' spread outgrows it by this factor.
RESCALE_FACTOR = 1.5

_ARCHIVE_KIND = "GPQAgent"
_ARCHIVE_VERSION = 1


@dataclass(frozen=True)
class GPQConfig:
    """Everything that defines a :class:`GPQAgent` (saved with it, reported with results)."""

    kernel: KernelName = "euclidean"
    """``euclidean`` (squared exponential), ``nearest`` (JC12 eq. 4), ``interpolated``
    (JC12 eq. 5) or ``resistance`` (positive-definite kernel on the same graph)."""
    max_bv: int = 400
    """Basis-vector budget of the sparse online GP. Measured on the swing-up (squared
    exponential, 2,500 steps): 200 BVs reached success >= 0.9 in 0 of 6 seeds, 400 in
    6 of 6: the balancing region needs the resolution."""
    gamma: float = 0.98
    """Discount factor."""
    exploration: Exploration = "ucb"
    """``ucb`` (mean + beta std), ``thompson``, ``gaussian`` (greedy + noise) or ``greedy``."""
    beta: float = 0.5
    """UCB width, in posterior standard deviations."""
    action_noise: float = 0.3
    """Std of the ``gaussian`` exploration noise, as a fraction of each action half-range."""
    n_candidates: int = 21
    """Candidate actions per state (a grid in 1-D; rounded up to a power of 2 in more)."""
    noise: float = 0.01
    """Observation-noise variance of the standardised targets."""
    lengthscale: float | tuple[float, ...] | None = None
    """Squared-exponential length-scale(s) in scaled input units (``euclidean``); a
    tuple has one entry per input dimension ``d_s + d_a``. ``None``: the rule
    ``state_lengthscale`` for every state dimension, ``action_lengthscale`` for
    every action dimension."""
    state_lengthscale: float = 0.15
    """Length-scale of each state dimension when ``lengthscale`` is None (in
    half-ranges of the space: 0.15 of the pendulum's ``[-pi, pi]`` is 0.47 rad)."""
    action_lengthscale: float = 0.6
    """Length-scale of each action dimension when ``lengthscale`` is None. Longer than
    the states': one step's action moves the next state by ``dt``-small amounts, so
    Q varies slowly along the action."""
    amplitude: float = 1.0
    """Prior variance of the standardised Q (every kernel)."""
    eps: float = 0.3
    """Graph threshold of JC12 eq. 2 (graph kernels)."""
    sigma_sp: float = 0.03
    """Width of JC12 eq. 3 (geodesic kernels)."""
    sigma_se: float = 0.01
    """Width of the JC12 eq. 5 interpolation weights (``interpolated``)."""
    resistance_lengthscale: float = 0.3
    """``l`` of the resistance kernel ``A exp(-R / l)``."""
    tol: float = 1e-6
    """Relative novelty threshold of the sparse GP."""
    train_every: int = 250
    """Steps between fitted-Q phases (one also runs at every episode's end)."""
    max_sweeps: int = 200
    """Largest number of fitted-Q sweeps per phase."""
    sweep_tol: float = 1e-3
    """A phase stops when no target moves by more than this (in units of ``y_scale``)."""
    window: int = 5_000
    """Fitted-Q phases use the most recent ``window`` transitions."""
    replay: Replay = "uniform"
    """``uniform``: each phase re-bootstraps every stored transition (fitted-Q sweeps,
    all transitions alike); ``none``: no replay, the targets stay those computed
    online when each step was taken and a phase only refits the posterior to them;
    ``graph``: ``uniform`` plus up to ``replay_budget`` transitions imagined by the
    graph's dynamics model (:mod:`geoq.agents.graph_replay`) for the actions not
    taken at the stored states of largest TD error; they join the fitted-Q sweeps
    (better bootstraps ``max_a' Q(s', a')`` for the stored transitions), not the
    posterior the agent acts with."""
    warmup_steps: int = 250
    """Observation spaces with an infinite bound and no ``scaling=``: the first
    ``warmup_steps`` steps take uniformly random actions, then the input scaling is
    set from the states seen (:func:`geoq.tasks.data_scaling`) and learning starts
    on them. As exploration widens, a fitted-Q phase that finds the states' spread
    grown past ``RESCALE_FACTOR`` (1.5) x a scale rescales and rebuilds the GP from
    the stored transitions (counted in ``GPQAgent.rescales``). Unused when every
    bound is finite."""
    replay_budget: int = 500
    """Largest number of imagined transitions per fitted-Q phase (``replay="graph"``)."""
    replay_eps: float = 0.9
    """JC12 eq. 2 threshold of the replay graph: two state-action pairs are linked when
    their squared-exponential similarity in length-scale units exceeds it."""
    prior: Prior = "optimistic"
    """What the GP assumes of ``Q`` where it has no data (the standardisation
    ``z = (y - y_mean) / y_scale``, set after every fitted-Q phase from the value
    bounds ``[lo, hi]`` of :meth:`GPQAgent.value_bounds` or from the targets):
    ``midrange``: mean ``(lo + hi) / 2``, std ``(hi - lo) / 2``; ``optimistic``:
    mean ``hi``, std ``(hi - lo) / 2`` (optimism in the face of uncertainty);
    ``empirical``: mean and std of the current targets."""

    def __post_init__(self) -> None:
        if self.kernel not in KERNEL_NAMES:
            raise ValueError(f"kernel must be one of {KERNEL_NAMES}, got {self.kernel!r}")
        if self.replay not in REPLAYS:
            raise ValueError(f"replay must be one of {REPLAYS}, got {self.replay!r}")
        if self.prior not in PRIORS:
            raise ValueError(f"prior must be one of {PRIORS}, got {self.prior!r}")
        if self.exploration not in EXPLORATION_MODES:
            raise ValueError(
                f"exploration must be one of {EXPLORATION_MODES}, got {self.exploration!r}"
            )
        _check_int(self.max_bv, "max_bv", 1)
        _check_int(self.n_candidates, "n_candidates", 3)
        _check_int(self.train_every, "train_every", 1)
        _check_int(self.max_sweeps, "max_sweeps", 0)
        _check_int(self.window, "window", 1)
        _check_int(self.replay_budget, "replay_budget", 0)
        _check_int(self.warmup_steps, "warmup_steps", 1)
        if not (isinstance(self.replay_eps, int | float) and 0.0 < self.replay_eps < 1.0):
            raise ValueError(f"replay_eps must be in (0, 1), got {self.replay_eps!r}")
        if not (isinstance(self.gamma, int | float) and 0.0 <= self.gamma < 1.0):
            raise ValueError(f"gamma must be in [0, 1), got {self.gamma!r}")
        for name in ("beta", "action_noise"):
            _check_real(getattr(self, name), name, strict=False)
        for name in ("noise", "amplitude", "eps", "sigma_sp", "sigma_se",
                     "resistance_lengthscale", "sweep_tol", "state_lengthscale",
                     "action_lengthscale"):  # fmt: skip
            _check_real(getattr(self, name), name, strict=True)
        if not 0.0 <= self.tol <= 1.0:
            raise ValueError(f"tol must be in [0, 1], got {self.tol!r}")
        if self.lengthscale is not None:
            ls = np.atleast_1d(np.asarray(self.lengthscale, dtype=np.float64))
            if not (np.all(np.isfinite(ls)) and np.all(ls > 0)):
                raise ValueError(f"lengthscale must be finite and > 0, got {self.lengthscale!r}")

    def as_dict(self) -> dict[str, Any]:
        """JSON-able representation."""
        out = asdict(self)
        if isinstance(self.lengthscale, tuple):
            out["lengthscale"] = list(self.lengthscale)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GPQConfig:
        """Inverse of :meth:`as_dict`; unknown keys raise ``ValueError``."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown GPQConfig field(s) {unknown}; known: {sorted(known)}")
        d = dict(data)
        if isinstance(d.get("lengthscale"), list):
            d["lengthscale"] = tuple(float(v) for v in d["lengthscale"])
        return cls(**d)


def _check_int(value: Any, name: str, minimum: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


def _check_real(value: Any, name: str, *, strict: bool) -> None:
    ok = isinstance(value, int | float | np.floating) and not isinstance(value, bool)
    if not ok or not np.isfinite(value) or value < 0 or (strict and value == 0):
        bound = "> 0" if strict else ">= 0"
        raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")


@dataclass(frozen=True)
class EpisodeRecord:
    """One finished training episode (a row of ``learning_curve.csv``)."""

    timesteps: int
    """Environment steps taken by the agent when the episode ended."""
    episode: int
    """1-based episode index."""
    ret: float
    """Undiscounted return of the episode."""
    success: float
    """``info["is_success"]`` at the episode's end (1/0), NaN if the env reports none."""


def _as_env(env: gymnasium.Env | str) -> gymnasium.Env:
    if isinstance(env, str):
        return gymnasium.make(env)
    if not isinstance(env, gymnasium.Env):
        raise ValueError(
            f"env must be a gymnasium.Env or a registered id, got {type(env).__name__}"
        )
    return env


def _check_spaces(env: gymnasium.Env) -> tuple[spaces.Box, spaces.Box]:
    obs, act = env.observation_space, env.action_space
    if not isinstance(obs, spaces.Box) or len(obs.shape) != 1:
        raise ValueError(
            f"GPQAgent supports a 1-D Box observation space; got {obs!r}. Flatten the "
            "observation (gymnasium.wrappers.FlattenObservation) for Dict or image spaces."
        )
    if not isinstance(act, spaces.Box) or len(act.shape) != 1:
        raise ValueError(
            f"GPQAgent supports a 1-D Box action space (continuous actions); got {act!r}. "
            "Discrete action spaces are not supported."
        )
    if not (np.all(np.isfinite(act.low)) and np.all(np.isfinite(act.high))):
        raise ValueError(f"the action space {act!r} must have finite bounds")
    return obs, act


class GPQAgent:
    """Online GP Q-learning agent (see the module docstring for the algorithm).

    Parameters
    ----------
    env : a ``gymnasium.Env`` with a 1-D Box observation space and a 1-D Box
        action space with finite bounds, or the id of a registered one.
    kernel : ``"euclidean" | "nearest" | "interpolated" | "resistance"``.
    max_bv : basis-vector budget of the sparse GP.
    seed : seed of every random choice (exploration, candidates, env resets).
    periods : wrap-around period of each observation dimension (raw units, 0 =
        not periodic); known for the bundled tasks.
    scaling : input scaling of ``[s, a]`` (default: the spaces' half-ranges).
    **config : any other field of :class:`GPQConfig`.
    """

    def __init__(
        self,
        env: gymnasium.Env | str,
        kernel: KernelName = "euclidean",
        max_bv: int = 400,
        seed: int | None = None,
        *,
        periods: Sequence[float] | None = None,
        scaling: InputScaling | None = None,
        **config: Any,
    ) -> None:
        unknown = sorted(set(config) - {f.name for f in fields(GPQConfig)})
        if unknown:
            raise TypeError(f"GPQAgent got unknown argument(s) {unknown}")
        self.config = GPQConfig(kernel=kernel, max_bv=max_bv, **config)
        self.env: gymnasium.Env | None = _as_env(env)
        obs_space, act_space = _check_spaces(self.env)
        self.obs_dim = int(obs_space.shape[0])
        self.action_dim = int(act_space.shape[0])
        self.action_low = act_space.low.astype(np.float64)
        self.action_high = act_space.high.astype(np.float64)
        self.env_id = self.env.spec.id if self.env.spec is not None else ""
        info = task_info(self.env, periods)
        #: True until ``warmup_steps`` steps have fixed a data-driven input scaling (an
        #: observation space with infinite bounds and no ``scaling=``).
        self.scaling_pending = scaling is None and not has_finite_bounds(obs_space)
        #: Whether the scaling comes from data (it then follows the states seen).
        self.data_scaled = self.scaling_pending
        if scaling is not None:
            self.scaling = scaling
        elif self.scaling_pending:  # placeholder (never used on data): replaced after warm-up
            self.scaling = data_scaling(np.zeros((1, self.obs_dim)), obs_space, act_space, info)
        else:
            self.scaling = box_scaling(obs_space, act_space, info)
        if self.scaling.dim != self.obs_dim + self.action_dim:
            raise ValueError(
                f"scaling has {self.scaling.dim} dimensions; expected "
                f"{self.obs_dim + self.action_dim} (observation + action)"
            )
        ls = np.atleast_1d(np.asarray(self._lengthscale(), dtype=np.float64))
        if ls.size not in (1, self.scaling.dim):
            raise ValueError(
                f"lengthscale has {ls.size} entries; expected 1 or {self.scaling.dim} "
                "(one per observation and action dimension)"
            )
        self.seed = seed
        self.rng = np.random.default_rng(np.random.SeedSequence(seed))
        self.candidates = candidate_actions(
            self.action_low, self.action_high, self.config.n_candidates, self.rng
        )  # [K, d_a]
        self.gp = self._new_gp()
        self.buffer = TransitionBuffer(self.obs_dim, self.action_dim)
        self.y_mean, self.y_scale = 0.0, 1.0 / (1.0 - self.config.gamma)
        self.reward_range = (np.inf, -np.inf)
        self.num_timesteps = 0
        self.episodes: list[EpisodeRecord] = []
        self.fitted_q_sweeps: list[int] = []
        self.imagined_counts: list[int] = []
        self.train_seconds = 0.0
        self.rescales = 0

    # ------------------------------------------------------------------ set-up
    def _lengthscale(self) -> float | tuple[float, ...]:
        c = self.config
        if c.lengthscale is None:
            return (c.state_lengthscale,) * self.obs_dim + (c.action_lengthscale,) * self.action_dim
        if isinstance(c.lengthscale, tuple):
            return tuple(float(v) for v in c.lengthscale)
        return float(c.lengthscale)

    def _q_config(self) -> QGPConfig:
        c = self.config
        ls = self._lengthscale()
        return QGPConfig(
            kernel=c.kernel, max_bv=c.max_bv, tol=c.tol, noise=c.noise, lengthscale=ls,
            amplitude=c.amplitude, eps=c.eps, sigma_sp=c.sigma_sp, sigma_se=c.sigma_se,
            resistance_lengthscale=c.resistance_lengthscale,
            wrap_angle=bool(np.any(np.asarray(self.scaling.periods) > 0)),
            attach_weights=c.kernel == "interpolated", scaling=self.scaling,
        )  # fmt: skip

    def _new_gp(self) -> SparseOnlineGP:
        c = self.config
        return SparseOnlineGP(
            make_kernel(self._q_config()), noise=c.noise, max_bv=c.max_bv, tol=c.tol
        )

    # ------------------------------------------------------------------ inputs
    def inputs(self, states: FloatArray, actions: FloatArray) -> FloatArray:
        """Scaled GP inputs ``[N, d_s + d_a]`` of states ``[N, d_s]`` and actions ``[N, d_a]``."""
        return self.scaling.transform(np.hstack([states, actions]))

    def _candidate_inputs(self, states: FloatArray) -> FloatArray:
        """Inputs ``[n K, d]`` of every state ``[n, d_s]`` paired with every candidate."""
        K = self.candidates.shape[0]
        return self.inputs(np.repeat(states, K, axis=0), np.tile(self.candidates, (len(states), 1)))

    def q_candidates(self, states: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Posterior mean and std of ``Q`` ``[n, K]`` at every state x candidate (one GP call)."""
        if self.scaling_pending:
            raise ValueError(
                "the observation space has infinite bounds and the agent has not yet seen the "
                f"{self.config.warmup_steps} warm-up steps that fix its input scaling: call "
                "learn() first, or pass scaling= with a finite scale per dimension"
            )
        mean, std = self.gp.predict(self._candidate_inputs(states), return_std=True)
        n = states.shape[0]
        return (self.y_mean + self.y_scale * mean).reshape(n, -1), (self.y_scale * std).reshape(
            n, -1
        )

    def _check_obs(self, obs: Any) -> tuple[FloatArray, bool]:
        raw = np.asarray(obs)
        if np.iscomplexobj(raw) or raw.dtype.kind not in "fiub":
            raise ValueError(f"observation must hold real numbers, got dtype {raw.dtype}")
        o = raw.astype(np.float64)
        single = o.ndim == 1
        if o.ndim not in (1, 2) or o.shape[-1] != self.obs_dim:
            d = self.obs_dim
            raise ValueError(f"observation has shape {o.shape}; expected ({d},) or (n, {d})")
        if not np.all(np.isfinite(o)):
            raise ValueError("observation contains NaN or inf")
        return np.atleast_2d(o), single

    # ------------------------------------------------------------------ acting
    def predict(self, observation: Any, deterministic: bool = True) -> tuple[FloatArray, None]:
        """The action ``[d_a]`` (or ``[n, d_a]`` for ``n`` observations) and ``None``.

        ``deterministic=True`` maximises the posterior mean (greedy); otherwise
        the configured exploration is used (it draws from the agent's generator).
        """
        S, single = self._check_obs(observation)
        mean, std = self.q_candidates(S)
        actions = self._act(mean, std, "greedy" if deterministic else self.config.exploration)
        return (actions[0] if single else actions), None

    def _act(self, mean: FloatArray, std: FloatArray, mode: Exploration) -> FloatArray:
        half = 0.5 * (self.action_high - self.action_low)
        return choose_actions(
            mean, std, self.candidates, mode, beta=self.config.beta,
            noise_scale=self.config.action_noise * half, low=self.action_low,
            high=self.action_high, rng=self.rng,
        )  # fmt: skip

    # ------------------------------------------------------------------ learning
    def value_bounds(self) -> tuple[float, float]:
        """``[lo, hi]`` holding every target: ``lo = min(r_min, r_min / (1 - gamma))``, same for hi.

        ``r_min, r_max`` are the extreme rewards observed so far; a discounted
        return (or a bootstrapped target) of rewards in that range lies within.
        """
        lo, hi = self.reward_range
        g = self.config.gamma
        return min(lo, lo / (1.0 - g)), max(hi, hi / (1.0 - g))

    @single_blas_thread
    def learn(
        self,
        total_timesteps: int,
        progress_bar: bool = False,
        callback: Callable[[EpisodeRecord], bool | None] | None = None,
    ) -> GPQAgent:
        """Interact with the env for ``total_timesteps`` steps, learning online. Returns self.

        ``callback`` is called with each finished episode's record; returning
        ``False`` stops learning after that episode. A fitted-Q phase runs at the
        end, so the agent reflects every step taken. Each call starts a new
        episode, seeding the env's first reset from the agent's generator, so a
        saved and reloaded agent continues exactly as the original would; an
        episode cut short by ``total_timesteps`` is not recorded.
        """
        _check_int(total_timesteps, "total_timesteps", 0)
        env = self.env
        if env is None:
            raise RuntimeError("this agent has no env; pass env= to GPQAgent.load to keep learning")
        bar = None
        if progress_bar:
            from tqdm.auto import tqdm

            bar = tqdm(total=int(total_timesteps), unit="step")
        c = self.config
        done_steps = 0
        stop = False
        seed: int | None = int(self.rng.integers(2**32))
        while done_steps < total_timesteps and not stop:
            obs, _ = env.reset(seed=seed)
            seed = None  # later episodes continue the env's own seeded generator
            s, _ = self._check_obs(obs)
            if isinstance(self.gp.kernel, GraphKernel):
                self.gp.kernel.start_rollout()
            mean, std = self._q_or_none(s)
            ep_return, success = 0.0, float("nan")
            while done_steps < total_timesteps:
                if mean is None or std is None:  # warm-up: uniformly random actions
                    a = self.rng.uniform(self.action_low, self.action_high)[None, :]
                else:
                    a = self._act(mean, std, c.exploration)  # [1, d_a]
                obs2, r, terminated, truncated, info = env.step(a[0].astype(env.action_space.dtype))
                r = float(r)
                if not np.isfinite(r):
                    raise ValueError(f"the env returned a non-finite reward {r!r}")
                s2, _ = self._check_obs(obs2)
                self.reward_range = (min(self.reward_range[0], r), max(self.reward_range[1], r))
                mean, std = self._q_or_none(s2)
                q_next = 0.0 if mean is None or terminated else float(np.max(mean))
                y = float(
                    np.clip(r + (0.0 if terminated else c.gamma * q_next), *self.value_bounds())
                )
                self.buffer.add(s[0], a[0], r, s2[0], bool(terminated), target=y)
                if self.scaling_pending:
                    if len(self.buffer) >= c.warmup_steps:
                        self._finish_warmup()
                        mean, std = self.q_candidates(s2)
                else:
                    self.gp.update(self.inputs(s, a)[0], (y - self.y_mean) / self.y_scale)
                self.num_timesteps += 1
                done_steps += 1
                ep_return += r
                if bar is not None:
                    bar.update(1)
                episode_over = terminated or truncated
                if (self.num_timesteps % c.train_every == 0 or episode_over) and (
                    not self.scaling_pending
                ):
                    self.train()
                    if not episode_over:
                        mean, std = self.q_candidates(s2)
                if episode_over:
                    if "is_success" in info:
                        success = float(bool(info["is_success"]))
                    rec = EpisodeRecord(
                        self.num_timesteps, len(self.episodes) + 1, ep_return, success
                    )
                    self.episodes.append(rec)
                    if callback is not None and callback(rec) is False:
                        stop = True
                    break
                s = s2
        if (
            len(self.buffer)
            and not self.scaling_pending
            and (not self.episodes or self.episodes[-1].timesteps != self.num_timesteps)
        ):
            self.train()
        if bar is not None:
            bar.close()
        return self

    def _q_or_none(self, states: FloatArray) -> tuple[FloatArray | None, FloatArray | None]:
        """:meth:`q_candidates`, or ``(None, None)`` while the input scaling is pending."""
        return (None, None) if self.scaling_pending else self.q_candidates(states)

    def _finish_warmup(self) -> None:
        """Fix the input scaling from the warm-up's states and start learning on them."""
        self._rescale_from_data()
        self.scaling_pending = False
        self.train()

    def _data_scaling(self) -> InputScaling:
        env = self.env
        if env is None:
            raise RuntimeError("a data-driven scaling needs the env's spaces")
        obs_space, act_space = _check_spaces(env)
        S, _, _, S2, _ = self.buffer.arrays(last=self.config.window)
        d_s = self.obs_dim
        info = TaskInfo(periods=self.scaling.periods[:d_s], names=self.scaling.names[:d_s])
        return data_scaling(np.vstack([S, S2]), obs_space, act_space, info)

    def _rescale_from_data(self) -> None:
        """Scale inputs by the states seen, then stream the stored transitions into a new GP.

        Each transition enters with its current target (the warm-up's: its reward).
        """
        self.scaling = self._data_scaling()
        self.gp = self._new_gp()
        S, A, _, S2, _ = self.buffer.arrays(last=self.config.window)
        y = self.buffer.targets(last=self.config.window)
        graph = isinstance(self.gp.kernel, GraphKernel)
        X = self.inputs(S, A)
        for i in range(len(y)):
            if graph and (i == 0 or not np.array_equal(S[i], S2[i - 1])):
                self.gp.kernel.start_rollout()  # type: ignore[attr-defined]
            self.gp.update(X[i], (y[i] - self.y_mean) / self.y_scale)
        self.rescales += 1

    def _spread_outgrew_scaling(self) -> bool:
        """A data-driven scale is refreshed once the states' spread outgrows it by 1.5x."""
        new = np.asarray(self._data_scaling().scale)
        return bool(np.any(new > RESCALE_FACTOR * np.asarray(self.scaling.scale)))

    def train(self) -> int:
        """One fitted-Q phase on the stored transitions; returns the number of sweeps.

        Its wall time is added to :attr:`train_seconds` (the compute cost of replay).
        """
        if self.scaling_pending:
            return 0
        t0 = time.perf_counter()
        if self.data_scaled and self.env is not None and self._spread_outgrew_scaling():
            self._rescale_from_data()
        try:
            return self._train()
        finally:
            self.train_seconds += time.perf_counter() - t0

    @single_blas_thread
    def _train(self) -> int:
        c = self.config
        S, A, R, S2, term = self.buffer.arrays(last=c.window)
        if len(R) == 0:
            return 0
        N = len(R)
        X = self.inputs(S, A)  # [N, d]
        gp = self.gp
        bounds = self.value_bounds()
        y0 = np.clip(self.buffer.targets(last=N), *bounds)  # warm start: the last targets
        if c.replay == "graph" and gp.n_bv > 0:
            S, A, R, S2, term, y0 = self._add_imagined(S, A, R, S2, term, y0, bounds)
            X = self.inputs(S, A)
        if gp.kernel.tracks_basis:  # K_BV follows a graph: factor the current one afresh
            gp.refit(X, (y0 - self.y_mean) / self.y_scale)
        m = gp.n_bv
        if m == 0:
            return 0
        if c.replay == "none":  # no re-bootstrapping: refit to the online targets
            self.y_mean, self.y_scale = self._standardisation(y0, bounds)
            gp.refit(X, (y0 - self.y_mean) / self.y_scale)
            self.fitted_q_sweeps.append(0)
            return 0
        Rf = gp.cholesky_factor  # [m, m] upper, K_BV = R^T R
        bv = gp.basis_vectors
        V = scipy.linalg.solve_triangular(Rf, gp.kernel.to_basis(X, bv).T, trans="T")  # [m, N]
        K_next = gp.kernel.to_basis(self._candidate_inputs(S2), bv)  # [N K, m]
        result = fitted_q_sweeps(
            V, K_next, Rf, c.noise, R, 1.0 - term.astype(np.float64), c.gamma, y0,
            y_mean=self.y_mean, y_scale=self.y_scale, max_sweeps=c.max_sweeps,
            tol=c.sweep_tol * self.y_scale, bounds=bounds,
        )  # fmt: skip
        y = result.targets
        self.buffer.set_targets(y[:N])
        self.y_mean, self.y_scale = self._standardisation(y[:N], bounds)
        # The posterior the agent acts with is fit to the stored transitions only: imagined
        # ones (replay="graph") shape their targets, not the uncertainty that drives
        # exploration (measured: fitting them too, 0 of 4 seeds learned the swing-up).
        gp.refit(X[:N], (y[:N] - self.y_mean) / self.y_scale)
        self.fitted_q_sweeps.append(result.sweeps)
        return result.sweeps

    def _add_imagined(
        self,
        S: FloatArray,
        A: FloatArray,
        R: FloatArray,
        S2: FloatArray,
        term: np.ndarray,
        y0: FloatArray,
        bounds: tuple[float, float],
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray, FloatArray]:
        """The stored transitions followed by the graph model's imagined ones (replay="graph").

        Sources are ranked by the absolute TD error of their stored target under the
        current posterior, ``|r + gamma (1 - term) max_k Q(s', a_k) - y|``; the imagined
        transitions start from the posterior mean at their inputs.
        """
        c = self.config
        mean_next, _ = self.q_candidates(S2)
        td = R + c.gamma * (1.0 - term) * mean_next.max(axis=1) - y0
        units = np.asarray(self.scaling.scale) * np.broadcast_to(
            np.asarray(self._lengthscale(), dtype=np.float64), (self.scaling.dim,)
        )
        space = self.env.observation_space if self.env is not None else None
        low = high = None
        if isinstance(space, spaces.Box):
            low = np.where(np.isfinite(space.low), space.low, -np.inf).astype(np.float64)
            high = np.where(np.isfinite(space.high), space.high, np.inf).astype(np.float64)
        im = imagine_transitions(
            S, A, R, S2, term, units=units, periods=np.asarray(self.scaling.periods),
            candidates=self.candidates, priority=np.abs(td), budget=c.replay_budget,
            eps=c.replay_eps, obs_low=low, obs_high=high,
        )  # fmt: skip
        self.imagined_counts.append(len(im))
        if len(im) == 0:
            return S, A, R, S2, term, y0
        y_im = self.y_mean + self.y_scale * self.gp.predict(self.inputs(im.states, im.actions))
        return (
            np.vstack([S, im.states]), np.vstack([A, im.actions]),
            np.concatenate([R, im.rewards]), np.vstack([S2, im.next_states]),
            np.concatenate([term, im.terminated]),
            np.concatenate([y0, np.clip(y_im, *bounds)]),
        )  # fmt: skip

    def _standardisation(self, y: FloatArray, bounds: tuple[float, float]) -> tuple[float, float]:
        """``(y_mean, y_scale)`` for the configured prior (see :attr:`GPQConfig.prior`)."""
        lo, hi = bounds
        floor = 1e-6 * max(abs(lo), abs(hi), 1.0)  # all rewards equal: keep a positive scale
        if self.config.prior == "empirical":
            return float(np.mean(y)), max(float(np.std(y)), floor)
        half = max(0.5 * (hi - lo), floor)
        return (hi if self.config.prior == "optimistic" else 0.5 * (lo + hi)), half

    # ------------------------------------------------------------------ persistence
    def save(self, path: str | PathLike[str]) -> None:
        """Save the agent (config, GP, transitions, counters, generator state) as ``.npz``."""
        arrays: dict[str, Any] = {f"gp/{k}": v for k, v in self.gp.to_arrays().items()}
        arrays.update({f"buffer/{k}": v for k, v in self.buffer.to_arrays().items()})
        meta = {
            "config": self.config.as_dict(),
            "scaling": self.scaling.as_dict(),
            "env_id": self.env_id,
            "seed": self.seed,
            "rng_state": self.rng.bit_generator.state,
            "y_mean": self.y_mean,
            "y_scale": self.y_scale,
            "reward_range": list(self.reward_range),
            "num_timesteps": self.num_timesteps,
            "fitted_q_sweeps": self.fitted_q_sweeps,
            "imagined_counts": self.imagined_counts,
            "train_seconds": self.train_seconds,
            "scaling_pending": self.scaling_pending,
            "data_scaled": self.data_scaled,
            "rescales": self.rescales,
        }
        arrays["meta"] = np.asarray(json.dumps(meta, allow_nan=True))
        arrays["episodes"] = np.array(
            [[e.timesteps, e.episode, e.ret, e.success] for e in self.episodes], dtype=np.float64
        ).reshape(-1, 4)
        arrays["candidates"] = self.candidates
        arrays["action_box"] = np.vstack([self.action_low, self.action_high])
        arrays["obs_dim"] = np.int64(self.obs_dim)
        save_archive(path, _ARCHIVE_KIND, _ARCHIVE_VERSION, arrays)

    @classmethod
    def load(cls, path: str | PathLike[str], env: gymnasium.Env | str | None = None) -> GPQAgent:
        """Load an agent written by :meth:`save`.

        ``env``: the env to keep learning in (its spaces must match the saved
        ones); by default the saved env id is made again if it is registered,
        else the agent can only :meth:`predict`.
        """
        _, a = load_archive(path, _ARCHIVE_KIND, _ARCHIVE_VERSION)
        try:
            meta = json.loads(str(a["meta"]))
            config = GPQConfig.from_dict(meta["config"])
            sc = meta["scaling"]
            scaling = InputScaling(tuple(sc["scale"]), tuple(sc["periods"]), tuple(sc["names"]))
            box = np.asarray(a["action_box"], dtype=np.float64)
            candidates = np.asarray(a["candidates"], dtype=np.float64)
            obs_dim = int(a["obs_dim"])
            gp = SparseOnlineGP.from_arrays(
                {k[3:]: v for k, v in a.items() if k.startswith("gp/")}, source=path
            )
            buffer = TransitionBuffer.from_arrays(
                {k[7:]: v for k, v in a.items() if k.startswith("buffer/")}
            )
            episodes = np.asarray(a["episodes"], dtype=np.float64)
        except ArchiveError:
            raise
        except (KeyError, ValueError, TypeError) as exc:
            raise ArchiveError(
                f"{path}: not a valid GPQAgent archive ({exc}); save it again"
            ) from exc
        d_a = box.shape[1] if box.ndim == 2 else -1
        if (
            box.shape != (2, d_a) or candidates.ndim != 2 or candidates.shape[1] != d_a
            or scaling.dim != obs_dim + d_a or buffer.obs_dim != obs_dim
            or buffer.action_dim != d_a or episodes.ndim != 2 or episodes.shape[1] != 4
            or not (np.all(np.isfinite(box)) and np.all(np.isfinite(candidates)))
            or np.any(candidates < box[0]) or np.any(candidates > box[1])
            or not np.isfinite(meta["y_mean"]) or not (meta["y_scale"] > 0)
        ):  # fmt: skip
            raise ArchiveError(f"{path}: inconsistent GPQAgent archive; save it again")
        agent = cls.__new__(cls)
        agent.config, agent.scaling = config, scaling
        agent.obs_dim, agent.action_dim = obs_dim, d_a
        agent.action_low, agent.action_high = box[0].copy(), box[1].copy()
        agent.env_id = str(meta["env_id"])
        agent.seed = meta["seed"]
        agent.rng = np.random.default_rng()
        agent.rng.bit_generator.state = meta["rng_state"]
        agent.candidates = candidates
        agent.gp, agent.buffer = gp, buffer
        agent.y_mean, agent.y_scale = float(meta["y_mean"]), float(meta["y_scale"])
        lo, hi = meta["reward_range"]
        agent.reward_range = (float(lo), float(hi))
        agent.num_timesteps = int(meta["num_timesteps"])
        agent.fitted_q_sweeps = [int(v) for v in meta["fitted_q_sweeps"]]
        agent.imagined_counts = [int(v) for v in meta.get("imagined_counts", [])]
        agent.train_seconds = float(meta.get("train_seconds", 0.0))
        agent.scaling_pending = bool(meta.get("scaling_pending", False))
        agent.data_scaled = bool(meta.get("data_scaled", False))
        agent.rescales = int(meta.get("rescales", 0))
        agent.episodes = [
            EpisodeRecord(int(t), int(e), float(r), float(s)) for t, e, r, s in episodes
        ]
        agent.env = None
        if env is None and agent.env_id and agent.env_id in gymnasium.registry:
            env = agent.env_id
        if env is not None:
            agent.set_env(env)
        return agent

    def set_env(self, env: gymnasium.Env | str) -> None:
        """Attach an env whose spaces match the agent's."""
        e = _as_env(env)
        obs_space, act_space = _check_spaces(e)
        if obs_space.shape != (self.obs_dim,) or act_space.shape != (self.action_dim,):
            raise ValueError(
                f"env spaces {obs_space.shape}/{act_space.shape} do not match the agent's "
                f"({self.obs_dim},)/({self.action_dim},)"
            )
        if not (
            np.allclose(act_space.low, self.action_low)
            and np.allclose(act_space.high, self.action_high)
        ):
            raise ValueError("the env's action bounds differ from the agent's")
        self.env = e

    def __repr__(self) -> str:
        return (
            f"GPQAgent(env={self.env_id or '?'}, kernel={self.config.kernel!r}, "
            f"max_bv={self.config.max_bv}, timesteps={self.num_timesteps})"
        )
