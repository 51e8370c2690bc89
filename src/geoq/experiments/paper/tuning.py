"""Hyper-parameters by evidence and by held-out validation, never by hand.

* Squared-exponential length-scales (one per input dimension), prior variance
  and noise variance: maximum exact-GP evidence on the tuning roll-outs
  (:func:`geoq.gp.evidence.fit_squared_exponential`), JC12 §3's advice, from its
  data-driven start plus :data:`EVIDENCE_RESTARTS` seeded restarts. The evidence
  at the start and at the end, every restart's end, whether the fit converged,
  the parameters left at a bound and the fit's warnings go into ``tuning.json``
  and REPORT.md, so a reader can see the fit worked (issue 14).
* The evidence's prior variance and noise are then used by *every* kernel, so
  the three learners differ only in their distance.
* Geodesic kernels: the graph threshold ``eps``, the width ``sigma_sp`` and, for
  JC12 eq. 5, ``sigma_se`` and the variant of the sum (:data:`EQ5_VARIANTS`) are
  chosen on a small grid by the MSE against Monte-Carlo ``Q^pi`` at held-out
  validation pairs (their Gram matrices are indefinite, so the evidence is not
  defined for them), scored after a refit on the final BV set and graph.

Tuning data come from their own random stream, disjoint from every seed of
Fig. 3.
"""

from __future__ import annotations

import functools
import itertools
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from geoq._typing import FloatArray
from geoq.evaluation.metrics import mse
from geoq.evaluation.monte_carlo import mc_q_values, sample_evaluation_pairs
from geoq.experiments.paper.config import ReproConfig
from geoq.experiments.paper.seeding import STREAM, rng_for
from geoq.gp import NumericalWarning
from geoq.gp.evidence import fit_squared_exponential
from geoq.learners import GPQFunction, QGPConfig
from geoq.policies import GaussianPolicy
from geoq.rollouts import Rollout, collect_rollouts

__all__ = [
    "EQ5_VARIANTS",
    "EVIDENCE_KEYS",
    "EVIDENCE_RESTARTS",
    "GRAPH_KERNELS",
    "RESISTANCE_LENGTHSCALE_GRID",
    "SIGMA_SE_GRID",
    "SIGMA_SP_GRID",
    "TUNING_COLUMNS",
    "TuningResult",
    "evidence_config",
    "select_by_validation",
    "tune",
]

#: Candidate ``sigma_sp`` of JC12 eq. 3 (log-spaced around the paper's value, 1; small
#: values make nearby points novel, hence a denser, connected graph).
SIGMA_SP_GRID: tuple[float, ...] = (0.01, 0.03, 0.1, 0.3, 1.0, 3.0)
#: Candidate ``sigma_se`` of JC12 eq. 5 (the paper: "small").
SIGMA_SE_GRID: tuple[float, ...] = (0.01, 0.1)
#: JC12 eq. 5 variants ``(normalize_weights, attach_weights)``: the paper's literal sum first,
#: then the normalised sum with the attaching edge kept (a soft JC12 eq. 4).
EQ5_VARIANTS: tuple[tuple[bool, bool], ...] = ((False, False), (True, True))
#: Columns of ``tuning.csv`` (one row per validated geodesic candidate).
TUNING_COLUMNS: tuple[str, ...] = (
    "kernel",
    "eps",
    "sigma_sp",
    "sigma_se",
    "normalize_weights",
    "attach_weights",
    "resistance_lengthscale",
    "n_bv",
    "val_mse",
)
#: Candidate ``l`` of the positive-definite ``resistance`` kernel ``A exp(-R / l)``.
RESISTANCE_LENGTHSCALE_GRID: tuple[float, ...] = (0.01, 0.03, 0.1, 0.3, 1.0, 3.0)
#: The kernels on the MDP graph, whose hyper-parameters are chosen by validation.
GRAPH_KERNELS: tuple[str, ...] = ("nearest", "interpolated", "resistance")
#: Restarts of the evidence maximisation beyond its data-driven start.
EVIDENCE_RESTARTS = 3
#: Keys of ``TuningResult.evidence``; a stored ``tuning.json`` without them predates
#: the restarted evidence fit (issue 14) and is tuned again.
EVIDENCE_KEYS: tuple[str, ...] = (
    "lengthscale",
    "amplitude",
    "noise",
    "log_evidence",
    "n_points",
    "log_evidence_start",
    "n_restarts",
    "log_evidence_runs",
    "converged",
    "at_bound",
    "warnings",
)


