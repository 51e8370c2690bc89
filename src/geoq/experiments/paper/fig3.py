"""Fig. 3: accuracy and predictive variance versus the basis budget ``max_bv``.

Two sweeps through :func:`geoq.experiments.sweep.run_sweep` (resumable,
parallel, one file per finished cell):

1. :func:`truth_cell`, one per seed: evaluation pairs drawn from held-out
   roll-outs of the policy, Monte-Carlo ``Q^pi`` there (mean and standard
   error) and the paper's TD table read at the same pairs.
2. :func:`budget_cell`, one per (kernel, max_bv, seed): the seed's training
   roll-outs (3 x 250 steps), one GP learner, its MSE against both ground
   truths and its normalised variance; then the same GP after a DTC refit on
   its final BV set and graph (docs/guide/reproduction.md, "Choices the paper leaves
   open"), and, for the paper's kernels, a learner that refits after every
   roll-out, so the effect of staleness is measured on the same data.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from geoq._typing import FloatArray
from geoq.baselines.tabular_td import td_baseline
from geoq.evaluation.metrics import mse, normalized_variance
from geoq.evaluation.monte_carlo import mc_q_values, sample_evaluation_pairs
from geoq.experiments.paper.config import ReproConfig
from geoq.experiments.paper.rounding import POSTERIOR_OF, PROBE_SUFFIX, perturb
from geoq.experiments.paper.seeding import STREAM, rng_for
from geoq.experiments.sweep import cell_key, cell_spec, load_cell
from geoq.gp import NumericalWarning
from geoq.learners import PAPER_KERNELS, GPQFunction, QGPConfig
from geoq.policies import default_policy
from geoq.rollouts import Rollout, collect_rollouts

__all__ = [
    "FIG3_COLUMNS",
    "VARIANT_COLUMNS",
    "BudgetCell",
    "TruthCell",
    "budget_cell",
    "load_truth",
    "longest_first",
    "score_learner",
    "truth_cell",
]

#: Column order of ``fig3.csv``.
FIG3_COLUMNS = (
    "kernel",
    "max_bv",
    "seed",
    "mse",
    "normalized_variance",
    "n_bv",
    "mse_td",
    "mse_refit",
    "normalized_variance_refit",
    "mse_refit_episode",
    "normalized_variance_refit_episode",
    "mse_constant",
    "mc_noise_floor",
    "negative_novelty",
    "variance_clipped",
    "eig_clips",
    "q_resyncs",
    # The rounding probe's values (geoq.experiments.paper.rounding; empty where not probed).
    *(column + PROBE_SUFFIX for column in POSTERIOR_OF),
)
#: Column order of ``fig3_variants.csv`` (learners run beside the tuned ones).
VARIANT_COLUMNS = ("variant", *FIG3_COLUMNS)


@dataclass(frozen=True)
class TruthCell:
    """Ground truth of one seed (the identity of a cell: changing a field recomputes it)."""

    seed: int
    root_seed: int
    policy_sigma: float
    gamma: float
    eval_pairs: int
    eval_rollouts: int
    eval_steps: int
    mc_rollouts: int
    td_episodes: int
    td_steps: int

    @classmethod
    def of(cls, cfg: ReproConfig, seed: int, policy_sigma: float) -> TruthCell:
        """The ground-truth cell of ``seed`` in the reproduction configured by ``cfg``."""
        return cls(
            seed=seed, root_seed=cfg.root_seed, policy_sigma=policy_sigma, gamma=cfg.gamma,
            eval_pairs=cfg.eval_pairs, eval_rollouts=cfg.eval_rollouts,
            eval_steps=cfg.train_steps, mc_rollouts=cfg.mc_rollouts,
            td_episodes=cfg.td_episodes, td_steps=cfg.td_steps,
        )  # fmt: skip


def truth_cell(cell: TruthCell) -> dict[str, Any]:
    """Evaluation pairs, Monte-Carlo ``Q^pi`` and the TD table's values there."""
    policy = default_policy(cell.policy_sigma)
    states, actions = sample_evaluation_pairs(
        cell.eval_pairs,
        policy,
        rng_for(cell.root_seed, cell.seed, STREAM["eval_pairs"]),
        n_rollouts=cell.eval_rollouts,
        steps=cell.eval_steps,
    )
    mc = mc_q_values(
        states,
        actions,
        policy,
        rng_for(cell.root_seed, cell.seed, STREAM["monte_carlo"]),
        n_rollouts=cell.mc_rollouts,
        gamma=cell.gamma,
    )
    # The TD table is run-wide (one per run, as in the paper) and rebuilt
    # deterministically from its own stream: cheaper than shipping it around.
    td = td_baseline(
        policy,
        rng_for(cell.root_seed, STREAM["td"]),
        n_episodes=cell.td_episodes,
        steps=cell.td_steps,
        gamma=cell.gamma,
    )
    return {
        "states": states.tolist(),
        "actions": actions.tolist(),
        "mc_mean": mc.mean.tolist(),
        "mc_stderr": mc.stderr.tolist(),
        "td": td.q(states, actions).tolist(),
        "td_visits": td.n_visits(states, actions).tolist(),
    }


