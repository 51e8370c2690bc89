"""The rounding probe: the perturbation, the flag and the verdicts it makes sensitive."""

from __future__ import annotations

import math

import numpy as np
import pytest

from geoq.experiments.paper.claims import SENSITIVE, claim_verdicts
from geoq.experiments.paper.rounding import (
    PERTURBATION,
    PROBE_SUFFIX,
    RELATIVE_CHANGE,
    attach_probes,
    decided_by_rounding,
    perturb,
    probe_summary,
    relative_change,
    sensitive_learners,
)
from geoq.policies import default_policy
from geoq.rollouts import collect_rollouts


def test_the_perturbation_is_relative_small_and_seeded():
    rollouts = collect_rollouts(2, 30, default_policy(1.0), np.random.default_rng(0), gamma=0.9)
    one = perturb(rollouts, np.random.default_rng(1))
    two = perturb(rollouts, np.random.default_rng(1))
    for r, p, q in zip(rollouts, one, two, strict=True):
        for name in ("states", "actions", "rewards", "next_states", "returns"):
            a, b = getattr(r, name), getattr(p, name)
            assert np.array_equal(b, getattr(q, name)) and not b.flags.writeable
            nonzero = a != 0
            ratio = np.abs(b[nonzero] / a[nonzero] - 1.0)
            assert ratio.max() <= PERTURBATION * (1 + 1e-3) and ratio.max() > PERTURBATION / 10
        assert p.gamma == r.gamma and p.terminated == r.terminated


@pytest.mark.parametrize(
    ("value", "probe", "change"),
    [
        (1.0, 1.0, 0.0),
        (2.0, 1.0, 0.5),
        (1.0, 1.0 + 1e-9, 1e-9),
        (math.inf, math.inf, 0.0),  # both diverged
        (1e303, math.inf, math.inf),  # finite against not finite
        (math.nan, 1.0, math.inf),
        (0.0, 0.0, 0.0),
        (0.0, 1e-300, 1.0),
    ],
)
def test_relative_change(value, probe, change):
    row = {"mse": value, "mse" + PROBE_SUFFIX: probe}
    assert relative_change(row, "mse") == pytest.approx(change, rel=1e-6)
    assert decided_by_rounding(row, "mse") == (change > RELATIVE_CHANGE)


def test_an_unprobed_row_is_not_decided():
    assert relative_change({"mse": 1.0}, "mse") is None
    assert relative_change({"mse": 1.0, "mse_probe": ""}, "mse") is None
    assert not decided_by_rounding({"mse": 1.0}, "mse")


def _row(kernel, seed, mse, nv, variant=None, **probe):
    row = {
        "kernel": kernel,
        "max_bv": 10,
        "seed": seed,
        "mse": mse,
        "normalized_variance": nv,
        "mse_refit": mse,
        "normalized_variance_refit": nv,
    }
    if variant:
        row["variant"] = variant
    row.update({k + PROBE_SUFFIX: v for k, v in probe.items()})
    return row


def test_probes_attach_to_their_cell_and_flag_the_learner():
    rows = [_row("euclidean", s, 1.0, 0.1) for s in range(3)]
    rows += [_row("nearest", s, 2.0, 0.2, variant="pd_novelty") for s in range(3)]
    probes = [_row("euclidean", 0, 1.0 + 1e-9, 0.1)]
    probes += [_row("nearest", 1, 2.0, 0.3, variant="pd_novelty")]
    merged = attach_probes(rows, probes)
    assert merged[0]["mse_probe"] == 1.0 + 1e-9 and "mse_probe" not in merged[1]
    assert merged[4]["normalized_variance_probe"] == 0.3 and "mse_probe" not in merged[3]
    assert sensitive_learners(merged) == {("pd_novelty", "nearest")}
    summary = probe_summary(merged)
    assert summary[("tuned", "euclidean")][1:] == (0, 4)
    assert summary[("pd_novelty", "nearest")][1:] == (2, 4)  # both posteriors' variances


def test_a_verdict_that_reads_a_decided_learner_is_sensitive():
    rng = np.random.default_rng(0)
    rows = []
    for kernel in ("euclidean", "nearest"):
        for b in (10, 20, 50):
            for s in range(3):
                mse = 1.0 + rng.uniform() + (kernel == "nearest")
                r = {**_row(kernel, s, mse, 0.1 + rng.uniform()), "max_bv": b}
                rows.append(r)
    variants = [{**r, "variant": "pd_novelty"} for r in rows if r["kernel"] == "nearest"]
    plain = claim_verdicts(rows, variants)
    assert all(SENSITIVE not in str(v.values()) for v in plain)
    variants[4]["mse_refit" + PROBE_SUFFIX] = 2 * variants[4]["mse_refit"]
    marked = claim_verdicts(rows, variants)
    assert all(v["pd_novelty"] == SENSITIVE and v["tuned"] != SENSITIVE for v in marked)
    local = claim_verdicts(rows, variants, show_local=True)
    for v, p in zip(local, plain, strict=True):
        assert v["pd_novelty"] == f"{SENSITIVE} (here: {p['pd_novelty']})"
    # The baseline decided by rounding: every verdict reads it.
    rows[0]["mse" + PROBE_SUFFIX] = math.inf
    assert all(v["tuned"] == SENSITIVE == v["pd_novelty"] for v in claim_verdicts(rows, variants))
