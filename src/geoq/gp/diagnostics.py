"""What a :class:`~geoq.gp.SparseOnlineGP` did and repaired: one counters object.

:class:`Counters` is the GP's single store of counts: the int64 array the compiled
step writes (indexed by :data:`COUNTER_NAMES`), the counts kept by Python
(resyncs, jitter, eigenvalue clips, covariance projections, refits), the repairs
made at prediction time, and whether the one :class:`~geoq.gp.numerics.NumericalWarning`
has been shown. :class:`OnlineDiagnostics` is the frozen snapshot users read
(``gp.diagnostics``); :func:`repair_warning` is the text of that warning.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from geoq._typing import IntArray

__all__ = ["COUNTER_NAMES", "Counters", "OnlineDiagnostics", "repair_warning"]

#: Indices into the int64 counter array shared by Python and the compiled step.
COUNTER_NAMES: tuple[str, ...] = (
    "n_seen",
    "n_added",
    "n_projected",
    "n_deleted",
    "negative_novelty",
    "variance_clipped",
    "novelty_clipped",
    "score_clipped",
    "noise_floored",
)
_SEEN, _ADDED, _PROJECTED, _DELETED, _NEGNOV, _VARCLIP, _NOVCLIP, _SCORECLIP, _NOISEFLOOR = range(9)

#: Counters kept by Python (not by the compiled step), in the order they are saved.
PYTHON_COUNTER_NAMES: tuple[str, ...] = (
    "q_resyncs",
    "jitter_events",
    "eig_clips",
    "covariance_projections",
    "refits",
)

#: The counters that are repairs: the first non-zero one triggers the warning.
_REPAIRS: tuple[str, ...] = (
    "variance_clipped",
    "novelty_clipped",
    "score_clipped",
    "noise_floored",
    "jitter_events",
    "eig_clips",
)


@dataclass(frozen=True)
class OnlineDiagnostics:
    """Counters of what a :class:`SparseOnlineGP` did and repaired (since the last reset)."""

    n_seen: int = 0
    """Observations processed by the online updates."""
    n_added: int = 0
    """Observations that became basis vectors (novel: full update)."""
    n_projected: int = 0
    """Observations projected onto the current basis (not novel, or negative novelty)."""
    n_deleted: int = 0
    """Basis vectors deleted to hold the budget (KL-optimal downdates)."""
    negative_novelty: int = 0
    """Observations whose novelty ``gamma`` was negative (indefinite kernel, or rounding)."""
    variance_clipped: int = 0
    """Negative predictive variances clipped to 0 (in updates and in :meth:`predict`),
    counting only those below ``-1e-9 k(x, x)`` (smaller ones are rounding noise)."""
    novelty_clipped: int = 0
    """Projections with a negative novelty below rounding level (indefinite kernel), where
    ``v = R^{-T} k_x`` was scaled onto ``|v|^2 = k(x, x)`` so that the update stays stable."""
    score_clipped: int = 0
    """Deletions where ``Q_ii + C_ii <= 0`` had to be repaired (broken numerical state)."""
    noise_floored: int = 0
    """Updates that used the noise variance ``CONFIG.noise_floor * k(x, x)`` instead of a
    smaller ``sigma0^2`` (below the rounding level of the posterior)."""
    q_resyncs: int = 0
    """Resyncs: exact refreshes of ``diag(Q)``, and for basis-tracking kernels
    re-factorisations of ``K_BV`` (when the factor came back unchanged, the refresh is
    made every ``SparseOnlineGP.score_refresh_every`` of them only)."""
    jitter_events: int = 0
    """Factorisations of ``K_BV`` that needed jitter (:func:`~geoq.gp.numerics.safe_cholesky`)."""
    eig_clips: int = 0
    """Eigenvalues of ``K_BV`` clipped when even the maximal jitter failed (indefinite kernel)."""
    covariance_projections: int = 0
    """Eigenvalues of the whitened posterior covariance ``S`` projected back onto
    ``[0, 1]`` after a basis-tracking kernel changed ``K_BV`` under the posterior
    (see ``SparseOnlineGP._resync_q``): a consequence of staleness, not a repair of
    an indefinite kernel, so it does not trigger the numerical warning."""
    refits: int = 0
    """Calls of :meth:`SparseOnlineGP.refit`."""
    max_q_drift: float = 0.0
    """Largest ``max|diag(Q)_online - diag(Q)_exact| / max|diag(Q)_exact|`` seen at a resync."""


class Counters:
    """Every count of one :class:`~geoq.gp.SparseOnlineGP`, in one place.

    Attributes
    ----------
    step : int64 [len(COUNTER_NAMES)], written in place by the compiled step.
    python : the counts of :data:`PYTHON_COUNTER_NAMES`, kept by Python.
    predict_clipped, predict_rescaled : repairs made by ``predict`` (added to
        ``variance_clipped`` and ``novelty_clipped`` in the snapshot).
    novclip_at_refit : ``step[novelty_clipped]`` at the last refit: predictions repair
        the test features iff the online updates repaired some since then.
    max_q_drift : largest relative drift of ``diag(Q)`` seen at a resync.
    warned : whether the one warning of this GP has been shown.
    """

    def __init__(self) -> None:
        self.step: IntArray = np.zeros(len(COUNTER_NAMES), dtype=np.int64)
        self.python: dict[str, int] = dict.fromkeys(PYTHON_COUNTER_NAMES, 0)
        self.predict_clipped = 0
        self.predict_rescaled = 0
        self.novclip_at_refit = 0
        self.max_q_drift = 0.0
        self.warned = False

    @property
    def novelty_clipped_online(self) -> int:
        """Negative-novelty repairs made by the online updates (not by ``predict``)."""
        return int(self.step[_NOVCLIP])

    @property
    def features_repaired(self) -> bool:
        """Whether online updates since the last refit rescaled ``v`` (``novelty_clipped``)."""
        return self.novelty_clipped_online > self.novclip_at_refit

    def snapshot(self) -> OnlineDiagnostics:
        """The counts as a frozen :class:`OnlineDiagnostics`."""
        counts: dict[str, Any] = {n: int(v) for n, v in zip(COUNTER_NAMES, self.step, strict=True)}
        counts["variance_clipped"] += self.predict_clipped
        counts["novelty_clipped"] += self.predict_rescaled
        counts.update(self.python)
        counts["max_q_drift"] = self.max_q_drift
        return OnlineDiagnostics(**counts)

    def any_repair(self) -> bool:
        """Whether any repair was counted (cheap: checked after every update and predict)."""
        return bool(
            self.step[_VARCLIP] or self.step[_NOVCLIP] or self.step[_SCORECLIP]
            or self.step[_NOISEFLOOR] or self.predict_clipped or self.predict_rescaled
            or self.python["jitter_events"] or self.python["eig_clips"]
        )  # fmt: skip

    def repairs(self) -> dict[str, int]:
        """The non-zero repair counts, by name."""
        d = self.snapshot()
        return {k: getattr(d, k) for k in _REPAIRS if getattr(d, k)}


def repair_warning(repairs: dict[str, int]) -> str:
    """Text of the one :class:`~geoq.gp.numerics.NumericalWarning` a GP shows."""
    what = ", ".join(f"{k}={v}" for k, v in repairs.items())
    return (
        f"SparseOnlineGP repaired its numerical state ({what}); the kernel is probably "
        "not positive definite on the basis set (e.g. a geodesic kernel) or the noise is "
        "tiny. Repairs are counted in gp.diagnostics; this warning is shown once per GP."
    )