@dataclass(frozen=True)
class BudgetCell:
    """One learner on one seed's data."""

    kernel: str
    max_bv: int
    seed: int
    root_seed: int
    train_rollouts: int
    train_steps: int
    learner: dict[str, Any]
    truth_dir: str = field(metadata={"key": False})
    """Where the truth cells are (not part of the cell's identity: folders are relocatable)."""
    truth: dict[str, Any]
    variant: str = "tuned"
    """``"tuned"`` (Fig. 3 proper) or a key of :data:`geoq.experiments.paper.config.VARIANTS`."""
    probe: bool = False
    """Whether this is the cell's rounding probe: the same learner on training data
    perturbed at rounding level (:mod:`geoq.experiments.paper.rounding`)."""


def refits_per_rollout(kernel: str, variant: str) -> bool:
    """Whether a Fig. 3 cell also runs the learner that refits after every roll-out
    (``mse_refit_episode``): the tuned learners of the paper's kernels only. A variant
    does not need it; for the ``resistance`` kernel that second learner re-anchors at
    every basis change (40% of the cell) and its column matched the single refit's within
    the intervals at every paper budget (issue 31)."""
    return variant == "tuned" and kernel in PAPER_KERNELS


def longest_first(cells: Sequence[BudgetCell]) -> list[BudgetCell]:
    """``cells`` in the order a sweep should start them: the learners that re-anchor their
    posterior at every change of the basis set (the ``resistance`` kernel, ``pd_novelty``:
    an O(max_bv^3) factorisation per change, seconds per cell) first, largest budget first;
    the others keep their order. The rows do not depend on it; two workers finish together
    instead of one waiting on the other's last long cell."""

    def reanchors(cell: BudgetCell) -> bool:
        return cell.kernel == "resistance" or bool(cell.learner.get("pd_novelty"))

    return sorted(cells, key=lambda c: (not reanchors(c), -c.max_bv if reanchors(c) else 0))


def load_truth(truth_dir: str | Path, truth: dict[str, Any]) -> dict[str, Any]:
    """The finished ground-truth row of the :class:`TruthCell` given as a spec."""
    spec = cell_spec(truth)
    row = load_cell(Path(truth_dir) / f"{cell_key(spec)}.json", spec)
    if row is None:
        raise FileNotFoundError(
            f"ground truth for seed {truth.get('seed')} is missing in {truth_dir}; "
            "run the truth sweep first"
        )
    return row


def budget_cell(cell: BudgetCell) -> dict[str, Any]:
    """Fit one GP learner and score it against the seed's ground truths."""
    truth = load_truth(cell.truth_dir, cell.truth)
    states = np.asarray(truth["states"], dtype=np.float64)
    actions = np.asarray(truth["actions"], dtype=np.float64)
    mc_mean = np.asarray(truth["mc_mean"], dtype=np.float64)
    td = np.asarray(truth["td"], dtype=np.float64)

    config = QGPConfig.from_dict(cell.learner).replace(kernel=cell.kernel, max_bv=cell.max_bv)
    policy = default_policy(float(cell.truth["policy_sigma"]))
    rollouts = collect_rollouts(
        cell.train_rollouts,
        cell.train_steps,
        policy,
        rng_for(cell.root_seed, cell.seed, STREAM["train"]),
        gamma=float(cell.truth["gamma"]),
    )
    if cell.probe:
        rollouts = perturb(rollouts, rng_for(cell.root_seed, cell.seed, STREAM["probe"]))
    row: dict[str, Any] = {"kernel": cell.kernel, "max_bv": cell.max_bv, "seed": cell.seed}
    row.update(
        score_learner(
            config,
            rollouts,
            states,
            actions,
            mc_mean,
            np.asarray(truth["mc_stderr"]),
            td=td,
            refit_episode=refits_per_rollout(cell.kernel, cell.variant),
        )
    )
    if cell.variant != "tuned":
        row["variant"] = cell.variant
    if cell.probe:
        row["probe"] = True
    return row


