"""Which Fig. 3 results rounding decides: a twin of each probed cell on perturbed data.

Other CPUs round differently (NumPy's SIMD ``exp``, OpenBLAS's kernels, libm's FMA
variants), so a learner whose computation amplifies the last bits (the chaotic
re-anchoring of ``pd_novelty`` on an indefinite Gram, for instance) gives other numbers
on another machine from the same code and seeds. No tolerance that such numbers meet
would still catch a change, and no list of machines is complete; so the reproduction
measures it on the machine it runs on.

A *probe* is the cell run again on its training data with every array (states,
actions, rewards, returns) multiplied by ``1 + PERTURBATION * u``, ``u`` uniform on
``[-1, 1]`` from the seed's own stream: a change of a few hundred units in the last
place, of the size by which two CPUs' kernels differ after a few operations. A stable
computation moves by about the condition number times that; a chaotic one by as much
as the result itself.

A *learner* (variant, kernel) is **decided by rounding** when any of its probed values
(MSE or normalised variance of any posterior, any budget, any probed seed) moves by more
than :data:`RELATIVE_CHANGE` of itself, or from finite to not finite. One flag per
learner, not per value: a chaotic computation shows in most of its values but not in
each of them (a variance clipped to 0 or an MSE that diverged in both runs does not
move), and the flag must not depend on the machine that measures it. Measured on the
reduced reference run (3 seeds, budgets 10, 50, 100; design notes): every value of the
other learners moved by at most 2.5e-5 of itself, while 28-100% of the values of each
posterior of ``pd_novelty`` moved by more than 1e-3 (medians 0.06-0.44). The claims'
verdicts that read a learner decided by rounding are reported as "sensitive to
rounding" (:mod:`geoq.experiments.paper.claims`), and the reference test holds them as that.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from geoq.rollouts import Rollout

__all__ = [
    "PERTURBATION",
    "POSTERIOR_OF",
    "PROBE_SUFFIX",
    "RELATIVE_CHANGE",
    "attach_probes",
    "decided_by_rounding",
    "perturb",
    "probe_summary",
    "relative_change",
    "sensitive_learners",
]

#: Relative size of a probe's perturbation of the training data.
PERTURBATION = 1e-13
#: A probed value that moves by more than this fraction of itself is decided by rounding.
RELATIVE_CHANGE = 1e-3
#: The probe's value of column ``c`` is stored as ``c + PROBE_SUFFIX``.
PROBE_SUFFIX = "_probe"
#: Each probed column and the posterior it belongs to.
POSTERIOR_OF: dict[str, str] = {
    "mse": "online",
    "normalized_variance": "online",
    "mse_refit": "refit",
    "normalized_variance_refit": "refit",
    "mse_refit_episode": "episode",
    "normalized_variance_refit_episode": "episode",
}


def perturb(rollouts: Sequence[Rollout], rng: np.random.Generator) -> list[Rollout]:
    """``rollouts`` with every array multiplied by ``1 + PERTURBATION * u`` (module)."""

    def moved(a: np.ndarray) -> np.ndarray:
        out = a * (1.0 + PERTURBATION * rng.uniform(-1.0, 1.0, a.shape))
        out.flags.writeable = False
        return out

    return [
        replace(
            r,
            states=moved(r.states),
            actions=moved(r.actions),
            rewards=moved(r.rewards),
            next_states=moved(r.next_states),
            returns=moved(r.returns),
        )
        for r in rollouts
    ]


def _identity(row: Mapping[str, Any]) -> tuple[str, str, int, int]:
    variant = str(row.get("variant", "tuned"))
    return (variant, str(row["kernel"]), int(row["max_bv"]), int(row["seed"]))


def attach_probes(
    rows: Iterable[Mapping[str, Any]], probes: Iterable[Mapping[str, Any]]
) -> list[dict[str, Any]]:
    """``rows`` with each probe's values beside its cell's, as ``COLUMN_probe``."""
    by_cell = {_identity(p): p for p in probes}
    out = []
    for row in rows:
        probe = by_cell.get(_identity(row))
        merged = dict(row)
        if probe is not None:
            merged.update({c + PROBE_SUFFIX: probe[c] for c in POSTERIOR_OF if c in probe})
        out.append(merged)
    return out


def _value(v: Any) -> float | None:
    return None if v is None or v == "" else float(v)


def relative_change(row: Mapping[str, Any], column: str) -> float | None:
    """How far ``row``'s probe moved ``column``, as a fraction of the larger of the two
    values: ``inf`` from finite to not finite, 0 when both diverged; None where the row
    was not probed."""
    a, b = _value(row.get(column)), _value(row.get(column + PROBE_SUFFIX))
    if a is None or b is None:
        return None
    if math.isfinite(a) != math.isfinite(b):
        return math.inf
    if not math.isfinite(a) or a == b:
        return 0.0  # both diverged, or equal
    return abs(a - b) / max(abs(a), abs(b))


def decided_by_rounding(row: Mapping[str, Any], column: str) -> bool:
    """Whether ``row``'s probe moved ``column`` by more than :data:`RELATIVE_CHANGE`
    (False where the row was not probed)."""
    change = relative_change(row, column)
    return change is not None and change > RELATIVE_CHANGE


def probe_summary(
    rows: Iterable[Mapping[str, Any]],
) -> dict[tuple[str, str], tuple[float, int, int]]:
    """Per probed learner (variant, kernel): the largest relative change of its probed
    values, how many moved by more than :data:`RELATIVE_CHANGE`, and how many there are."""
    out: dict[tuple[str, str], tuple[float, int, int]] = {}
    for row in rows:
        for column in POSTERIOR_OF:
            change = relative_change(row, column)
            if change is None:
                continue
            key = (str(row.get("variant", "tuned")), str(row["kernel"]))
            largest, moved, n = out.get(key, (0.0, 0, 0))
            out[key] = (max(largest, change), moved + (change > RELATIVE_CHANGE), n + 1)
    return out


def sensitive_learners(rows: Iterable[Mapping[str, Any]]) -> set[tuple[str, str]]:
    """The learners (variant, kernel) whose results rounding decides (module docstring);
    the variant of a row of ``fig3.csv`` is ``"tuned"``."""
    return {
        (str(row.get("variant", "tuned")), str(row["kernel"]))
        for row in rows
        if any(decided_by_rounding(row, column) for column in POSTERIOR_OF)
    }
