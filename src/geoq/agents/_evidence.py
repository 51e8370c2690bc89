"""``hyperparameters="evidence"``: the agent's squared-exponential length-scales by
maximum exact-GP evidence (:func:`geoq.gp.evidence.fit_squared_exponential`)."""

from __future__ import annotations

import warnings
from typing import Any, Protocol

import numpy as np

from geoq._typing import FloatArray
from geoq.agents.buffer import TransitionBuffer
from geoq.agents.config import GPQConfig
from geoq.agents.state import LearningState, TrainingLog
from geoq.gp.evidence import fit_squared_exponential
from geoq.gp.numerics import NumericalWarning
from geoq.learners.scaling import InputScaling

__all__ = [
    "EVIDENCE_RESTARTS",
    "EvidenceAgent",
    "blind_actions",
    "fit_lengthscales",
    "refit_lengthscales",
]

#: Random restarts of each fit beyond the warm start (the length-scales in use).
EVIDENCE_RESTARTS = 1


def fit_lengthscales(
    X: FloatArray, z: FloatArray, start: FloatArray, rng: np.random.Generator, points: int
) -> tuple[tuple[float, ...], dict[str, Any]]:
    """ARD length-scales ``[d]`` fitted to inputs ``X`` ``[n, d]`` and standardised targets
    ``z`` ``[n]`` (at most ``points`` of them, drawn with ``rng``), from ``start`` ``[d]``
    plus :data:`EVIDENCE_RESTARTS` random starts; and the fit's record (transitions,
    points used, length-scales, log evidence, convergence, bounds reached, and the
    :class:`NumericalWarning` the fit raised)."""
    d = X.shape[1]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", NumericalWarning)
        fit = fit_squared_exponential(
            X, z, lengthscale0=start, ard=True, max_points=points,
            n_restarts=EVIDENCE_RESTARTS, rng=rng,
        )  # fmt: skip
    ls = tuple(float(v) for v in np.broadcast_to(fit.kernel.lengthscale, (d,)))
    record = {
        "transitions": len(z), "points": fit.n_used, "lengthscale": list(ls),
        "log_evidence": fit.log_evidence,
        "log_evidence_start": fit.log_evidence_start, "converged": fit.converged,
        "at_bound": list(fit.at_bound), "warnings": [str(w.message) for w in caught],
    }  # fmt: skip
    return ls, record


def blind_actions(record: dict[str, Any], action_dim: int) -> list[int]:
    """Indices (``0 .. action_dim - 1``) of the actions whose length-scale a fit's
    ``record`` left at its upper bound; the actions are the last ``action_dim`` inputs."""
    d = len(record["lengthscale"])
    return [
        k - (d - action_dim)
        for k in range(d - action_dim, d)
        if f"lengthscale[{k}] upper" in record["at_bound"]
    ]


class EvidenceAgent(Protocol):
    """What a refit reads of the agent (a :class:`~geoq.agents.GPQAgent`), and the two
    steps it asks of it: the length-scales in use, and rebuilding its GP with new ones."""

    config: GPQConfig
    state: LearningState
    buffer: TransitionBuffer
    scaling: InputScaling
    rng: np.random.Generator
    log: TrainingLog
    action_dim: int

    def inputs(self, states: FloatArray, actions: FloatArray) -> FloatArray: ...
    def _lengthscale(self) -> float | tuple[float, ...]: ...
    def _restream(self) -> None: ...


def refit_lengthscales(agent: EvidenceAgent) -> None:
    """``hyperparameters="evidence"``: ``agent``'s length-scales fitted to its window's
    inputs and standardised targets (:func:`fit_lengthscales` on at most
    ``config.evidence_points``, warm-started from those in use; again on
    ``config.evidence_points_blind`` when an action's ends at its upper bound); its GP is
    rebuilt with them, the fit recorded in its log."""
    c, st, buffer = agent.config, agent.state, agent.buffer
    stored = buffer.transitions(last=c.window)
    z = (buffer.targets(last=c.window) - st.y_mean) / st.y_scale
    n, d = len(z), agent.scaling.dim
    st.evidence_due = 2 * n
    if n < 2 or np.ptp(z) == 0.0:
        return  # equal targets say nothing about length-scales
    start = np.broadcast_to(np.asarray(agent._lengthscale(), dtype=np.float64), (d,))
    X = agent.inputs(stored.states, stored.actions)
    rng = np.random.default_rng(agent.rng.integers(2**32))
    ls, record = fit_lengthscales(X, z, start, rng, c.evidence_points)
    if min(n, c.evidence_points_blind) > record["points"] and blind_actions(
        record, agent.action_dim
    ):
        first = {key: record[key] for key in ("points", "lengthscale", "log_evidence", "at_bound")}
        ls, record = fit_lengthscales(X, z, start, rng, c.evidence_points_blind)
        record["first_fit"] = first
    agent.log.evidence_fits.append(record)
    st.fitted_lengthscale = ls
    agent._restream()
