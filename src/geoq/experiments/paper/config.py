"""Settings of the paper reproduction (JC12 §5), as frozen dataclasses (CleanRL style).

Two presets: ``quick`` (``make demo``: under a minute on 2 cores; the paper's three
kernels and the ``faithful`` variant, every claim of the paper) and ``paper`` (the full
protocol: >= 10 seeds, ~10 budgets between 5 and 200, and beyond the paper the
``resistance`` kernel and the ``pd_novelty`` variant, at six of those budgets). Every
result file carries the configuration it came from (``config.json``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from numbers import Integral, Real
from typing import Any, Literal

from geoq.learners import KERNEL_NAMES, PAPER_KERNELS, QGPConfig
from geoq.learners.q_gp import MAX_BUDGET
from geoq.learners.scaling import PENDULUM_SCALING, InputScaling

__all__ = [
    "BEYOND_PAPER_VARIANTS",
    "RAW_UNITS",
    "SCALES",
    "VARIANTS",
    "VARIANT_KERNELS",
    "ReproConfig",
    "config_for_scale",
    "config_with_overrides",
    "faithful_learner",
    "variant_learner",
]

#: The pendulum's inputs in raw physical units (rad, rad/s, N m): JC12 §5 scales nothing.
RAW_UNITS = InputScaling((1.0, 1.0, 1.0), PENDULUM_SCALING.periods, PENDULUM_SCALING.names)

#: Learners run beside the tuned ones in Fig. 3 (``fig3_variants.csv``), with what they are.
VARIANTS: dict[str, str] = {
    "faithful": "the paper's literal settings where it states them: raw physical units, "
    "A = sigma_sp = 1 (JC12 eq. 3), eps = 0.3 (Fig. 1 (a)), the literal unnormalised eq. 5 "
    "sum; what the paper does not state (noise, tol, sigma_se, target standardisation) "
    "as tuned",
    "pd_novelty": "the tuned learner with novelty measured under the positive-definite repair "
    "(eigenvalue-clipped K_BV re-anchored at every BV change, flipped negative eigenvalue "
    "of the augmented Gram: geoq.gp.pd_novelty), so the BV set can grow to the budget",
}
#: The kernels the variants are run for (the paper's graph kernels).
VARIANT_KERNELS: tuple[str, ...] = ("nearest", "interpolated")
#: The variants that go beyond the paper (``ReproConfig.beyond_paper_budgets`` applies to them,
#: as to the kernels outside ``PAPER_KERNELS``).
BEYOND_PAPER_VARIANTS: tuple[str, ...] = ("pd_novelty",)


def faithful_learner(tuned: QGPConfig) -> QGPConfig:
    """``tuned`` with the paper's literal settings where it states them (``VARIANTS``)."""
    return tuned.replace(
        scaling=RAW_UNITS,
        amplitude=1.0,
        sigma_sp=1.0,
        eps=0.3,
        normalize_weights=False,
        attach_weights=False,
        wrap_angle=False,
        temporal_edges=False,
        pd_novelty=False,
    )


def variant_learner(variant: str, tuned: QGPConfig) -> QGPConfig:
    """The learner of ``variant`` (a key of :data:`VARIANTS`) derived from the tuned one."""
    if variant == "faithful":
        return faithful_learner(tuned)
    if variant == "pd_novelty":
        return tuned.replace(pd_novelty=True)
    raise ValueError(f"variant must be one of {sorted(VARIANTS)}, got {variant!r}")


