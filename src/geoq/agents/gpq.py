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
2. **Acting.** One batched GP call per step gives the posterior mean and std of ``Q(s, a_k)``
   at ``K`` candidate actions (a grid in 1-D, refined by parabolic interpolation; a Sobol'
   set in more dimensions); the action maximises the acquisition
   (:mod:`geoq.agents.acquisition`): UCB ``mean + beta std`` (GP-UCB), Thompson-style
   samples, or the greedy action plus Gaussian noise. Greedy past one action dimension:
   the best action taken near the state (:mod:`geoq.agents.greedy_data`), the action
   ``gaussian`` noises.
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
5. **Standardisation.** The GP sees ``z = (y - y_mean) / y_scale``, set after each phase
   by ``prior`` (:class:`GPQConfig`): the prior mean, the value of what was never tried,
   the upper value bound (optimism) where ``Q`` alone learns, the prior std half the range.
6. **Exploration over states** where the moves are the actions' own (``explore_map``):
   a map of the observed moves (:mod:`geoq.agents.map_explorer`) picks the training
   actions, and the greedy ones where it knows a route to a termination.
7. **Bounded targets.** Targets are clipped to :meth:`GPQAgent.value_bounds`, where
   every discounted return lies (without it regression + max diverged).
8. **Planning** (``planner``): acting through a GP model (:mod:`~geoq.agents.model_planning`);
   or (``actor``) a policy trained on ``Q``'s mean (:mod:`~geoq.agents.q_actor`); greedy,
   the ``Q`` that did best in training (``keep_q``, :mod:`~geoq.agents.kept_q`).

