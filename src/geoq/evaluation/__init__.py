"""Ground truth and metrics: Monte-Carlo ``Q^pi`` and the errors of Fig. 3."""

from __future__ import annotations

from geoq.evaluation.metrics import mean_confidence_interval, mse, normalized_variance
from geoq.evaluation.monte_carlo import (
    HORIZON_TOLERANCE,
    MCEstimate,
    mc_horizon,
    mc_q_values,
    sample_evaluation_pairs,
)

__all__ = [
    "HORIZON_TOLERANCE",
    "MCEstimate",
    "mc_horizon",
    "mc_q_values",
    "mean_confidence_interval",
    "mse",
    "normalized_variance",
    "sample_evaluation_pairs",
]
