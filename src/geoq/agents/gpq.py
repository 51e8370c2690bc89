"""``GPQAgent``: online GP Q-learning for continuous control (beyond the paper).

The paper's future work (JC12 §6): "applying the presented method in a policy
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
4. **Fitted-Q phases** every ``train_every`` (25) steps while the data are few,
   then each time they grew by ``train_fraction`` (5%), and at each episode's end:
   targets of every stored transition are re-bootstrapped to convergence on the
   current basis set and kernel (:mod:`geoq.agents.fitted_q`), then the
   posterior is refit to them (DTC, :meth:`SparseOnlineGP.refit`).
5. **Standardisation.** The GP sees ``z = (y - y_mean) / y_scale``; after each
   phase ``y_mean, y_scale`` become the mean and standard deviation of the
   targets, so the prior mean (the value of what was never tried) is the
   average value seen and the prior std is the spread of values.
6. **Threads.** ``learn`` and ``train`` run on one BLAS thread (the library's
   policy, :mod:`geoq._threads`): their matrices have a few hundred rows.
7. **Bounded targets.** Targets are clipped to :meth:`GPQAgent.value_bounds`,
   ``[r_min, r_max] / (1 - gamma)`` of the rewards declared or observed so far,
   widened by the rewards of terminating steps (received once, they count by
   themselves): every discounted return lies there, and without it regression +
   max diverged (targets of 3e5 after 9 episodes on the swing-up).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import fields
from os import PathLike
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from geoq._threads import single_blas_thread
from geoq._typing import FloatArray, IntArray
from geoq.agents._covariance_cache import NextStateCovariances, separable_factors
from geoq.agents._persist import load_agent, save_agent
from geoq.agents.acquisition import Exploration, candidate_actions, choose_actions
from geoq.agents.buffer import EpisodeRecord, TransitionBuffer
from geoq.agents.config import REPLAYS, GPQConfig, check_int, default_max_bv
from geoq.agents.fitted_q import (
    CandidateCovariances,
    DenseCandidates,
    SeparableCandidates,
    fitted_q_sweeps,
)
from geoq.agents.graph_replay import imagine_transitions
from geoq.gp import SparseOnlineGP
from geoq.gp.evidence import fit_squared_exponential
from geoq.gp.numerics import NumericalWarning
from geoq.kernels.geodesic import GraphKernel
from geoq.learners.q_gp import KernelName, QGPConfig, make_kernel
from geoq.learners.scaling import InputScaling
from geoq.tasks import TaskInfo, box_scaling, data_scaling, has_finite_bounds, task_info

__all__ = ["REPLAYS", "EpisodeRecord", "GPQAgent", "GPQConfig"]

#: A data-driven input scale is refreshed when the states' spread outgrows it by this factor.
RESCALE_FACTOR = 1.5
#: ``hyperparameters="evidence"``: points of each fit (O(n^3) per evaluation) and its
#: random restarts beyond the warm start (the length-scales in use).
EVIDENCE_POINTS = 300
EVIDENCE_RESTARTS = 1


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
    max_bv : basis-vector budget of the sparse GP (default: :func:`default_max_bv` of
        ``d_s + d_a``, 400 up to 3 inputs, 800 beyond).
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
        max_bv: int | None = None,
        seed: int | None = None,
        *,
        periods: Sequence[float] | None = None,
        scaling: InputScaling | None = None,
        **config: Any,
    ) -> None:
        unknown = sorted(set(config) - {f.name for f in fields(GPQConfig)})
        if unknown:
            raise TypeError(f"GPQAgent got unknown argument(s) {unknown}")
        self.env: gymnasium.Env | None = _as_env(env)
        obs_space, act_space = _check_spaces(self.env)
        self.obs_dim = int(obs_space.shape[0])
        self.action_dim = int(act_space.shape[0])
        if max_bv is None:
            max_bv = default_max_bv(self.obs_dim + self.action_dim)
        self.config = GPQConfig(kernel=kernel, max_bv=max_bv, **config)
        #: Length-scales fitted by evidence (``hyperparameters="evidence"``), else None.
        self.fitted_lengthscale: tuple[float, ...] | None = None
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
        declared = self.config.reward_bounds or info.reward_range
        #: Extreme rewards of the steps that did not end an episode (declared, then widened
        #: by those seen); see :meth:`value_bounds`.
        self.reward_range: tuple[float, float] = (
            (float(declared[0]), float(declared[1])) if declared else (np.inf, -np.inf)
        )
        terminal = self.config.terminal_reward_bounds or info.terminal_reward_range
        #: Extreme rewards of the steps that ended an episode (``terminated``), likewise.
        self.terminal_reward_range: tuple[float, float] = (
            (float(terminal[0]), float(terminal[1])) if terminal else (np.inf, -np.inf)
        )
        self.num_timesteps = 0
        #: ``num_timesteps`` at the last fitted-Q phase (``train_fraction``).
        self.last_train_timestep = 0
        self.episodes: list[EpisodeRecord] = []
        self.fitted_q_sweeps: list[int] = []
        #: Per fitted-Q phase, the largest change of a target in its last sweep (return
        #: units; 0 without sweeps). Above ``sweep_tol`` x the phase's ``y_scale``: it
        #: stopped at ``max_sweeps`` without converging (docs/design-notes.md).
        self.fitted_q_residuals: list[float] = []
        self.imagined_counts: list[int] = []
        self.train_seconds = 0.0
        self.rescales = 0
        #: One record per evidence fit: transitions, length-scales, log evidence, ...
        self.evidence_fits: list[dict[str, Any]] = []
        #: The next evidence fit runs once this many transitions are stored.
        self.evidence_due = 0
        self._next_covariances = NextStateCovariances(self.max_bv)

    # ------------------------------------------------------------------ set-up
    @property
    def max_bv(self) -> int:
        """The basis-vector budget: ``config.max_bv``, or :func:`default_max_bv` if None."""
        c = self.config
        return c.max_bv if c.max_bv is not None else default_max_bv(self.obs_dim + self.action_dim)

    def _lengthscale(self) -> float | tuple[float, ...]:
        c = self.config
        if self.fitted_lengthscale is not None:
            return self.fitted_lengthscale
        if c.lengthscale is None:
            return (c.state_lengthscale,) * self.obs_dim + (c.action_lengthscale,) * self.action_dim
        if isinstance(c.lengthscale, tuple):
            return tuple(float(v) for v in c.lengthscale)
        return float(c.lengthscale)

    def _q_config(self) -> QGPConfig:
        c = self.config
        ls = self._lengthscale()
        return QGPConfig(
            kernel=c.kernel, max_bv=self.max_bv, tol=c.tol, noise=c.noise, lengthscale=ls,
            amplitude=c.amplitude, eps=c.eps, sigma_sp=c.sigma_sp, sigma_se=c.sigma_se,
            resistance_lengthscale=c.resistance_lengthscale,
            wrap_angle=bool(np.any(np.asarray(self.scaling.periods) > 0)),
            attach_weights=c.kernel == "interpolated", scaling=self.scaling,
        )  # fmt: skip

    def _new_gp(self) -> SparseOnlineGP:
        c = self.config
        return SparseOnlineGP(
            make_kernel(self._q_config()), noise=c.noise, max_bv=self.max_bv, tol=c.tol
        )

    # ------------------------------------------------------------------ inputs
    def inputs(self, states: FloatArray, actions: FloatArray) -> FloatArray:
        """Scaled GP inputs ``[N, d_s + d_a]`` of states ``[N, d_s]`` and actions ``[N, d_a]``."""
        return self.scaling.transform(np.hstack([states, actions]))

    def _candidate_inputs(self, states: FloatArray) -> FloatArray:
        """Inputs ``[n K, d]`` of every state ``[n, d_s]`` (validated float64) paired with
        every candidate: :meth:`inputs`' bits (each column divided by its scale), built
        in place (an agent step's call)."""
        n, K, d_s = states.shape[0], self.candidates.shape[0], self.obs_dim
        scale = np.asarray(self.scaling.scale, dtype=np.float64)
        X = np.empty((n * K, scale.shape[0]))
        X[:, :d_s] = np.repeat(states / scale[:d_s], K, axis=0)
        X[:, d_s:] = np.tile(self.candidates / scale[d_s:], (n, 1))
        return X

    def q_candidates(self, states: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Posterior mean and std of ``Q`` ``[n, K]`` at every state x candidate (one GP call)."""
        mean, std = self.gp.predict(self._scaled_candidate_inputs(states), return_std=True)
        n = states.shape[0]
        return (self.y_mean + self.y_scale * mean).reshape(n, -1), (self.y_scale * std).reshape(
            n, -1
        )

    def q_mean(self, states: FloatArray) -> FloatArray:
        """Posterior mean of ``Q`` ``[n, K]`` at every state x candidate: the mean of
        :meth:`q_candidates` bit for bit, without the O(m^2)-per-point std."""
        mean = self.gp.predict(self._scaled_candidate_inputs(states))
        return (self.y_mean + self.y_scale * mean).reshape(states.shape[0], -1)

    def _scaled_candidate_inputs(self, states: FloatArray) -> FloatArray:
        if self.scaling_pending:
            raise ValueError(
                "the observation space has infinite bounds and the agent has not yet seen the "
                f"{self.config.warmup_steps} warm-up steps that fix its input scaling: call "
                "learn() first, or pass scaling= with a finite scale per dimension"
            )
        return self._candidate_inputs(states)

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
        """``[lo, hi]`` holding every target.

        ``lo = min(r_min, r_min / (1 - gamma), t_min)``, ``hi = max(r_max, r_max / (1 -
        gamma), t_max)`` with ``[r_min, r_max]`` the range of the rewards of steps that do
        not end an episode and ``[t_min, t_max]`` of those that do (declared or seen).
        A discounted return is ``sum_{t<k} gamma^t r_t + gamma^k t_k``: between
        ``r / (1 - gamma)`` and ``t`` for constant rewards, so within the bounds.
        """
        lo, hi = self.reward_range
        t_lo, t_hi = self.terminal_reward_range
        g = self.config.gamma
        return min(lo, lo / (1.0 - g), t_lo), max(hi, hi / (1.0 - g), t_hi)

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
        check_int(total_timesteps, "total_timesteps", 0)
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
                if terminated:
                    t_lo, t_hi = self.terminal_reward_range
                    self.terminal_reward_range = (min(t_lo, r), max(t_hi, r))
                else:
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
                if (self._phase_due() or episode_over) and not self.scaling_pending:
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

    def _phase_due(self) -> bool:
        """Whether a fitted-Q phase is due mid-episode (``train_every``, ``train_fraction``)."""
        c = self.config
        if self.num_timesteps % c.train_every:
            return False
        new = self.num_timesteps - self.last_train_timestep
        return new >= c.train_fraction * min(len(self.buffer), c.window)

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
        """Scale inputs by the states seen, then stream the stored transitions into a new GP."""
        self.scaling = self._data_scaling()
        self._restream()
        self.rescales += 1

    def _restream(self) -> None:
        """A new GP (current scaling and length-scales) fed the stored transitions in order.

        Each transition enters with its current target (the warm-up's: its reward).
        """
        self._next_covariances.clear()  # new inputs or kernel
        self.gp = self._new_gp()
        S, A, _, S2, _ = self.buffer.arrays(last=self.config.window)
        y = self.buffer.targets(last=self.config.window)
        graph = isinstance(self.gp.kernel, GraphKernel)
        X = self.inputs(S, A)
        for i in range(len(y)):
            if graph and (i == 0 or not np.array_equal(S[i], S2[i - 1])):
                self.gp.kernel.start_rollout()  # type: ignore[attr-defined]
            self.gp.update(X[i], (y[i] - self.y_mean) / self.y_scale)

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
        self.last_train_timestep = self.num_timesteps
        t0 = time.perf_counter()
        if self.data_scaled and self.env is not None and self._spread_outgrew_scaling():
            self._rescale_from_data()
        if self.config.hyperparameters == "evidence" and len(self.buffer) >= self.evidence_due:
            self._fit_lengthscales()
        try:
            return self._train()
        finally:
            self.train_seconds += time.perf_counter() - t0

    def _fit_lengthscales(self) -> None:
        """Squared-exponential length-scales by maximum evidence (``hyperparameters="evidence"``).

        Fitted on the stored inputs and their current standardised targets (at most
        :data:`EVIDENCE_POINTS`, drawn with the agent's generator), from the length-scales
        in use plus :data:`EVIDENCE_RESTARTS` random starts; the GP is rebuilt with them.
        The fit's :class:`NumericalWarning` are recorded in :attr:`evidence_fits`.
        """
        c = self.config
        S, A, _, _, _ = self.buffer.arrays(last=c.window)
        z = (self.buffer.targets(last=c.window) - self.y_mean) / self.y_scale
        n, d = len(z), self.scaling.dim
        self.evidence_due = 2 * n
        if n < 2 or np.ptp(z) == 0.0:
            return  # equal targets say nothing about length-scales
        start = np.broadcast_to(np.asarray(self._lengthscale(), dtype=np.float64), (d,))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", NumericalWarning)
            fit = fit_squared_exponential(
                self.inputs(S, A), z, lengthscale0=start, ard=True,
                max_points=EVIDENCE_POINTS, n_restarts=EVIDENCE_RESTARTS,
                rng=np.random.default_rng(self.rng.integers(2**32)),
            )  # fmt: skip
        ls = tuple(float(v) for v in np.broadcast_to(fit.kernel.lengthscale, (d,)))
        self.evidence_fits.append({
            "transitions": n, "lengthscale": list(ls), "log_evidence": fit.log_evidence,
            "log_evidence_start": fit.log_evidence_start, "converged": fit.converged,
            "at_bound": list(fit.at_bound), "warnings": [str(w.message) for w in caught],
        })  # fmt: skip
        self.fitted_lengthscale = ls
        self._restream()

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
        if gp.n_bv == 0:
            return 0
        # V = R^{-T} K_BX and B^{-1} on a fresh factor of the current K_BV (a graph kernel's
        # follows its graph), formed once: every sweep and the final refit use them.
        system = gp.projected_system(X)
        if c.replay == "none":  # no re-bootstrapping: refit to the online targets
            self.y_mean, self.y_scale = self._standardisation(y0, bounds)
            gp.refit_projected(system, (y0 - self.y_mean) / self.y_scale)
            self.fitted_q_sweeps.append(0)
            self.fitted_q_residuals.append(0.0)
            return 0
        K_next, slots = self._next_state_covariances(S2, N, gp.basis_vectors)
        result = fitted_q_sweeps(
            system, K_next, R, 1.0 - term.astype(np.float64), c.gamma, y0,
            y_mean=self.y_mean, y_scale=self.y_scale, max_sweeps=c.max_sweeps,
            tol=c.sweep_tol * self.y_scale, bounds=bounds, slots=slots,
        )  # fmt: skip
        y = result.targets
        self.buffer.set_targets(y[:N])
        self.y_mean, self.y_scale = self._standardisation(y[:N], bounds)
        # The posterior the agent acts with is fit to the stored transitions only: imagined
        # ones (replay="graph") shape their targets, not the uncertainty that drives
        # exploration (docs/design-notes.md).
        stored = system if system.n_inputs == N else system.head(N)
        gp.refit_projected(stored, (y[:N] - self.y_mean) / self.y_scale)
        self.fitted_q_sweeps.append(result.sweeps)
        self.fitted_q_residuals.append(result.max_change)
        return result.sweeps

    def _next_state_covariances(
        self, S2: FloatArray, n_stored: int, bv: FloatArray
    ) -> tuple[CandidateCovariances, IntArray]:
        """``k([s'_i, a_k], BV)`` for the next states ``S2`` x candidates, basis vector ``j``
        in column ``slots[j]``, and ``slots`` ``[m]``. The first ``n_stored`` next states
        are the stored transitions', kept from phase to phase where the kernel allows
        (:class:`NextStateCovariances`; only their state factor, the squared exponential
        being a product of a state and an action factor), the rest imagined ones
        (computed)."""
        kernel, n_cand = self.gp.kernel, self.candidates.shape[0]
        factors = None if kernel.tracks_basis else separable_factors(kernel, self.obs_dim)
        if factors is None:
            dense = kernel.to_basis(self._candidate_inputs(S2), bv)
            return DenseCandidates(dense, n_cand), np.arange(bv.shape[0])
        state, action = factors
        scale = np.asarray(self.scaling.scale, dtype=np.float64)
        d_s = self.obs_dim
        K_state, slots = self._next_covariances.get(
            state, lambda X: X / scale[:d_s], S2[:n_stored], len(self.buffer) - n_stored, bv,
            1, scratch_states=S2[n_stored:] if len(S2) > n_stored else None,
        )  # fmt: skip
        K_action = np.zeros((n_cand, K_state.shape[1]))
        K_action[:, slots] = action.to_basis(
            self.candidates / scale[d_s:], np.ascontiguousarray(bv[:, d_s:])
        )
        return SeparableCandidates(K_state, K_action), slots

    def _stored_next_q(self, S2: FloatArray) -> FloatArray:
        """Posterior mean of ``Q`` ``[N, K]`` at the stored next states ``S2`` (the last
        ``N`` transitions) x candidates: :meth:`q_mean` up to rounding, but from the kept
        covariances (no kernel evaluation) where the kernel allows."""
        gp = self.gp
        if gp.kernel.tracks_basis:
            return self.q_mean(S2)
        K_next, slots = self._next_state_covariances(S2, len(S2), gp.basis_vectors)
        weights = np.zeros(K_next.n_columns)
        weights[slots] = gp.alpha
        return self.y_mean + self.y_scale * K_next.q(weights)

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
        td = R + c.gamma * (1.0 - term) * self._stored_next_q(S2).max(axis=1) - y0
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
        save_agent(self, path)

    @classmethod
    def load(cls, path: str | PathLike[str], env: gymnasium.Env | str | None = None) -> GPQAgent:
        """Load an agent written by :meth:`save`.

        ``env``: the env to keep learning in (its spaces must match the saved
        ones); by default the saved env id is made again if it is registered,
        else the agent can only :meth:`predict`.
        """
        return load_agent(cls, path, env)

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
