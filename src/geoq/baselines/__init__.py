"""Baselines: the paper's tabular TD evaluation of the fixed policy (TD(0) or SARSA(0))."""

from __future__ import annotations

from geoq.baselines.tabular_td import (
    DEFAULT_STEP_SIZES,
    StateActionGrid,
    TabularQ,
    TDMethod,
    sarsa_evaluate,
    td_baseline,
)

__all__ = [
    "DEFAULT_STEP_SIZES",
    "StateActionGrid",
    "TDMethod",
    "TabularQ",
    "sarsa_evaluate",
    "td_baseline",
]