@dataclass(frozen=True)
class TuningResult:
    """Chosen learner settings per kernel, and the evidence behind them."""

    configs: dict[str, QGPConfig]
    evidence: dict[str, Any]
    validation: list[dict[str, Any]]

    def as_dict(self) -> dict[str, Any]:
        return {
            "configs": {k: v.as_dict() for k, v in self.configs.items()},
            "evidence": self.evidence,
            "validation": self.validation,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TuningResult:
        """Inverse of :meth:`as_dict`; ``KeyError`` for a result without the evidence
        diagnostics (made before issue 14: its fit may have stalled)."""
        missing = [k for k in EVIDENCE_KEYS if k not in data["evidence"]]
        if missing:
            raise KeyError(f"tuning result predates the evidence diagnostics: no {missing}")
        return cls(
            {k: QGPConfig.from_dict(v) for k, v in data["configs"].items()},
            dict(data["evidence"]),
            list(data["validation"]),
        )


def tune(cfg: ReproConfig, policy: GaussianPolicy, jobs: int = 1) -> TuningResult:
    """Choose every kernel's hyper-parameters for the run ``cfg``.

    Repairs of the indefinite geodesic Gram matrices (:class:`NumericalWarning`)
    are expected while scanning the grid and are not shown. ``jobs``: worker
    processes of the validation grid (:func:`select_by_validation`).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        return _tune(cfg, policy, jobs)


def _tune(cfg: ReproConfig, policy: GaussianPolicy, jobs: int) -> TuningResult:
    base = cfg.learner
    rollouts = collect_rollouts(
        cfg.train_rollouts,
        cfg.train_steps,
        policy,
        rng_for(cfg.root_seed, STREAM["tuning"], 0),
        gamma=cfg.gamma,
    )
    shared, evidence = evidence_config(rollouts, base, rng_for(cfg.root_seed, STREAM["tuning"], 1))
    configs = {"euclidean": shared.replace(kernel="euclidean")}
    shared = shared.replace(lengthscale=base.lengthscale)

    # Held-out validation for the geodesic kernels.
    states, actions = sample_evaluation_pairs(
        cfg.tune_pairs,
        policy,
        rng_for(cfg.root_seed, STREAM["tuning"], 2),
        n_rollouts=max(2, cfg.eval_rollouts // 2),
        steps=cfg.train_steps,
    )
    truth = mc_q_values(
        states,
        actions,
        policy,
        rng_for(cfg.root_seed, STREAM["tuning"], 3),
        n_rollouts=cfg.tune_mc_rollouts,
        gamma=cfg.gamma,
    ).mean
    validation: list[dict[str, Any]] = []
    for method in GRAPH_KERNELS:
        if method not in cfg.kernels:
            continue
        best, records = select_by_validation(
            method, rollouts, states, actions, truth, shared, cfg.graph_eps, cfg.tune_max_bv,
            jobs=jobs,
        )  # fmt: skip
        validation.extend(records)
        configs[method] = best.replace(max_bv=base.max_bv)
    return TuningResult(configs, evidence, validation)


def evidence_config(
    rollouts: Sequence[Rollout], base: QGPConfig, rng: np.random.Generator
) -> tuple[QGPConfig, dict[str, Any]]:
    """SE length-scales, prior variance and noise by maximum exact-GP evidence.

    The evidence is that of the standardised training targets (what the GP sees) at the
    scaled inputs of ``rollouts``, on a subsample of at most 500 points, from the
    data-driven start plus :data:`EVIDENCE_RESTARTS` restarts drawn with ``rng``.

    Returns ``base`` with the fitted ``lengthscale``, ``amplitude`` and ``noise``, and the
    evidence record (:data:`EVIDENCE_KEYS`). The fit's :class:`NumericalWarning` are
    recorded there, not shown; other warnings go on to the caller.
    """
    probe = GPQFunction(base.replace(kernel="euclidean"))
    X = np.vstack([probe.inputs(ro.states, ro.actions) for ro in rollouts])
    y = np.concatenate([ro.returns for ro in rollouts])
    z = (y - y.mean()) / (y.std() or 1.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", NumericalWarning)
        fit = fit_squared_exponential(
            X, z, ard=True, max_points=500, n_restarts=EVIDENCE_RESTARTS, rng=rng
        )
    lengthscale = tuple(float(v) for v in np.broadcast_to(fit.kernel.lengthscale, (X.shape[1],)))
    shared = base.replace(
        amplitude=float(fit.kernel.variance), noise=float(fit.noise), lengthscale=lengthscale
    )
    evidence = {
        "lengthscale": list(lengthscale),
        "amplitude": float(fit.kernel.variance),
        "noise": float(fit.noise),
        "log_evidence": float(fit.log_evidence),
        "n_points": int(fit.n_used),
        "log_evidence_start": float(fit.log_evidence_start),
        "n_restarts": int(fit.n_restarts),
        "log_evidence_runs": [float(v) for v in fit.log_evidence_runs],
        "converged": bool(fit.converged),
        "at_bound": list(fit.at_bound),
        "warnings": [str(w.message) for w in caught if issubclass(w.category, NumericalWarning)],
    }
    for w in caught:  # anything else goes on to the caller
        if not issubclass(w.category, NumericalWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return shared, evidence


def select_by_validation(
    method: str,
    rollouts: Sequence[Rollout],
    states: FloatArray,
    actions: FloatArray,
    truth: FloatArray,
    shared: QGPConfig,
    graph_eps: Sequence[float],
    tune_max_bv: int,
    jobs: int = 1,
) -> tuple[QGPConfig, list[dict[str, Any]]]:
    """The candidate of graph kernel ``method`` with the lowest validation MSE.

    Every candidate of the grid (:func:`_candidates`) is fitted to ``rollouts`` with
    budget ``tune_max_bv`` and scored by its MSE against ``truth`` (Monte-Carlo
    ``Q^pi``) at the held-out pairs ``states``, ``actions`` (in the learner's input
    space), after a refit on the final BV set and graph. Returns the best candidate
    (its ``max_bv`` is ``tune_max_bv``) and one record per candidate
    (:data:`TUNING_COLUMNS`). ``RuntimeError`` if every candidate diverged.
    ``jobs > 1`` scores the candidates in that many joblib (loky) worker processes,
    one native thread each; the result does not depend on it.
    """
    candidates = list(_candidates(method, graph_eps, tune_max_bv, shared))
    score = functools.partial(
        _validation_score, rollouts=rollouts, states=states, actions=actions, truth=truth
    )
    if jobs > 1 and len(candidates) > 1:
        from joblib import Parallel, delayed, parallel_config

        with parallel_config(backend="loky", n_jobs=jobs, inner_max_num_threads=1):
            scores = Parallel(batch_size=1)(delayed(score)(c) for c in candidates)
    else:
        scores = [score(c) for c in candidates]
    best: tuple[float, QGPConfig] | None = None
    validation: list[dict[str, Any]] = []
    for candidate, (err, n_bv) in zip(candidates, scores, strict=True):
        record = {c: getattr(candidate, c) for c in TUNING_COLUMNS[1:-2]}
        validation.append({"kernel": method, **record, "n_bv": n_bv, "val_mse": err})
        if np.isfinite(err) and (best is None or err < best[0]):
            best = (err, candidate)
    if best is None:
        raise RuntimeError(f"every {method} candidate gave a non-finite validation MSE")
    return best[1], validation


def _validation_score(
    candidate: QGPConfig,
    *,
    rollouts: Sequence[Rollout],
    states: FloatArray,
    actions: FloatArray,
    truth: FloatArray,
) -> tuple[float, int]:
    """Validation MSE and basis-vector count of one candidate.

    Scored after a refit on the final BV set and graph: the online posterior of a
    graph kernel is stale (its Gram changes as the graph grows), and the
    hyper-parameters should measure the kernel, not that staleness. Repairs of the
    indefinite Gram (:class:`NumericalWarning`) are expected and not shown.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        learner = GPQFunction(candidate.replace(refit="end")).fit(rollouts)
        err = mse(learner.predict(states, actions), truth)
    assert learner.gp_ is not None
    return err, learner.gp_.n_bv


def _candidates(
    method: str, graph_eps: Sequence[float], tune_max_bv: int, shared: QGPConfig
) -> Iterator[QGPConfig]:
    """The validation grid of one graph kernel."""
    if method == "resistance":
        for eps, length in itertools.product(graph_eps, RESISTANCE_LENGTHSCALE_GRID):
            yield shared.replace(
                kernel=method, eps=eps, resistance_lengthscale=length, max_bv=tune_max_bv
            )
        return
    se_grid = SIGMA_SE_GRID if method == "interpolated" else (shared.sigma_se,)
    variants = EQ5_VARIANTS if method == "interpolated" else ((False, False),)
    for eps, sigma_sp, sigma_se, (normalize, attach) in itertools.product(
        graph_eps, SIGMA_SP_GRID, se_grid, variants
    ):
        yield shared.replace(
            kernel=method,
            eps=eps,
            sigma_sp=sigma_sp,
            sigma_se=sigma_se,
            normalize_weights=normalize,
            attach_weights=attach,
            max_bv=tune_max_bv,
        )
