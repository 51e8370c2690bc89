"""``GPQConfig``: everything that defines a :class:`~geoq.agents.GPQAgent`, validated.

Saved with every agent and reported with every result; ``as_dict`` /
``from_dict`` give its JSON form (unknown keys are an error).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any, Literal

import numpy as np

from geoq.agents.acquisition import EXPLORATION_MODES, Exploration
from geoq.learners.q_gp import KERNEL_NAMES, KernelName

__all__ = [
    "HYPERPARAMETERS",
    "PRIORS",
    "REPLAYS",
    "GPQConfig",
    "Hyperparameters",
    "Prior",
    "Replay",
    "check_int",
    "default_max_bv",
]

#: ``default_max_bv``: the budget up to ``BUDGET_BASE_DIM`` inputs, doubled beyond.
BUDGET_BASE = 400
BUDGET_BASE_DIM = 3

Prior = Literal["midrange", "optimistic", "empirical"]
PRIORS: tuple[str, ...] = ("midrange", "optimistic", "empirical")
Replay = Literal["uniform", "none", "graph"]
REPLAYS: tuple[str, ...] = ("uniform", "none", "graph")
Hyperparameters = Literal["rule", "evidence"]
HYPERPARAMETERS: tuple[str, ...] = ("rule", "evidence")


@dataclass(frozen=True)
class GPQConfig:
    """Everything that defines a :class:`GPQAgent` (saved with it, reported with results)."""

    kernel: KernelName = "euclidean"
    """``euclidean`` (squared exponential), ``nearest`` (JC12 eq. 4), ``interpolated``
    (JC12 eq. 5) or ``resistance`` (positive-definite kernel on the same graph). The
    resistance kernel re-factorises ``K_BV`` after every change of the basis set,
    O(max_bv^3): measured 46-76 ms per step at 400 BVs, 314-329 ms at 800 (TwoRooms),
    11-22 ms at 200; consider ``max_bv=200`` with it (README, replay table)."""
    max_bv: int | None = None
    """Basis-vector budget of the sparse online GP. ``None``: :func:`default_max_bv` of
    the input dimension ``d_s + d_a`` (400 up to 3 inputs, 800 beyond), resolved by
    :class:`GPQAgent`, whose ``config`` holds the number."""
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
    hyperparameters: Hyperparameters = "rule"
    """Where the squared-exponential length-scales come from. ``rule``: ``lengthscale``, or
    ``state_lengthscale`` / ``action_lengthscale``, fixed. ``evidence`` (``euclidean``
    only): re-fitted by maximum exact-GP evidence
    (:func:`geoq.gp.evidence.fit_squared_exponential`, ARD, on at most 300 of the
    stored inputs and their current standardised targets, warm-started from the
    length-scales in use; periodic inputs enter unwrapped) at the first
    fitted-Q phase and whenever the stored transitions have doubled since the last fit
    (250, 500, 1,000, ...: a few fits per run); the GP is then rebuilt from the stored
    transitions. The rule's values are the first start. Only the length-scales are
    taken: ``amplitude`` and ``noise`` define the prior over values never seen (the
    optimism that drives exploration), which the evidence of the visited ones does
    not inform. Each fit is recorded in ``GPQAgent.evidence_fits``. The default is
    ``rule``: on the swing-up the evidence's length-scales learned worse
    (docs/design-notes.md)."""
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
    (500) steps costs. Swing-up, 10 seeds: success >= 0.9 after a median 1,000
    steps [750, 1,000], 10 of 10 seeds, against 1,375 [1,250, 2,000] and 9 of 10
    with a phase every 250 steps (docs/design-notes.md); 20 seeds (2026-12-02):
    875 [750, 1,000], 20 of 20. 0: every ``train_every``
    steps, the schedule of files saved before this field."""
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
    the stored transitions (counted in ``GPQAgent.rescales``). Unused when every
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
        if self.hyperparameters not in HYPERPARAMETERS:
            raise ValueError(
                f"hyperparameters must be one of {HYPERPARAMETERS}, got {self.hyperparameters!r}"
            )
        if self.hyperparameters == "evidence" and self.kernel != "euclidean":
            raise ValueError(
                "hyperparameters='evidence' fits squared-exponential length-scales: it needs "
                f"kernel='euclidean', got {self.kernel!r}. The graph kernels' Gram is not "
                "positive definite (or, for 'resistance', has no length-scale per input): "
                "use hyperparameters='rule' and set eps / sigma_sp / resistance_lengthscale"
            )
        if self.prior not in PRIORS:
            raise ValueError(f"prior must be one of {PRIORS}, got {self.prior!r}")
        if self.exploration not in EXPLORATION_MODES:
            raise ValueError(
                f"exploration must be one of {EXPLORATION_MODES}, got {self.exploration!r}"
            )
        if self.max_bv is not None:
            check_int(self.max_bv, "max_bv", 1)
        check_int(self.n_candidates, "n_candidates", 3)
        check_int(self.train_every, "train_every", 1)
        check_int(self.max_sweeps, "max_sweeps", 0)
        check_int(self.window, "window", 1)
        check_int(self.replay_budget, "replay_budget", 0)
        check_int(self.warmup_steps, "warmup_steps", 1)
        if not (isinstance(self.replay_eps, int | float) and 0.0 < self.replay_eps < 1.0):
            raise ValueError(f"replay_eps must be in (0, 1), got {self.replay_eps!r}")
        if not (isinstance(self.gamma, int | float) and 0.0 <= self.gamma < 1.0):
            raise ValueError(f"gamma must be in [0, 1), got {self.gamma!r}")
        for name in ("beta", "action_noise", "train_fraction"):
            _check_real(getattr(self, name), name, strict=False)
        for name in ("noise", "amplitude", "eps", "sigma_sp", "sigma_se",
                     "resistance_lengthscale", "sweep_tol", "state_lengthscale",
                     "action_lengthscale"):  # fmt: skip
            _check_real(getattr(self, name), name, strict=True)
        if not 0.0 <= self.tol <= 1.0:
            raise ValueError(f"tol must be in [0, 1], got {self.tol!r}")
        for name in ("reward_bounds", "terminal_reward_bounds"):
            _check_bounds(getattr(self, name), name)
        if self.lengthscale is not None:
            ls = np.atleast_1d(np.asarray(self.lengthscale, dtype=np.float64))
            if not (np.all(np.isfinite(ls)) and np.all(ls > 0)):
                raise ValueError(f"lengthscale must be finite and > 0, got {self.lengthscale!r}")

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
        d = dict(data)
        for name in ("lengthscale", "reward_bounds", "terminal_reward_bounds"):
            if isinstance(d.get(name), list):
                d[name] = tuple(d[name])
        return cls(**d)


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


def check_int(value: Any, name: str, minimum: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


def _check_bounds(rb: Any, name: str) -> None:
    if rb is None:
        return
    ok = (
        isinstance(rb, tuple | list)
        and len(rb) == 2
        and all(
            isinstance(v, int | float) and not isinstance(v, bool) and np.isfinite(v) for v in rb
        )
    )
    if not ok or rb[0] > rb[1]:
        raise ValueError(
            f"{name} must be two finite numbers (r_min, r_max) with r_min <= r_max, got {rb!r}"
        )


def _check_real(value: Any, name: str, *, strict: bool) -> None:
    ok = isinstance(value, int | float | np.floating) and not isinstance(value, bool)
    if not ok or not np.isfinite(value) or value < 0 or (strict and value == 0):
        bound = "> 0" if strict else ">= 0"
        raise ValueError(f"{name} must be a finite number {bound}, got {value!r}")
