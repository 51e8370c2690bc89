"""The agent's learned dynamics model and the planner that acts through it (``planner``).

With ``planner="cem"`` or ``"cem-q"`` a :class:`~geoq.models.GPDynamicsModel` learns
the task's steps from the agent's transitions: fitted once ``warmup_steps``
transitions are stored and again each time they have doubled (on the most recent
``window``: the evidence's length-scales and the standardisation follow the data),
every other transition streamed into it online.
Each action, in training and greedy alike, is then the first of the plan
:class:`~geoq.models.CEMPlanner` finds through the model, halted with the least value
it could score where the model does not know (:func:`~geoq.models.model_returns`).
With ``cem-q`` the plans are closed by the agent's own ``Q`` (the posterior mean at the
plan's last state and action: model-based value expansion, Feinberg et al. 2018;
TD-MPC's terminal value); with ``cem`` they end at the horizon. With ``policy`` and
``policy-net`` the actions are a feedback policy's, searched through the model at
episode starts (:mod:`geoq.agents.policy_planning`; ``policy`` refits the model at each
search and streams nothing). Measured, the ``Q``
learned alongside made the plans worse on ``InvertedPendulum-v5`` and ``Reacher-v5``
(docs/design-notes.md).

Training plans draw from the agent's generator (the CEM's samples and the model's
trajectory samples); greedy plans (``predict(deterministic=True)``) draw from a
generator of their own, seeded by the agent's seed and step count, and keep their own
warm start: they change nothing the learning reads.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from geoq._typing import FloatArray
from geoq.agents.buffer import TransitionBuffer
from geoq.agents.config import GPQConfig
from geoq.agents.policy_planning import NET_MODEL, FeedbackPlanning
from geoq.agents.state import LearningState
from geoq.gp import SparseOnlineGP
from geoq.models import CEMPlanner, GPDynamicsModel, ModelSettings, PlannerSettings, model_returns

__all__ = ["ModelPlanning", "PlanningAgent"]


class PlanningAgent(Protocol):
    """What a plan reads of the agent (a :class:`~geoq.agents.GPQAgent`): its seed and
    step (a greedy plan's generator), its settings, and its Q (``cem-q``'s closing value)."""

    seed: int | None
    config: GPQConfig
    state: LearningState
    gp: SparseOnlineGP

    @property
    def num_timesteps(self) -> int: ...
    def value_bounds(self) -> tuple[float, float]: ...
    def inputs(self, states: FloatArray, actions: FloatArray) -> FloatArray: ...


class ModelPlanning:
    """The model, its fit schedule and two planners (training's and greedy's)."""

    def __init__(self, config: GPQConfig, obs_dim: int, low: FloatArray, high: FloatArray):
        self.mode, self.window = config.planner, config.window
        self.policy_mode = self.mode in ("policy", "policy-net")
        self.first_fit = max(config.warmup_steps, 2)
        # a policy's long roll-outs must stop where any state input leaves the data
        settings = ModelSettings(standardised_support=self.policy_mode)
        if self.mode == "policy-net":
            settings = NET_MODEL
        self.model = GPDynamicsModel(obs_dim, low.shape[0], settings)
        self.training = CEMPlanner(low, high, PlannerSettings())
        self.greedy = CEMPlanner(low, high, PlannerSettings())
        assert config.policy_horizon is not None  # resolved by GPQConfig.for_dims
        net = self.mode == "policy-net"
        self.feedback = FeedbackPlanning(obs_dim, low, high, config.policy_horizon, net=net,
                                         real_test=net)  # fmt: skip
        self.next_fit = self.first_fit

    @property
    def active(self) -> bool:
        """Whether actions are planned now (a planner chosen and a model fitted; with
        ``policy`` or ``policy-net``, a policy searched that acts, not ``Q``)."""
        if self.policy_mode:
            return self.feedback.policy is not None and self.feedback.acting
        return self.mode != "off" and self.model.fitted

    @property
    def greedy_active(self) -> bool:
        """Whether greedy actions are planned now: as :attr:`active`, but with ``policy`` or
        ``policy-net`` whenever a policy's weights are the greedy ones
        (:attr:`~geoq.agents.policy_planning.FeedbackPlanning.greedy_weights`)."""
        if self.policy_mode:
            return self.feedback.policy is not None and self.feedback.greedy_weights is not None
        return self.active

    def observe(self, buffer: TransitionBuffer, rng: np.random.Generator) -> None:
        """Take in the buffer's newest transition: a fit when one is due, else a stream
        (``policy``: neither; the model is refitted at each search, :meth:`start_episode`,
        and read nowhere else)."""
        if self.mode in ("off", "policy"):
            return
        n = len(buffer)
        if n >= self.next_fit:
            self._fit(buffer, rng)
        elif self.model.fitted:
            self.model.observe(*(column[-1] for column in buffer.arrays(last=1)))

    def _fit(self, buffer: TransitionBuffer, rng: np.random.Generator) -> None:
        self.model.fit(*buffer.arrays(last=self.window), rng)
        self.next_fit = 2 * len(buffer)

    def start_episode(self, s: FloatArray, buffer: TransitionBuffer,
                      rng: np.random.Generator) -> None:  # fmt: skip
        """A new episode from ``s`` [1, d_s]: the training plan's warm start is forgotten;
        with ``policy`` or ``policy-net``, ``s`` joins the starts, and a search is made if
        one is due."""
        self.training.reset()
        if not self.policy_mode:
            return
        self.feedback.starts = np.vstack([self.feedback.starts, s])
        n = len(buffer)
        rewards, terminated = buffer.arrays()[2::2]
        self.feedback.close_episode(rewards, terminated)
        if n >= self.first_fit and self.feedback.due(n):
            if self.mode == "policy" or not self.model.fitted:
                self._fit(buffer, rng)
            self.feedback.search(self.model, n, rng, buffer.arrays(last=self.window)[0])
        self.feedback.open_episode(n)

    def action(
        self, agent: PlanningAgent, s: FloatArray, rng: np.random.Generator | None
    ) -> FloatArray:
        """The planned action ``[1, d_a]`` at ``s`` [1, d_s]; ``rng`` None: a greedy plan."""
        if self.policy_mode:
            return self.feedback.action(s, rng)
        planner = self.training if rng is not None else self.greedy
        if rng is None:
            seed = [agent.seed if agent.seed is not None else 0, agent.num_timesteps]
            rng = np.random.default_rng(np.random.SeedSequence(seed))
        lo = agent.value_bounds()[0]

        def q_value(S: FloatArray, A: FloatArray) -> FloatArray:
            mean = agent.gp.predict(agent.inputs(S, A))
            return np.clip(agent.state.y_mean + agent.state.y_scale * mean, *agent.value_bounds())

        value = q_value if self.mode == "cem-q" else None

        def score(A: FloatArray) -> FloatArray:
            return model_returns(self.model, s[0], A, gamma=agent.config.gamma, value=value,
                                 value_floor=lo, rng=rng)  # fmt: skip

        return planner.plan(score, rng)[None, :]

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> dict[str, Any]:
        """The model and schedule as arrays (an agent's archive, prefix ``model/``)."""
        if self.mode == "off":
            return {}
        plans = {}
        for name, planner in (("training", self.training), ("greedy", self.greedy)):
            if planner.mean is not None:
                plans[f"plan_{name}"] = planner.mean
            if planner.elites is not None:
                plans[f"elites_{name}"] = planner.elites
        if self.policy_mode:
            plans = self.feedback.to_arrays()
        return self.model.to_arrays() | plans | {"next_fit": np.array(self.next_fit)}

    def restore(self, a: dict[str, Any], source: str) -> None:
        """Inverse of :meth:`to_arrays`; ``ValueError`` where it does not fit this planning."""
        if self.mode == "off":
            if a:
                raise ValueError("the file holds a dynamics model, but its config's planner is off")
            return
        model = GPDynamicsModel.from_arrays(a, source)
        self.next_fit = int(a["next_fit"])
        if (model.obs_dim, model.action_dim) != (self.model.obs_dim, self.model.action_dim):
            raise ValueError(f"the dynamics model's dimensions {model.obs_dim}, {model.action_dim} "
                             "are not the agent's")  # fmt: skip
        if model.fitted != (self.next_fit > self.first_fit) or self.next_fit < self.first_fit:
            raise ValueError(f"next_fit {self.next_fit} does not fit a model fitted={model.fitted}")
        self.model = model
        if self.policy_mode:
            self.feedback.restore(a)
        for name, planner in (("training", self.training), ("greedy", self.greedy)):
            steps = (planner.settings.horizon + 1, len(planner.low))
            planner.mean = _plan(a, f"plan_{name}", steps)
            planner.elites = _plan(a, f"elites_{name}", (planner.settings.elites, *steps))


def _plan(a: dict[str, Any], key: str, shape: tuple[int, ...]) -> FloatArray | None:
    """A stored plan (centred actions of ``shape``), or None if there is none."""
    if key not in a:
        return None
    plan = np.asarray(a[key], dtype=np.float64)
    if plan.shape != shape or not np.all(np.abs(plan) <= 1.0):
        raise ValueError(f"{key} must be {shape} within [-1, 1], got shape {plan.shape}")
    return plan