@dataclass(frozen=True)
class ReproConfig:
    """Everything that defines one run of ``geoq reproduce``."""

    scale: str = "quick"
    """Name of the preset."""
    root_seed: int = 2012
    """Root of every random stream: ``SeedSequence(root_seed).spawn(...)``."""
    seeds: int = 3
    """Independent repetitions of Fig. 3 (training roll-outs, evaluation pairs, ground truth)."""
    budgets: tuple[int, ...] = (10, 25, 50, 100, 200)
    """``max_bv`` values of Fig. 3."""
    beyond_paper_budgets: tuple[int, ...] = ()
    """``max_bv`` values of the learners beyond the paper (the kernels outside the paper's
    three, the variants in :data:`BEYOND_PAPER_VARIANTS`): a subset of ``budgets``; empty:
    every budget."""
    gamma: float = 0.95
    """Discount factor of targets and ground truth."""
    train_rollouts: int = 3
    """Roll-outs the GPs learn from (paper: 3)."""
    train_steps: int = 250
    """Steps per training roll-out (paper: 250)."""
    graph_rollouts: int = 5
    """Roll-outs behind the Fig. 1 graphs (paper: 5)."""
    graph_eps: tuple[float, ...] = (0.3, 0.5)
    """Graph thresholds drawn in Fig. 1 (paper: 0.3 and 0.5)."""
    edge_count_eps: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
    """Thresholds at which the Fig. 1 graphs' edges are counted (``fig1_eps.csv``): JC12 eq. 2
    gives fewer edges for a larger ``eps``, where the paper's text says more."""
    graph_max_bv: int = 200
    """Basis budget of the GP that builds the Fig. 1 graphs."""
    eval_pairs: int = 150
    """Evaluation state-action pairs per seed, drawn from held-out roll-outs."""
    eval_rollouts: int = 10
    """Held-out roll-outs the evaluation pairs are drawn from."""
    mc_rollouts: int = 50
    """Monte-Carlo roll-outs per evaluation pair (ground truth)."""
    map_grid: int = 30
    """Fig. 2: the (theta, omega) grid is ``map_grid x map_grid``."""
    map_mc_rollouts: int = 16
    """Fig. 2: Monte-Carlo roll-outs per grid cell for the ground-truth map."""
    map_max_bv: int = 100
    """Fig. 2: basis budget of the three GPs drawn."""
    td_episodes: int = 800
    """Paper's TD baseline: episodes (paper: 800)."""
    td_steps: int = 150
    """Paper's TD baseline: steps per episode (paper: 150)."""
    tune_max_bv: int = 100
    """Basis budget used when choosing hyper-parameters by validation."""
    tune_pairs: int = 100
    """Held-out validation pairs for choosing the geodesic hyper-parameters."""
    tune_mc_rollouts: int = 30
    """Monte-Carlo roll-outs per validation pair."""
    kernels: tuple[str, ...] = KERNEL_NAMES
    """Learners compared in Fig. 2 and 3: the paper's three and, beyond the paper, the
    positive-definite ``resistance`` kernel on the same graph."""
    variants: tuple[str, ...] = tuple(VARIANTS)
    """Learners run beside the tuned ones in Fig. 3 for the paper's graph kernels
    (:data:`VARIANTS`; empty: none)."""
    probe_seeds: int = 3
    """Seeds (the first ones) whose Fig. 3 cells also run a rounding probe, which finds the
    results that rounding decides (:mod:`geoq.experiments.paper.rounding`); 0: none."""
    learner: QGPConfig = field(default_factory=QGPConfig)
    """Base learner settings; the kernel, budget and tuned values are filled in per cell."""

    def __post_init__(self) -> None:
        """Types and ranges of every field, checked before anything runs."""
        if not isinstance(self.scale, str) or not self.scale:
            raise ValueError(f"scale must be a non-empty string, got {self.scale!r}")
        _integer(self.root_seed, "root_seed", 0, 2**63 - 1)
        for name in _COUNT_FIELDS:
            high = MAX_BUDGET if name.endswith("max_bv") else _MAX_COUNT
            _integer(getattr(self, name), name, 1, high)
        _integer(self.probe_seeds, "probe_seeds", 0, _MAX_COUNT)
        _sequence(self.budgets, "budgets", lambda v, n: _integer(v, n, 1, MAX_BUDGET))
        _sequence(
            self.beyond_paper_budgets,
            "beyond_paper_budgets",
            lambda v, n: _subset_budget(v, n, self.budgets),
            empty=True,
        )
        if isinstance(self.gamma, bool) or not isinstance(self.gamma, Real):
            raise ValueError(f"gamma must be a number in (0, 1), got {self.gamma!r}")
        if not 0.0 < float(self.gamma) < 1.0:
            raise ValueError(f"gamma must be in (0, 1), got {self.gamma!r}")
        for name in ("graph_eps", "edge_count_eps"):
            _sequence(getattr(self, name), name, _open_unit)
        _sequence(self.kernels, "kernels", lambda v, n: _choice(v, n, KERNEL_NAMES))
        if not {"euclidean", "nearest"} <= set(self.kernels):
            raise ValueError(
                "kernels must include 'euclidean' (the baseline) and 'nearest' (Fig. 1) and "
                f"come from {KERNEL_NAMES}, got {list(self.kernels)}"
            )
        _sequence(
            self.variants, "variants", lambda v, n: _choice(v, n, tuple(VARIANTS)), empty=True
        )
        if not isinstance(self.learner, QGPConfig):
            raise ValueError(f"learner must be a QGPConfig, got {type(self.learner).__name__}")
        # Values that would only fail minutes later, inside a sweep:
        pool = self.eval_rollouts * self.train_steps
        if self.eval_pairs > pool:
            raise ValueError(
                f"eval_pairs = {self.eval_pairs} exceeds the {pool} states of eval_rollouts x "
                "train_steps it is drawn from"
            )
        tune_pool = max(2, self.eval_rollouts // 2) * self.train_steps
        if self.tune_pairs > tune_pool:
            raise ValueError(
                f"tune_pairs = {self.tune_pairs} exceeds the {tune_pool} states of "
                "max(2, eval_rollouts // 2) x train_steps it is drawn from"
            )

    def replace(self, **changes: Any) -> ReproConfig:
        return replace(self, **changes)

    def budgets_of(self, kernel: str, variant: str = "tuned") -> tuple[int, ...]:
        """The ``max_bv`` values Fig. 3 runs ``kernel`` at, tuned or as ``variant``."""
        beyond = kernel not in PAPER_KERNELS or variant in BEYOND_PAPER_VARIANTS
        return self.beyond_paper_budgets if beyond and self.beyond_paper_budgets else self.budgets

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["learner"] = self.learner.as_dict()
        out["budgets"] = list(self.budgets)
        out["beyond_paper_budgets"] = list(self.beyond_paper_budgets)
        out["graph_eps"] = list(self.graph_eps)
        out["edge_count_eps"] = list(self.edge_count_eps)
        out["kernels"] = list(self.kernels)
        out["variants"] = list(self.variants)
        return out


_COUNT_FIELDS = (
    "seeds", "train_rollouts", "train_steps", "graph_rollouts", "graph_max_bv",
    "eval_pairs", "eval_rollouts", "mc_rollouts", "map_grid", "map_mc_rollouts",
    "map_max_bv", "td_episodes", "td_steps", "tune_max_bv", "tune_pairs", "tune_mc_rollouts",
)  # fmt: skip
#: Largest count a configuration accepts (beyond it a run would not finish, or 10**30
#: would overflow an array size minutes into the run).
_MAX_COUNT = 1_000_000
_SEQUENCE_FIELDS = (
    "budgets", "beyond_paper_budgets", "graph_eps", "edge_count_eps", "kernels", "variants",
)  # fmt: skip


def _integer(value: Any, name: str, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    if not low <= int(value) <= high:
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def _subset_budget(value: Any, name: str, budgets: tuple[int, ...]) -> int:
    _integer(value, name, 1, MAX_BUDGET)
    if int(value) not in budgets:
        raise ValueError(
            f"{name} = {value!r} is not one of budgets {list(budgets)}; give "
            "beyond_paper_budgets as a subset of budgets ([] for every budget)"
        )
    return int(value)


def _open_unit(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, Real) or not 0.0 < float(value) < 1.0:
        raise ValueError(f"{name} must be a number in (0, 1), got {value!r}")
    return float(value)


def _choice(value: Any, name: str, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{name} must be one of {list(choices)}, got {value!r}")
    return value


def _sequence(values: Any, name: str, check: Any, empty: bool = False) -> None:
    if not isinstance(values, tuple | list):
        raise ValueError(f"{name} must be a list, got {values!r}")
    if not values and not empty:
        raise ValueError(f"{name} must not be empty")
    for i, v in enumerate(values):
        check(v, f"{name}[{i}]")
    if len(set(values)) != len(values):
        raise ValueError(f"{name} has duplicates: {list(values)}")


SCALES: dict[str, ReproConfig] = {
    # The beyond-paper cells (resistance, pd_novelty: 3/4 of the quick run's time, issue 31)
    # run at the paper scale only; the quick run still tests every claim of the paper.
    "quick": ReproConfig(kernels=PAPER_KERNELS, variants=("faithful",)),
    "paper": ReproConfig(
        scale="paper",
        seeds=10,
        budgets=(5, 10, 20, 35, 50, 75, 100, 125, 150, 200),
        # Six budgets, the same span and the claims' smallest third: the learners beyond
        # the paper re-anchor at every basis change, 80% of the run's CPU on every budget
        # (issue 31).
        beyond_paper_budgets=(5, 10, 20, 50, 100, 200),
        eval_pairs=500,
        eval_rollouts=20,
        mc_rollouts=100,
        map_grid=50,
        map_mc_rollouts=32,
    ),
}


def config_for_scale(
    scale: Literal["quick", "paper"] | str, root_seed: int | None = None
) -> ReproConfig:
    """The preset called ``scale``, optionally with another root seed."""
    if scale not in SCALES:
        raise ValueError(f"scale must be one of {sorted(SCALES)}, got {scale!r}")
    cfg = SCALES[scale]
    return cfg if root_seed is None else cfg.replace(root_seed=int(root_seed))


def config_with_overrides(base: ReproConfig, overrides: Mapping[str, Any]) -> ReproConfig:
    """``base`` with the fields in ``overrides`` replaced (``learner`` merged field by field).

    ``overrides`` is what ``geoq reproduce --config FILE`` reads from JSON, e.g.
    ``{"seeds": 2, "budgets": [5, 10], "learner": {"tol": 1e-4}}``.
    """
    if not isinstance(overrides, Mapping):
        raise ValueError(f"a configuration must be a JSON object, got {type(overrides).__name__}")
    known = {f.name for f in fields(ReproConfig)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ValueError(f"unknown configuration field(s) {unknown}; known: {sorted(known)}")
    changes = dict(overrides)
    label = changes.get("scale")
    if isinstance(label, str) and label in SCALES and label != base.scale:
        # The report and config.json name the scale: a preset's name must be the preset
        # that ran. Any other name labels this configuration (e.g. the tests' "tiny").
        raise ValueError(
            f"scale {changes['scale']!r} in the configuration differs from the preset "
            f"{base.scale!r} it overrides; choose the preset with --scale"
        )
    for name in _SEQUENCE_FIELDS:
        if name in changes:
            if not isinstance(changes[name], list | tuple):
                raise ValueError(f"{name} must be a list, got {changes[name]!r}")
            changes[name] = tuple(changes[name])
    if "learner" in changes:
        learner = changes["learner"]
        if not isinstance(learner, Mapping):
            raise ValueError(f"learner must be an object of learner fields, got {learner!r}")
        per_cell = {"kernel": "kernels", "max_bv": "budgets"}.items()
        for key, instead in per_cell:
            # Every cell sets its own: another value would be silently lost (the value of
            # a config.json written by geoq reproduce is the base's, and is accepted).
            if key in learner and learner[key] != getattr(base.learner, key):
                raise ValueError(
                    f"learner.{key} is set per sweep cell; choose them with '{instead}'"
                )
        try:
            changes["learner"] = QGPConfig.from_dict({**base.learner.as_dict(), **learner})
        except (ValueError, TypeError) as exc:
            msg = str(exc)
            names = {f.name for f in fields(QGPConfig)}
            dot = msg.split(" ", 1)[0].split(".")[0] in names  # "noise must be ..."
            raise ValueError(f"learner.{msg}" if dot else f"learner: {msg}") from None
    try:
        return base.replace(**changes)
    except TypeError as exc:
        raise ValueError(f"invalid configuration: {exc}") from exc
