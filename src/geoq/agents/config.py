"""``GPQConfig``: everything that defines a :class:`~geoq.agents.GPQAgent`, validated.

Saved with every agent and reported with every result; ``as_dict`` /
``from_dict`` give its JSON form (unknown keys are an error).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from typing import Any, Literal

import numpy as np

from geoq._typing import FloatArray
from geoq._validation import check_budget, check_int, check_learn_arguments, check_real, check_seed
from geoq.agents.acquisition import EXPLORATION_MODES, Exploration
from geoq.agents.greedy_data import GREEDY_ACTIONS, GreedyActions, resolve_greedy_actions
from geoq.agents.kept_q import KEEP_Q, KeepQ
from geoq.agents.map_explorer import EXPLORE_MAP_MODES, ExploreMap
from geoq.agents.q_actor import ACTORS, Actor
from geoq.agents.state import LearningState, as_range, check_value_bounds, value_bounds
from geoq.gp import SparseOnlineGP
from geoq.kernels import KERNEL_NAMES, Kernel, KernelName, make_kernel
from geoq.learners.scaling import InputScaling

__all__ = [
    "HYPERPARAMETERS", "PLANNERS", "PRIORS", "REPLAYS", "GPQConfig", "Hyperparameters", "Planner",
    "Prior", "Replay", "check_learn_arguments", "check_seed", "default_max_bv", "rule_coverage",
]  # fmt: skip

#: Largest ``beta`` and ``action_noise``: past a million posterior standard deviations UCB
#: is pure uncertainty sampling, past a million half-ranges the noise only hits the box's
#: edges; beyond, products with the posterior std overflow.
MAX_EXPLORATION = 1e6
#: Largest ``evidence_points``: a fit holds ``8 d n^2`` bytes (0.74 GB at 23 inputs).
MAX_EVIDENCE_POINTS = 2000
#: Largest ``n_candidates``: each step asks the GP about this many inputs (16,384 x 800
#: basis vectors = 100 MB per call).
MAX_CANDIDATES = 16_384

#: ``default_max_bv``: the budget up to ``BUDGET_BASE_DIM`` inputs, doubled beyond.
BUDGET_BASE = 400
BUDGET_BASE_DIM = 3

Prior = Literal["auto", "midrange", "optimistic", "empirical"]
PRIORS: tuple[str, ...] = ("auto", "midrange", "optimistic", "empirical")
Replay = Literal["uniform", "none", "graph"]
REPLAYS: tuple[str, ...] = ("uniform", "none", "graph")
Planner = Literal["off", "auto", "cem", "cem-q", "policy", "policy-net"]
PLANNERS: tuple[str, ...] = ("off", "auto", "cem", "cem-q", "policy", "policy-net")
#: ``policy_horizon``'s most when the task's time limit sets it.
POLICY_HORIZON_CAP = 1000
Hyperparameters = Literal["auto", "rule", "evidence"]
HYPERPARAMETERS: tuple[str, ...] = ("auto", "rule", "evidence")


@dataclass(frozen=True)
class GPQConfig:
    """Everything that defines a :class:`GPQAgent` (saved with it, reported with results)."""

    kernel: KernelName = "euclidean"
    """``euclidean`` (squared exponential), ``nearest`` (JC12 eq. 4), ``interpolated``
    (JC12 eq. 5) or ``resistance`` (positive-definite kernel on the same graph). The
    resistance kernel re-factorises ``K_BV`` after every change of the basis set,
    O(max_bv^3): consider ``max_bv=200`` with it (docs/results.md, the replay table)."""
    max_bv: int | None = None
    """Basis-vector budget of the sparse online GP, in ``[1, 5000]``. ``None``:
    :func:`default_max_bv` of the input dimension ``d_s + d_a`` (400 up to 3 inputs,
    800 beyond), resolved by :meth:`for_dims`; a :class:`GPQAgent`'s ``config`` holds
    the number."""
    gamma: float = 0.98
    """Discount factor."""
    exploration: Exploration = "ucb"
    """``ucb`` (mean + beta std), ``thompson``, ``gaussian`` (greedy + noise) or ``greedy``;
    greedy as ``greedy_actions`` says (:func:`~geoq.agents.greedy_data.act_in_data`)."""
    beta: float = 0.5
    """UCB width, in posterior standard deviations."""
    action_noise: float = 0.3
    """Std of the ``gaussian`` exploration noise, as a fraction of each action half-range."""
    n_candidates: int = 21
    """Candidate actions per state (a grid in 1-D; rounded up to a power of 2 in more)."""
    greedy_actions: GreedyActions = "auto"
    """``Q``'s greedy action: the candidates' best, or (``data``) the best of the actions taken
    at the stored states nearest the state (:mod:`geoq.agents.greedy_data`); ``auto``: ``data``
    past one action dimension (:meth:`for_dims`). Learning alike."""
    noise: float = 0.01
    """Observation-noise variance of the standardised targets."""
    lengthscale: float | tuple[float, ...] | None = None
    """Squared-exponential length-scale(s) in scaled input units (``euclidean``); a
    sequence (stored as a tuple) has one entry per input dimension ``d_s + d_a``. ``None``: the rule
    ``state_lengthscale`` for every state dimension, ``action_lengthscale`` for
    every action dimension. Given (or ``state_lengthscale`` / ``action_lengthscale``
    given other than their defaults), they are the length-scales used: ``hyperparameters="auto"``
    then resolves to ``rule``, never to a fit that would replace them (ask for
    ``hyperparameters="evidence"`` to have them only as the fit's first start)."""
    state_lengthscale: float = 0.15
    """Length-scale of each state dimension when ``lengthscale`` is None (in
    half-ranges of the space: 0.15 of the pendulum's ``[-pi, pi]`` is 0.47 rad)."""
    action_lengthscale: float = 0.6
    """Length-scale of each action dimension when ``lengthscale`` is None. Longer than
    the states': one step's action moves the next state by ``dt``-small amounts, so
    Q varies slowly along the action."""
    hyperparameters: Hyperparameters = "auto"
    """Where the squared-exponential length-scales come from. ``rule``: ``lengthscale``, or
    ``state_lengthscale`` / ``action_lengthscale``, fixed. ``evidence`` (``euclidean``
    only): re-fitted by maximum exact-GP evidence
    (:func:`geoq.gp.evidence.fit_squared_exponential`, ARD, on at most ``evidence_points``
    of the stored inputs and their current standardised targets, warm-started from the
    length-scales in use; periodic inputs enter unwrapped) at the first
    fitted-Q phase and whenever the stored transitions have doubled since the last fit
    (250, 500, 1,000, ...: a few fits per run); the GP is then rebuilt from the stored
    transitions. The rule's values are the first start. Only the length-scales are
    taken: ``amplitude`` and ``noise`` define the prior over values never seen (the
    optimism that drives exploration), which the evidence of the visited ones does
    not inform. Each fit is recorded in ``GPQAgent.log.evidence_fits``. ``auto`` (the
    default, resolved by :meth:`for_dims`): ``rule`` where the length-scales were given
    (``lengthscale``, or ``state_lengthscale`` / ``action_lengthscale`` other than
    their defaults: a setting given is the setting used), and where the default
    rule's length-scales let the dimension's default budget cover the input box
    (:func:`rule_coverage` >= 1: the swing-up, the mountain car, ``Pendulum-v1``,
    TwoRooms); ``evidence`` where they cannot (``euclidean`` only; 4 states and 1
    action, 3 and 2, and beyond: Gymnasium's MuJoCo tasks). On the swing-up the
    evidence's length-scales learned worse; on ``Reacher-v5`` (12 inputs) the rule's
    left every greedy state at the prior (docs/design-notes.md)."""
    evidence_points: int = 300
    """Most stored transitions an evidence fit sees (``hyperparameters="evidence"``), drawn
    at random from the window, in ``[2, 2000]``; a fit costs ``O(n^3)`` per evaluation and
    holds ``8 (d_s + d_a) n^2`` bytes. The evidence sees an action's effect only through
    pairs near in state and apart in action: on ``Walker2d-v5`` (23 inputs) 300 points
    leave some action length-scales at the bound, 1,000 most at 1.2-5 box sides."""
    evidence_points_blind: int = 300
    """Points of a second fit, taken, where the first leaves an action's length-scale at
    its upper bound (``Q`` flat along it) and the window holds more; its record keeps the
    first as ``first_fit``. In ``[2, 2000]``; at most ``evidence_points``: never."""
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
    train_every: int = 25
    """Fitted-Q phases run at multiples of ``train_every`` steps and at every episode's
    end; a mid-episode one is skipped while fewer than ``train_fraction`` x the
    transitions in the window arrived since the last phase."""
    train_fraction: float = 0.05
    """With ``train_every``: a phase every 25 steps while the agent has up to 500
    transitions, then each time its data grew by 5%, so early experience is used at
    once, while a long run pays about what a phase every ``train_fraction x window``
    (500) steps costs (the swing-up succeeds sooner than with a phase every 250 steps:
    docs/design-notes.md). 0: every ``train_every`` steps, as files saved before it."""
    max_sweeps: int = 200
    """Largest number of fitted-Q sweeps per phase."""
    sweep_tol: float = 1e-3
    """A phase stops when no target moves by more than this (in units of ``y_scale``)."""
    window: int = 10_000
    """Fitted-Q phases use the most recent ``window`` transitions. One that leaves the
    window is forgotten: where nothing else was seen the value returns to the
    optimistic prior and the agent goes back to explore (the mountain car's greedy
    return wavered after 6,500 steps with 5,000; docs/design-notes.md). The agent
    keeps the covariances of the ``window`` next states with the basis between phases
    (the squared exponential's state factor; the action factor is formed per phase):
    up to ``1.5 x 8 window max_bv`` bytes (48 MB at the swing-up's defaults;
    ``window + replay_budget`` rows with graph replay, whose imagined next states take
    the rows after the stored ones)."""
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
    the stored transitions (counted in ``GPQAgent.log.rescales``). Unused when every
    bound is finite."""
    replay_budget: int = 500
    """Largest number of imagined transitions per fitted-Q phase (``replay="graph"``)."""
    replay_eps: float = 0.9
    """JC12 eq. 2 threshold of the replay graph: two state-action pairs are linked when
    their squared-exponential similarity in length-scale units exceeds it."""
    reward_bounds: tuple[float, float] | None = None
    """Declared range ``(r_min, r_max)`` of one step's reward (of the steps that do not
    end the episode, when ``terminal_reward_bounds`` is known). The value bounds (and so
    the optimistic prior) start from it instead of from the rewards seen so far;
    rewards outside it still widen them. ``None``: the task's known range (Gymnasium's
    ``MountainCarContinuous-v0`` and ``Pendulum-v1``, :data:`geoq.tasks.KNOWN_TASKS`), else
    only the rewards seen. Without it a task whose reward arrives late (the mountain
    car's +100 at the flag) has an optimistic prior of 0, the value of doing nothing."""
    terminal_reward_bounds: tuple[float, float] | None = None
    """Declared range of the reward of a step that ends the episode (``terminated``).
    Received once, it bounds a return by itself: the value bounds are ``[min(r_min,
    r_min / (1 - gamma), t_min), max(r_max, r_max / (1 - gamma), t_max)]``, so the
    mountain car's +100 at the flag makes the optimistic prior 100, not
    ``100 / (1 - gamma) = 5,000``. ``None``: the task's known range (the mountain car's
    ``(99.9, 100)``), else the rewards of the terminating steps seen."""
    prior: Prior = "auto"
    """What the GP assumes of ``Q`` where it has no data (the standardisation
    ``z = (y - y_mean) / y_scale``, set after every fitted-Q phase from the value
    bounds ``[lo, hi]`` of :meth:`GPQAgent.value_bounds` or from the targets):
    ``midrange``: mean ``(lo + hi) / 2``, std ``(hi - lo) / 2``; ``optimistic``:
    mean ``hi``, std ``(hi - lo) / 2`` (optimism in the face of uncertainty);
    ``empirical``: mean and std of the current targets. ``auto`` (the default,
    resolved by :meth:`for_dims`): ``optimistic`` where the rule's length-scales (those
    in use at the start: ``lengthscale`` if given, else ``state_lengthscale`` /
    ``action_lengthscale``, whether given or the defaults) let the dimension's default
    budget cover the input box (:func:`rule_coverage` >= 1), ``empirical`` where they
    cannot: there most inputs the agent meets are far from every basis vector, an
    optimistic prior makes every unvisited action the best one, and the greedy policy
    chases novelty (``Reacher-v5``: worse than no torque; docs/design-notes.md). So
    short length-scales given on a task the defaults cover (``lengthscale=0.05`` on
    TwoRooms: coverage 0.005) resolve to ``empirical``."""
    explore_map: ExploreMap = "auto"
    """Exploration over states on a map of the observed moves
    (:mod:`geoq.agents.map_explorer`, :mod:`geoq.agents.state_map`): ``auto`` builds one
    after ``2 n_candidates`` steps where the moves are the actions' own (a point pushed
    around: TwoRooms and its layouts), never where the state integrates a velocity (the
    pendulums, the mountain car: their agents are unchanged); ``on``: always; ``off``:
    never. With a map, training actions follow its explore plan and greedy actions its
    exploit plan where it knows a route to a termination (the GP's elsewhere)."""
    planner: Planner = "auto"
    """``cem``: learn a GP model of the task's steps and act by planning through it over
    a short horizon (:mod:`geoq.agents.model_planning`); ``cem-q``: the same, the plans
    closed by the agent's ``Q``; ``policy``: act with a linear feedback policy searched
    through the model over a long horizon, again each episode (PILCO's loop,
    :mod:`geoq.agents.policy_planning`); ``policy-net``: the same with a neural policy
    searched by gradients; ``off``: act on ``Q`` alone; ``auto`` (resolved by
    :meth:`for_dims`): ``off`` where the rule's length-scales let the default budget cover
    the input box (as ``prior``'s ``auto``: the tasks ``Q`` alone learns, the pendulums,
    the mountain car, TwoRooms), ``policy-net`` where they cannot (where the model does
    not expect its policies to beat ``Q``, or they do not on the task, ``Q`` acts:
    :mod:`geoq.agents.policy_planning`).
    Where both a map and a planner would act, the map's plan comes first."""
    policy_horizon: int | None = None
    """Model steps a ``policy`` or ``policy-net`` search scores its policies over (undiscounted);
    None: the task's time limit, at most :data:`POLICY_HORIZON_CAP` (1,000 without one)."""
    actor: Actor = "auto"
    """``on``: a policy trained on ``Q``'s posterior mean (DDPG's actor,
    :mod:`geoq.agents.q_actor`) acts where ``Q`` would, its training actions its own plus
    ``action_noise`` half-ranges of noise; ``curved``: the same, in the phases where ``Q``
    can turn inside the action box (every action length-scale at most the box's side;
    :func:`~geoq.agents.q_actor.curves_inside`); ``off``: none; ``auto`` (resolved by
    :meth:`for_dims`, as ``planner``'s): ``off`` on the tasks ``Q`` alone learns,
    ``curved`` elsewhere. A map's or a planner's policy comes first."""
    keep_q: KeepQ = "off"
    """``on``: ``Q``'s greedy actions are those of the copy of ``Q`` that did best in training
    (:mod:`geoq.agents.kept_q`; learning alike; better on ``Hopper-v5`` and ``Walker2d-v5``,
    worse on ``InvertedDoublePendulum-v5``: docs/design-notes.md); ``off``: the current's."""

    def __post_init__(self) -> None:
        """Every rule of every field, checked once, here; NumPy scalars become Python ones
        (a config is saved as JSON)."""
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.generic):
                object.__setattr__(self, f.name, value.item())
        for name, allowed in (
            ("kernel", KERNEL_NAMES), ("replay", REPLAYS), ("hyperparameters", HYPERPARAMETERS),
            ("prior", PRIORS), ("exploration", EXPLORATION_MODES),
            ("explore_map", EXPLORE_MAP_MODES), ("planner", PLANNERS),
            ("greedy_actions", GREEDY_ACTIONS), ("actor", ACTORS), ("keep_q", KEEP_Q),
        ):  # fmt: skip
            if getattr(self, name) not in allowed:
                raise ValueError(f"{name} must be one of {allowed}, got {getattr(self, name)!r}")
        if self.hyperparameters == "evidence" and self.kernel != "euclidean":
            raise ValueError(
                "hyperparameters='evidence' fits squared-exponential length-scales: it needs "
                f"kernel='euclidean', got {self.kernel!r}. The graph kernels' Gram is not "
                "positive definite (or, for 'resistance', has no length-scale per input): "
                "use hyperparameters='rule' and set eps / sigma_sp / resistance_lengthscale"
            )
        if self.max_bv is not None:
            check_budget(self.max_bv)
        if self.policy_horizon is not None:
            check_int(self.policy_horizon, "policy_horizon", 1, 100_000)
        for name, minimum in (
            ("train_every", 1), ("max_sweeps", 0), ("window", 1), ("replay_budget", 0),
            ("warmup_steps", 1),
        ):  # fmt: skip
            check_int(getattr(self, name), name, minimum)
        check_int(self.n_candidates, "n_candidates", 3, MAX_CANDIDATES)
        check_int(self.evidence_points, "evidence_points", 2, MAX_EVIDENCE_POINTS)
        check_int(self.evidence_points_blind, "evidence_points_blind", 2, MAX_EVIDENCE_POINTS)
        check_real(self.replay_eps, "replay_eps", low=0.0, high=1.0, low_open=True, high_open=True)
        check_real(self.gamma, "gamma", low=0.0, high=1.0, high_open=True)
        try:
            check_real(self.tol, "tol", low=0.0, high=1.0)
        except ValueError as exc:
            raise ValueError(
                f"{exc}: tol is the sparse GP's novelty threshold relative to k(x, x) (above 1 "
                "no point would ever become a basis vector; the default is 1e-6)"
            ) from None
        for name in ("beta", "action_noise"):
            check_real(getattr(self, name), name, low=0.0, high=MAX_EXPLORATION)
        check_real(self.train_fraction, "train_fraction", low=0.0)
        for name in ("noise", "amplitude", "eps", "sigma_sp", "sigma_se",
                     "resistance_lengthscale", "sweep_tol", "state_lengthscale",
                     "action_lengthscale"):  # fmt: skip
            check_real(getattr(self, name), name, low=0.0, low_open=True)
        for name in ("reward_bounds", "terminal_reward_bounds"):
            object.__setattr__(self, name, _bounds(getattr(self, name), name))
        bounds = value_bounds(as_range(self.reward_bounds),
                              as_range(self.terminal_reward_bounds), self.gamma)  # fmt: skip
        check_value_bounds(bounds, "reward_bounds / terminal_reward_bounds")
        object.__setattr__(self, "lengthscale", _lengthscale(self.lengthscale))
        self._check_model()

    def _check_model(self) -> None:
        """The kernel and GP these settings make, built once so that their own rules
        (variance, widths, noise, tol) are checked here, with the config."""
        try:
            kernel = self.make_kernel(self.rule_lengthscale(1, 1), None)
            SparseOnlineGP(kernel, noise=self.noise, max_bv=1, tol=self.tol)
        except ValueError as exc:
            raise ValueError(f"these settings make no valid GP: {exc}") from None

    def for_dims(self, obs_dim: int, action_dim: int, time_limit: int | None = None) -> GPQConfig:
        """This config for a task of ``obs_dim`` observations and ``action_dim`` actions
        (and episodes of at most ``time_limit`` steps, None: unknown): ``max_bv`` resolved
        (:func:`default_max_bv`), ``policy_horizon`` resolved from ``time_limit`` (capped
        at :data:`POLICY_HORIZON_CAP`), ``lengthscale``'s length checked, and
        ``greedy_actions`` (:func:`resolve_greedy_actions`), ``hyperparameters``, ``prior``,
        ``planner`` and ``actor`` resolved where ``auto``: by whether
        the rule's length-scales let the dimension's default budget cover the input box
        (:func:`rule_coverage`; the default's, so that a smaller ``max_bv``, chosen for
        speed, does not change how the agent learns); ``hyperparameters`` to ``rule``
        wherever length-scales were given (:meth:`lengthscales_given`). A resolved
        config resolves to itself (a loaded agent's file is resolved again)."""
        d = check_int(obs_dim, "obs_dim", 1) + check_int(action_dim, "action_dim", 1)
        ls = self.lengthscale
        if isinstance(ls, tuple) and len(ls) not in (1, d):
            raise ValueError(
                f"lengthscale has {len(ls)} entries; expected 1 or {d} "
                "(one per observation and action dimension)"
            )
        max_bv = default_max_bv(d) if self.max_bv is None else self.max_bv
        rule = np.broadcast_to(self.rule_lengthscale(obs_dim, action_dim), (d,))
        covered = rule_coverage(rule, default_max_bv(d)) >= 1.0
        hyperparameters, prior = self.hyperparameters, self.prior
        if hyperparameters == "auto":
            rule_kept = covered or self.kernel != "euclidean" or self.lengthscales_given()
            hyperparameters = "rule" if rule_kept else "evidence"
        if prior == "auto":
            prior = "optimistic" if covered else "empirical"
        planner, actor = self.planner, self.actor
        if planner == "auto":
            planner = "off" if covered else "policy-net"
        if actor == "auto":
            actor = "off" if covered else "curved"
        horizon = self.policy_horizon or min(time_limit or POLICY_HORIZON_CAP, POLICY_HORIZON_CAP)
        greedy = resolve_greedy_actions(self.greedy_actions, action_dim)
        return replace(self, max_bv=max_bv, hyperparameters=hyperparameters, prior=prior,
                       planner=planner, policy_horizon=horizon, greedy_actions=greedy,
                       actor=actor)  # fmt: skip

    def lengthscales_given(self) -> bool:
        """Whether the user chose the squared exponential's length-scales: ``lengthscale``
        set, or ``state_lengthscale`` / ``action_lengthscale`` other than their defaults."""
        return self.lengthscale is not None or any(
            getattr(self, name) != _DEFAULTS[name]
            for name in ("state_lengthscale", "action_lengthscale")
        )

    def make_kernel(
        self, lengthscale: float | tuple[float, ...], period: FloatArray | None
    ) -> Kernel:
        """A fresh kernel of these settings (:func:`geoq.kernels.make_kernel`) with the given
        squared-exponential ``lengthscale`` and input periods (scaled units; None: none)."""
        return make_kernel(
            self.kernel, lengthscale=lengthscale, amplitude=self.amplitude, eps=self.eps,
            sigma_sp=self.sigma_sp, sigma_se=self.sigma_se,
            resistance_lengthscale=self.resistance_lengthscale, period=period,
            attach_weights=self.kernel == "interpolated",
        )  # fmt: skip

    def agent_kernel(self, lengthscale: float | tuple[float, ...], scaling: InputScaling) -> Kernel:
        """The kernel of an agent's GP: :meth:`make_kernel` with the periods of the inputs
        ``scaling`` wraps (scaled units; none if no input wraps)."""
        periodic = np.any(np.asarray(scaling.periods) > 0)
        return self.make_kernel(lengthscale, scaling.scaled_periods() if periodic else None)

    def lengthscale_in_use(
        self, obs_dim: int, action_dim: int, state: LearningState
    ) -> float | tuple[float, ...]:
        """The squared exponential's length-scale(s) of an agent in ``state``: those fitted by
        evidence if any, else :meth:`rule_lengthscale`."""
        if state.fitted_lengthscale is not None:
            return state.fitted_lengthscale
        return self.rule_lengthscale(obs_dim, action_dim)

    def rule_lengthscale(self, obs_dim: int, action_dim: int) -> float | tuple[float, ...]:
        """The squared exponential's length-scale(s) by the rule: ``lengthscale``, or
        ``state_lengthscale`` per observation and ``action_lengthscale`` per action."""
        if self.lengthscale is None:
            return (self.state_lengthscale,) * obs_dim + (self.action_lengthscale,) * action_dim
        return self.lengthscale

    def as_dict(self) -> dict[str, Any]:
        """JSON-able representation."""
        out = asdict(self)
        for name in ("lengthscale", "reward_bounds", "terminal_reward_bounds"):
            if isinstance(getattr(self, name), tuple):
                out[name] = list(getattr(self, name))
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> GPQConfig:
        """Inverse of :meth:`as_dict`; unknown keys raise ``ValueError``."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown GPQConfig field(s) {unknown}; known: {sorted(known)}")
        return cls(**data)


#: Every field's default (``GPQConfig.lengthscales_given`` compares with them).
_DEFAULTS: dict[str, Any] = {f.name: f.default for f in fields(GPQConfig)}


def default_max_bv(input_dim: int) -> int:
    """The basis-vector budget for ``input_dim = d_s + d_a`` inputs: 400 for up to 3, 800 beyond.

    A grid of fixed resolution needs ``c^d`` points, so the budget a task needs grows
    with its input dimension. 400 is what the swing-up (3 inputs) needs, 800 what
    Gymnasium's ``Pendulum-v1`` (4 inputs) needs (docs/design-notes.md). The doubling
    stops at 4 inputs: nothing larger was measured, a step costs ``O(max_bv^2)`` and
    the fitted-Q covariances ``O(window n_candidates max_bv)`` (``window``).
    """
    check_int(input_dim, "input_dim", 1)
    return BUDGET_BASE * (2 if input_dim > BUDGET_BASE_DIM else 1)


def rule_coverage(lengthscale: FloatArray, max_bv: int) -> float:
    """How many times ``max_bv`` basis vectors could tile the scaled input box
    ``[-1, 1]^d`` at length-scales ``lengthscale`` ``[d]`` (scaled units):
    ``max_bv prod_i min(l_i, 1)``, each basis vector covering a box of half-sides ``l_i``.

    Below 1 most of the box is more than a length-scale from every basis vector, and a
    GP with those length-scales cannot carry values from the inputs it kept to the
    ones the agent meets. The default rule (0.15 per state, 0.6 per action) gives 5.4
    on 2 states and 1 action at 400 basis vectors (the swing-up, the mountain car),
    1.6 on 3 + 1 at 800 (``Pendulum-v1``), 6.5 on 2 + 2 (TwoRooms), 0.24 on 4 + 1
    (``InvertedPendulum-v5``) and 1e-7 on 10 + 2 (``Reacher-v5``).

    ``ValueError`` unless ``lengthscale`` is one or more finite numbers > 0 and ``max_bv``
    an integer >= 1.
    """
    check_int(max_bv, "max_bv", 1)
    given = np.asarray(lengthscale)
    ls = given.astype(np.float64) if given.dtype.kind in "iuf" else np.empty(0)
    if ls.ndim > 1 or ls.size == 0 or not np.all(np.isfinite(ls)) or np.any(ls <= 0.0):
        raise ValueError("lengthscale must be one finite length-scale > 0 or a flat sequence of "
                         f"them (one per input, in scaled units), got {lengthscale!r}")  # fmt: skip
    return float(max_bv * np.prod(np.minimum(ls, 1.0)))


def _bounds(rb: Any, name: str) -> tuple[float, float] | None:
    if rb is None:
        return None
    ok = isinstance(rb, tuple | list | np.ndarray) and np.ndim(rb) == 1 and len(rb) == 2
    try:
        pair = tuple(check_real(v, name) for v in rb) if ok else ()
    except ValueError:
        ok = False
    if not ok or pair[0] > pair[1]:
        raise ValueError(f"{name} must be two finite numbers (r_min, r_max) with r_min <= r_max, "
                         f"got {rb!r}")  # fmt: skip
    return (pair[0], pair[1])


def _lengthscale(ls: Any) -> float | tuple[float, ...] | None:
    """``None``, one length-scale, or a tuple of them (from any sequence or array)."""
    if ls is None:
        return None
    values = np.asarray(ls, dtype=object).ravel() if np.ndim(ls) else [ls]
    try:
        checked = tuple(check_real(v, "lengthscale", low=0.0, low_open=True) for v in values)
    except ValueError:
        raise ValueError(
            f"lengthscale must be finite and > 0 (one number, or one per input), got {ls!r}"
        ) from None
    if not checked or np.ndim(ls) > 1:
        raise ValueError(f"lengthscale must be one number or a flat sequence, got {ls!r}")
    return checked if np.ndim(ls) else checked[0]