def score_learner(
    config: QGPConfig,
    rollouts: Sequence[Rollout],
    states: FloatArray,
    actions: FloatArray,
    mc_mean: FloatArray,
    mc_stderr: FloatArray,
    *,
    td: FloatArray | None = None,
    refit_episode: bool = True,
    focus: np.ndarray | None = None,
) -> dict[str, Any]:
    """Fit one GP learner on ``rollouts`` and score it at the evaluation pairs: the Fig. 3
    columns (online posterior, after a DTC refit on its final BV set and graph, and, with
    ``refit_episode``, a second learner that refits after every roll-out).

    ``states [N, d]`` and ``actions [N]`` / ``[N, d_a]`` are in the learner's input space;
    ``mc_mean``, ``mc_stderr`` the Monte-Carlo ``Q^pi`` there; ``td`` the TD table's values
    (column ``mse_td``; left out when ``None``). ``focus``, a boolean mask ``[N]`` of
    pairs of special interest, adds ``mse_focus`` and ``mse_refit_focus``: the MSEs over
    those pairs only (NaN when there are none).
    """

    def focused(mean: FloatArray) -> float:
        assert focus is not None
        return mse(mean[focus], mc_mean[focus]) if focus.any() else float("nan")

    with warnings.catch_warnings(), np.errstate(over="ignore"):
        # Repairs of the indefinite geodesic Gram are expected; they are counted in the row.
        # A diverged posterior scores an MSE of inf (counted in REPORT.md), not a warning.
        warnings.simplefilter("ignore", NumericalWarning)
        learner = GPQFunction(config)
        # The learner that refits after every roll-out streams the first roll-out as this
        # one does: fitted alongside, that part runs once (the same numbers as on its own).
        episodic = learner.fit_twin(rollouts, "episode") if refit_episode else None
        if episodic is None:
            learner.fit(rollouts)
        assert learner.gp_ is not None
        prior = learner.prior_variance(states, actions)
        mean, std = learner.predict(states, actions, return_std=True)
        diag = learner.gp_.diagnostics
        row: dict[str, Any] = {
            "mse": mse(mean, mc_mean),
            "normalized_variance": normalized_variance(std**2, prior),
            "n_bv": int(learner.gp_.n_bv),
        }
        if td is not None:
            row["mse_td"] = mse(mean, td)
        if focus is not None:
            row["mse_focus"] = focused(mean)
        row.update(
            {
                # The trivial baseline: predict the mean training return everywhere.
                "mse_constant": mse(np.full_like(mc_mean, learner.y_mean_), mc_mean),
                "mc_noise_floor": float(np.mean(np.asarray(mc_stderr) ** 2)),
                "negative_novelty": int(diag.negative_novelty),
                "variance_clipped": int(diag.variance_clipped),
                "eig_clips": int(diag.eig_clips),
                "q_resyncs": int(diag.q_resyncs),
            }
        )
        learner.refit()
        mean, std = learner.predict(states, actions, return_std=True)
        row["mse_refit"] = mse(mean, mc_mean)
        row["normalized_variance_refit"] = normalized_variance(std**2, prior)
        if focus is not None:
            row["mse_refit_focus"] = focused(mean)
        if episodic is None:
            return row
        # A refit after every roll-out changes what the later online updates start from:
        # a different learner on the same data.
        mean, std = episodic.predict(states, actions, return_std=True)
        row["mse_refit_episode"] = mse(mean, mc_mean)
        row["normalized_variance_refit_episode"] = normalized_variance(std**2, prior)
    return row
