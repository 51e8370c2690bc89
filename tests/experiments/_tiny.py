"""A tiny reproduction configuration shared by the end-to-end tests (seconds, not minutes)."""

from __future__ import annotations

from geoq.experiments.paper.config import ReproConfig
from geoq.learners import QGPConfig

TINY = ReproConfig(
    scale="tiny",
    seeds=2,
    budgets=(5, 15),
    beyond_paper_budgets=(15,),  # the resistance and pd_novelty cells at part of the grid
    train_rollouts=2,
    train_steps=60,
    graph_rollouts=2,
    graph_max_bv=30,
    eval_pairs=20,
    eval_rollouts=2,
    mc_rollouts=4,
    map_grid=6,
    map_mc_rollouts=2,
    map_max_bv=15,
    td_episodes=20,
    td_steps=30,
    tune_max_bv=15,
    tune_pairs=20,
    tune_mc_rollouts=4,
    learner=QGPConfig(),
)