**Threads.** ``learn`` and ``train`` run on one BLAS thread (:mod:`geoq._threads`). A learning
step (an env step, its phase, an episode's callback) holds the agent's re-entrant lock, as do
``predict`` (which, greedy, draws nothing), ``q_candidates``, ``q_mean``, ``train``, ``save``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import fields
from os import PathLike
from typing import Any

import gymnasium
import numpy as np

from geoq._threads import single_blas_thread
from geoq._typing import FloatArray
from geoq.agents import _env
from geoq.agents._evidence import refit_lengthscales
from geoq.agents._persist import load_agent, save_agent
from geoq.agents.acquisition import candidate_actions, choose_actions
from geoq.agents.buffer import EpisodeRecord, TransitionBuffer, Transitions
from geoq.agents.config import REPLAYS, GPQConfig, check_learn_arguments, check_seed
from geoq.agents.fitted_q import FittedQPhase, PhaseInputs
from geoq.agents.greedy_data import act_in_data
from geoq.agents.kept_q import KeptQ
from geoq.agents.map_explorer import MapExplorer
from geoq.agents.model_planning import ModelPlanning
from geoq.agents.phase_inputs import phase_inputs_of
from geoq.agents.q_actor import QActor
from geoq.agents.replay import replay_strategy
from geoq.agents.state import LearningState, TrainingLog, as_range, check_target
from geoq.gp import SparseOnlineGP
from geoq.kernels import KernelName
from geoq.kernels.geodesic import GraphKernel
from geoq.learners.scaling import InputScaling
from geoq.tasks import task_info

__all__ = ["REPLAYS", "EpisodeRecord", "GPQAgent", "GPQConfig"]

#: A data-driven input scale is refreshed when the states' spread outgrows it by this factor.
RESCALE_FACTOR = 1.5

#: ``Q``'s posterior mean and std ``[n, K]`` at states x candidates (None: scaling pending).
QValues = tuple[FloatArray, FloatArray] | None
#: Called with each finished episode's record; ``False`` stops learning.
Callback = Callable[[EpisodeRecord], bool | None] | None


class GPQAgent:
    """Online GP Q-learning agent (see the module docstring for the algorithm).

    Parameters
    ----------
    env : a ``gymnasium.Env`` with a 1-D Box observation space and a 1-D Box
        action space with finite bounds, or the id of a registered one.
    kernel : ``"euclidean" | "nearest" | "interpolated" | "resistance"``.
    max_bv : basis-vector budget of the sparse GP (default: :func:`default_max_bv`).
    seed : seed of every random choice (exploration, candidates, env resets).
    periods : wrap-around period per observation (raw units, 0: none); known when bundled.
    scaling : input scaling of ``[s, a]`` (default: the spaces' half-ranges).
    **config : any other field of :class:`GPQConfig`.

    Attributes
    ----------
    config : the settings, resolved (``max_bv`` a number).
    gp : the sparse online GP of the standardised ``Q`` (scaled inputs).
    buffer : the transitions seen and their current targets.
    state : what the agent has learned besides (:class:`LearningState`).
    log : what it recorded while learning (:class:`TrainingLog`).
    phase : the fitted-Q phase (:class:`FittedQPhase`) with its replay strategy.
    explorer : the exploration map, once decided on (:class:`MapExplorer`).
    kept_q : the copy of ``Q`` greedy actions follow (:class:`~geoq.agents.kept_q.KeptQ`).
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
        self.env: gymnasium.Env | None = _env.as_env(env)
        obs_space, act_space = _env.agent_spaces(self.env)
        obs_dim, action_dim = int(obs_space.shape[0]), int(act_space.shape[0])
        c = GPQConfig(kernel=kernel, max_bv=max_bv, **config)
        c = c.for_dims(obs_dim, action_dim, _env.time_limit(self.env))
        seed = check_seed(seed)
        info = task_info(self.env, periods)
        scaling, pending = _env.initial_scaling(self.env, info, scaling)
        rng = np.random.default_rng(np.random.SeedSequence(seed))
        low, high = act_space.low.astype(np.float64), act_space.high.astype(np.float64)
        state = LearningState(
            y_mean=0.0, y_scale=1.0 / (1.0 - c.gamma),
            reward_range=as_range(c.reward_bounds or info.reward_range),
            terminal_reward_range=as_range(c.terminal_reward_bounds or info.terminal_reward_range),
            scaling_pending=pending, data_scaled=pending,
        )  # fmt: skip
        self._assemble(
            config=c, scaling=scaling, action_box=np.vstack([low, high]), obs_dim=obs_dim,
            env_id=self.env.spec.id if self.env.spec is not None else "", seed=seed, rng=rng,
            candidates=candidate_actions(low, high, c.n_candidates, rng),  # [K, d_a]
            buffer=TransitionBuffer(obs_dim, action_dim), state=state, log=TrainingLog(),
        )  # fmt: skip
        self.gp = self._new_gp()

    # fmt: off
    def _assemble(
        self, *, config: GPQConfig, scaling: InputScaling, action_box: FloatArray,
        obs_dim: int, env_id: str, seed: int | None, rng: np.random.Generator,
        candidates: FloatArray, buffer: TransitionBuffer, state: LearningState, log: TrainingLog,
    ) -> None:
        # fmt: on
        """Set every attribute but ``gp`` and ``env`` (a new agent's or a loaded one's)."""
        self._lock = threading.RLock()  # a learning step, predict, save: module docstring
        self.config, self.scaling, self.obs_dim = config, scaling, obs_dim
        self.action_low, self.action_high = action_box[0].copy(), action_box[1].copy()
        self.action_dim = self.action_low.shape[0]
        self.env_id, self.seed, self.rng, self.candidates = env_id, seed, rng, candidates
        self.buffer, self.state, self.log = buffer, state, log
        replay = replay_strategy(config.replay, config.gamma, config.replay_budget,
                                 config.replay_eps)  # fmt: skip
        self.phase = FittedQPhase(config, replay)
        self.explorer = MapExplorer(config.explore_map, candidates, self.action_low,
                                    self.action_high, config.gamma)  # fmt: skip
        self.planning = ModelPlanning(config, obs_dim, self.action_low, self.action_high)
        self.actor = QActor(config.actor, self.action_low, self.action_high)
        self.kept_q = KeptQ(config.keep_q == "on")

    @property
    def max_bv(self) -> int:
        """The basis-vector budget (``config.max_bv``, resolved at construction)."""
        assert self.config.max_bv is not None
        return self.config.max_bv

    @property
    def num_timesteps(self) -> int:
        """Environment steps taken (``state.num_timesteps``)."""
        return self.state.num_timesteps

    @property
    def episodes(self) -> list[EpisodeRecord]:
        """The finished training episodes (``log.episodes``)."""
        return self.log.episodes

    def _lengthscale(self) -> float | tuple[float, ...]:
        return self.config.lengthscale_in_use(self.obs_dim, self.action_dim, self.state)

    def _new_gp(self) -> SparseOnlineGP:
        c, kernel = self.config, self.config.agent_kernel(self._lengthscale(), self.scaling)
        return SparseOnlineGP(kernel, noise=c.noise, max_bv=self.max_bv, tol=c.tol)

    # ------------------------------------------------------------------ inputs
    def inputs(self, states: FloatArray, actions: FloatArray) -> FloatArray:
        """Scaled GP inputs ``[N, d_s + d_a]`` of states ``[N, d_s]`` and actions ``[N, d_a]``."""
        return self.scaling.transform(np.hstack([states, actions]))

    def q_candidates(self, states: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Posterior mean and std of ``Q`` ``[n, K]`` at every state x candidate (one GP call)."""
        with self._lock:
            mean, std = self.gp.predict(self._scaled_candidate_inputs(states), return_std=True)
            y_mean, y_scale, n = self.state.y_mean, self.state.y_scale, states.shape[0]
        return (y_mean + y_scale * mean).reshape(n, -1), (y_scale * std).reshape(n, -1)

    def q_mean(self, states: FloatArray) -> FloatArray:
        """:meth:`q_candidates`'s mean ``[n, K]`` bit for bit, without the O(m^2)-per-point std."""
        with self._lock:
            mean = self.gp.predict(self._scaled_candidate_inputs(states))
            return (self.state.y_mean + self.state.y_scale * mean).reshape(states.shape[0], -1)

    def _scaled_candidate_inputs(self, states: FloatArray) -> FloatArray:
        if self.state.scaling_pending:
            raise ValueError(
                "the observation space has infinite bounds and the agent has not yet seen the "
                f"{self.config.warmup_steps} warm-up steps that fix its input scaling: call "
                "learn() first, or pass scaling= with a finite scale per dimension")  # fmt: skip
        return self.scaling.transform_pairs(states, self.candidates)

    # ------------------------------------------------------------------ acting
    def predict(self, observation: Any, deterministic: bool = True) -> tuple[FloatArray, None]:
        """The action ``[d_a]`` (or ``[n, d_a]`` for ``n`` observations) and ``None``.

        ``deterministic=True``: the greedy action (the posterior mean's best, the plan's, the
        kept ``Q``'s or the actor's); otherwise the configured exploration (drawing from the
        agent's generator).
        Before the warm-up has fixed a data-driven input scaling: the warm-up's policy."""
        if not isinstance(deterministic, bool | np.bool_):
            raise ValueError(f"deterministic must be True or False, got {deterministic!r}")
        with self._lock:  # between two learning steps of another thread
            S, single = _env.as_observations(observation, self.obs_dim, self._obs_scale())
            if self.state.scaling_pending:
                a = _env.warmup_actions(self.action_low, self.action_high, len(S), deterministic,
                                        self.rng)  # fmt: skip
                return (a[0] if single else a), None
            mean, std = self.q_candidates(S)
            if deterministic and self.planning.greedy_active:
                actions = np.vstack([self.planning.action(self, s[None], None) for s in S])
            elif deterministic and self.kept_q.kept is not None:
                actions = self.kept_q.greedy(self, S)
            elif deterministic and self.actor.ready:
                actions = self.actor.act(S)
            else:  # Q's own: greedy (drawing nothing) or exploring
                actions = self._act(S, mean, std, greedy=deterministic)
            actions = self.explorer.greedy(S, mean, actions) if deterministic else actions
            return (actions[0] if single else actions), None

    def _act(self, S: FloatArray, mean: FloatArray, std: FloatArray, greedy: bool) -> FloatArray:
        mode = "greedy" if greedy else self.config.exploration
        if self.config.greedy_actions == "data" and mode in ("greedy", "gaussian"):
            return act_in_data(self, S, mean, mode, self.rng)
        half, c = 0.5 * (self.action_high - self.action_low), self.config
        return choose_actions(mean, std, self.candidates, mode, beta=c.beta, rng=self.rng,
                              noise_scale=c.action_noise * half, low=self.action_low,
                              high=self.action_high)  # fmt: skip

    def _explore(self, s: FloatArray, q: QValues) -> FloatArray:
        """The action ``[1, d_a]`` at ``s [1, d_s]``: the map's if there is one, else uniform
        in the warm-up, else planned, else the actor's, else by ``exploration``."""
        a = self.explorer.action(s, self.rng)
        if a is not None:
            return a
        if q is None:
            return self.rng.uniform(self.action_low, self.action_high)[None, :]
        if self.planning.active:
            return self.planning.action(self, s, self.rng)
        if self.actor.ready:
            return self.actor.explore(s, self.config.action_noise, self.rng)
        return self._act(s, *q, greedy=False)

    def _obs_scale(self) -> FloatArray:
        return np.asarray(self.scaling.scale[: self.obs_dim])

    def _q_or_none(self, states: FloatArray) -> QValues:
        """:meth:`q_candidates`, or None while the input scaling is pending."""
        return None if self.state.scaling_pending else self.q_candidates(states)

    # ------------------------------------------------------------------ learning
    def value_bounds(self) -> tuple[float, float]:
        """``[lo, hi]`` holding every target (:meth:`LearningState.value_bounds`)."""
        return self.state.value_bounds(self.config.gamma)

    @single_blas_thread
    def learn(self, total_timesteps: int, progress_bar: bool = False,
              callback: Callback = None) -> GPQAgent:  # fmt: skip
        """Interact with the env for ``total_timesteps`` steps, learning online. Returns self.

        ``callback`` is called with each finished episode's record; ``False`` stops learning
        after that episode. A fitted-Q phase runs at the end. Each call starts a new episode,
        seeding the env's first reset from the agent's generator, so a saved and reloaded
        agent continues exactly as the original would; an episode cut short is not recorded.
        A step the env answers wrongly (:func:`~geoq.agents._env.env_step`) raises a
        ``ValueError`` and is not taken (the agent stays as after the step before).
        ``learn(0)`` changes nothing. Other threads may predict meanwhile."""
        check_learn_arguments(total_timesteps, progress_bar, callback)
        env = self.env
        if env is None:
            raise RuntimeError("this agent has no env; pass env= to GPQAgent.load to keep learning")
        if total_timesteps == 0:  # no episode to seed, no step to train on
            return self
        bar = _env.make_progress_bar(total_timesteps) if progress_bar else None
        start, n_before = self.rng.bit_generator.state, self.num_timesteps
        # Later episodes continue the env's own generator, seeded at the first reset.
        seed: int | None = int(self.rng.integers(2**32))
        remaining, stop = int(total_timesteps), False
        try:
            while remaining > 0 and not stop:
                steps, stop = self._collect_episode(env, seed, remaining, bar, callback)
                remaining, seed = remaining - steps, None
        except BaseException:
            if self.num_timesteps == n_before:  # no step taken: the generator as it was
                self.rng.bit_generator.state = start
            raise
        finally:
            if bar is not None:
                bar.close()
        with self._lock:
            last = self.log.episodes[-1].timesteps if self.log.episodes else None
            if len(self.buffer) and not self.state.scaling_pending and last != self.num_timesteps:
                self.train()  # the steps of an unfinished episode
            self.explorer.plan()
        return self

    def _collect_episode(self, env: gymnasium.Env, seed: int | None, max_steps: int, bar: Any,
                         callback: Callback) -> tuple[int, bool]:  # fmt: skip
        """One episode, or its first ``max_steps`` steps, learning online and training when
        a phase is due; returns the steps taken and whether the callback asked to stop.
        Each step (with its phase and, at the end, the callback) holds the agent's lock."""
        s = _env.env_reset(env, seed, self.obs_dim, self._obs_scale())
        q = self._q_or_none(s)  # (q_candidates holds the lock)
        self.planning.start_episode(s, self.buffer, self.rng)
        self.kept_q.start_episode(self)
        ep_return, steps = 0.0, 0
        while steps < max_steps:
            with self._lock:
                step, q = self._observe(env, s, q, first=steps == 0)
                steps, ep_return = steps + 1, ep_return + step.reward
                if bar is not None:
                    bar.update(1)
                over = step.terminated or step.truncated
                due = self.state.phase_due(self.config, len(self.buffer))
                if (due or over) and not self.state.scaling_pending:
                    self.train()
                    q = None if over else self.q_candidates(step.next_state)
                if over:
                    n = len(self.episodes) + 1
                    rec = EpisodeRecord(self.num_timesteps, n, ep_return, step.success)
                    self.log.episodes.append(rec)
                    self.kept_q.end_episode(ep_return)
                    return steps, callback is not None and callback(rec) is False
            s = step.next_state
        return steps, False

    def _observe(
        self, env: gymnasium.Env, s: FloatArray, q: QValues, first: bool = False
    ) -> tuple[_env.EnvStep, QValues]:
        """One step at ``s`` (``Q`` there: ``q``; ``first`` of its episode): act, check what
        the env returned, store the transition with its bootstrapped target and stream it
        into the GP (JC12 §6); returns the step and ``Q`` at its next state. A refused step
        raises before anything changes (the generator put back)."""
        st, g, rng_state = self.state, self.config.gamma, self.rng.bit_generator.state
        try:
            step = _env.env_step(env, self._explore(s, q), self.obs_dim, self._obs_scale())
            bounds = st.value_bounds_with(step.reward, step.terminated, g)
            q = self._q_or_none(step.next_state)
            q_next = 0.0 if q is None or step.terminated else float(np.max(q[0]))
            y = float(np.clip(step.reward + (0.0 if step.terminated else g * q_next), *bounds))
            if not st.scaling_pending:  # a GP update refused changes nothing
                z = check_target((y - st.y_mean) / st.y_scale, step.reward)
                if first and isinstance(self.gp.kernel, GraphKernel):
                    self.gp.kernel.start_rollout()
                self.gp.update(self.inputs(s, step.action)[0], z)
        except BaseException:
            self.rng.bit_generator.state = rng_state
            raise
        st.observe_reward(step.reward, step.terminated)
        self.buffer.add(s[0], step.action[0], step.reward, step.next_state[0], step.terminated,
                        target=y)  # fmt: skip
        self.explorer.observe(self.buffer, *_env.observation_box(env))
        self.planning.observe(self.buffer, self.rng)
        if st.scaling_pending and len(self.buffer) >= self.config.warmup_steps:
            self._finish_warmup()
            q = self.q_candidates(step.next_state)
        st.num_timesteps += 1
        return step, q

    def _finish_warmup(self) -> None:
        """Fix the input scaling from the warm-up's states and start learning on them."""
        self._rescale_from_data()
        self.state.scaling_pending = False
        self.train()

    def _data_scaling(self) -> InputScaling:
        stored = self.buffer.transitions(last=self.config.window)
        return _env.scaling_from_states(self.env, stored, self.scaling)

    def _rescale_from_data(self) -> None:
        """Scale inputs by the states seen, then stream the stored transitions into a new GP."""
        self.scaling = self._data_scaling()
        self._restream()
        self.log.rescales += 1

    def _restream(self) -> None:
        """A new GP (current scaling, length-scales) fed the stored transitions and targets."""
        self.phase.covariances.clear()  # new inputs or kernel
        self.gp = self._new_gp()
        stored = self.buffer.transitions(last=self.config.window)
        y = self.buffer.targets(last=self.config.window)
        graph = isinstance(self.gp.kernel, GraphKernel)
        S, S2 = stored.states, stored.next_states
        X = self.inputs(S, stored.actions)
        for i in range(len(y)):
            if graph and (i == 0 or not np.array_equal(S[i], S2[i - 1])):
                self.gp.kernel.start_rollout()  # type: ignore[attr-defined]
            self.gp.update(X[i], (y[i] - self.state.y_mean) / self.state.y_scale)

    def train(self) -> int:
        """One fitted-Q phase on the stored transitions; returns the number of sweeps. Its
        wall time is added to ``log.train_seconds`` (the compute cost of replay)."""
        with self._lock:
            st = self.state
            if st.scaling_pending:
                return 0
            st.last_train_timestep = st.num_timesteps
            t0 = time.perf_counter()
            if st.data_scaled and self.env is not None:  # the states' spread outgrew the scale?
                if _env.outgrew(self._data_scaling(), self.scaling, RESCALE_FACTOR):
                    self._rescale_from_data()
            if self.config.hyperparameters == "evidence" and len(self.buffer) >= st.evidence_due:
                refit_lengthscales(self)
            try:
                return self._train()
            finally:
                self.log.train_seconds += time.perf_counter() - t0

    @single_blas_thread
    def _train(self) -> int:
        """Run :attr:`phase` on the window's transitions and take in its outcome."""
        st, log = self.state, self.log
        stored = self.buffer.transitions(last=self.config.window)
        if len(stored) == 0:
            return 0
        result = self.phase.run(self._phase_inputs(stored))
        if result is None:
            return 0
        if result.imagined is not None:
            log.imagined_counts.append(result.imagined)
        if result.targets is not None:
            self.buffer.set_targets(result.targets)
        st.y_mean, st.y_scale = result.y_mean, result.y_scale
        log.fitted_q_sweeps.append(result.sweeps)
        log.fitted_q_residuals.append(result.residual)
        measured = self.config.hyperparameters != "evidence" or st.fitted_lengthscale is not None
        self.actor.train(stored.states, self.gp, self.scaling, self.rng, measured)
        return result.sweeps

    def _phase_inputs(self, stored: Transitions) -> PhaseInputs:
        """What a phase on ``stored`` (the window's transitions) reads of the agent."""
        return phase_inputs_of(self, stored, _env.observation_box(self.env))

    # ------------------------------------------------------------------ persistence
    def save(self, path: str | PathLike[str]) -> None:
        """Save the agent (config, GP, transitions, state, log, generator state) as ``.npz``."""
        with self._lock:  # between two learning steps of another thread
            save_agent(self, path)

    @classmethod
    def load(cls, path: str | PathLike[str], env: gymnasium.Env | str | None = None) -> GPQAgent:
        """Load an agent written by :meth:`save`. ``env``: the env to keep learning in (its
        spaces must match the saved ones); by default the saved env id is made again if it
        is registered, else the agent can only :meth:`predict`."""
        return load_agent(cls, path, env)

    def set_env(self, env: gymnasium.Env | str) -> None:
        """Attach an env whose spaces match the agent's."""
        with self._lock:
            self.env = _env.matching_env(env, self.obs_dim, self.action_low, self.action_high)

    def __getstate__(self) -> dict[str, Any]:
        """Copies (``copy.deepcopy``, pickling) leave out the lock; each gets its own."""
        return {k: v for k, v in self.__dict__.items() if k != "_lock"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state, _lock=threading.RLock())

    def __repr__(self) -> str:
        return (f"GPQAgent(env={self.env_id or '?'}, kernel={self.config.kernel!r}, "
                f"max_bv={self.max_bv}, timesteps={self.num_timesteps})")  # fmt: skip
