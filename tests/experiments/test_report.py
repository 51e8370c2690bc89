"""The claim assessment of REPORT.md, on synthetic rows whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from geoq.experiments.paper.report import assess_claims
from geoq.experiments.stats import mean_interval, paired_difference


def _rows(mse_geo, mse_euc, nv_geo, nv_euc, seeds=8, noise=0.01):
    rng = np.random.default_rng(0)
    rows = []
    for budget in mse_geo:
        for s in range(seeds):
            e = rng.normal(scale=noise)
            rows.append(
                {
                    "kernel": "euclidean",
                    "max_bv": budget,
                    "seed": s,
                    "mse": mse_euc[budget] + e,
                    "normalized_variance": nv_euc[budget],
                }
            )
            rows.append(
                {
                    "kernel": "nearest",
                    "max_bv": budget,
                    "seed": s,
                    "mse": mse_geo[budget] + e + rng.normal(scale=noise / 10),
                    "normalized_variance": nv_geo[budget] + rng.normal(scale=noise / 10),
                }
            )
    return rows


def test_paper_shaped_data_supports_every_claim():
    budgets = [5, 10, 20, 50, 100, 200]
    mse_euc = dict(zip(budgets, [4.0, 3.0, 2.0, 1.0, 0.5, 0.5], strict=True))
    mse_geo = dict(zip(budgets, [2.0, 1.5, 2.0, 1.3, 0.5, 0.5], strict=True))  # worse at 50
    nv_euc = dict(zip(budgets, [0.5, 0.4, 0.3, 0.2, 0.1, 0.05], strict=True))
    nv_geo = {b: v + 0.1 for b, v in nv_euc.items()}
    v = assess_claims(_rows(mse_geo, mse_euc, nv_geo, nv_euc))["nearest"]
    verdicts = [x["verdict"] for x in v]
    assert verdicts[0] == verdicts[2] == verdicts[3] == "supported"
    assert verdicts[1].startswith("consistent")
    assert v[1]["threshold"] == 100
    assert v[3]["worse_at"] == [50]


def test_opposite_data_contradicts():
    budgets = [5, 10, 20, 50, 100, 200]
    mse_euc = dict.fromkeys(budgets, 1.0)
    mse_geo = dict.fromkeys(budgets, 2.0)
    nv = dict.fromkeys(budgets, 0.3)
    nv_geo = {b: 0.1 for b in budgets}
    v = assess_claims(_rows(mse_geo, mse_euc, nv_geo, nv))["nearest"]
    assert v[0]["verdict"] == "contradicted"
    assert v[1]["verdict"] == "not supported" and v[1]["threshold"] is None
    assert v[2]["verdict"] == "contradicted"
    assert v[3]["worse_at"] == budgets


def test_intervals_match_scipy_t():
    scipy_stats = pytest.importorskip("scipy.stats")
    x = np.array([1.0, 2.0, 4.0, 3.5])
    iv = mean_interval(x)
    lo, hi = scipy_stats.t.interval(0.95, len(x) - 1, loc=x.mean(), scale=scipy_stats.sem(x))
    assert (iv.low, iv.high) == pytest.approx((lo, hi))
    assert mean_interval([3.0]).low == -np.inf
    d = paired_difference([1.0, 2.0, 3.0], [0.5, 1.5, 2.0])
    assert d.mean == pytest.approx(2 / 3)


def test_config_overrides_merge_the_learner_and_reject_unknown_fields():
    from geoq.experiments.paper.config import SCALES, config_with_overrides

    cfg = config_with_overrides(SCALES["quick"], {"seeds": 2, "learner": {"tol": 1e-3}})
    assert cfg.seeds == 2 and cfg.learner.tol == 1e-3
    assert cfg.learner.scaling == SCALES["quick"].learner.scaling
    with pytest.raises(ValueError, match="unknown"):
        config_with_overrides(SCALES["quick"], {"seedz": 2})
    with pytest.raises(ValueError, match="budgets"):
        config_with_overrides(SCALES["quick"], {"budgets": [0]})
    # The paper preset's sub-grid must follow a changed grid, and the error says how.
    with pytest.raises(ValueError, match=r"subset of budgets \(\[\] for every budget\)"):
        config_with_overrides(SCALES["paper"], {"budgets": [5, 10]})
    cfg = config_with_overrides(SCALES["paper"], {"budgets": [5, 10], "beyond_paper_budgets": []})
    assert cfg.budgets_of("resistance") == (5, 10)


def test_variant_learners_change_only_what_they_name():
    from geoq.experiments.paper.config import RAW_UNITS, variant_learner
    from geoq.learners import QGPConfig

    tuned = QGPConfig(
        kernel="interpolated", eps=0.5, sigma_sp=0.03, amplitude=3.7, noise=0.2,
        normalize_weights=True, attach_weights=True, sigma_se=0.1,
    )  # fmt: skip
    f = variant_learner("faithful", tuned)
    assert f.scaling == RAW_UNITS and RAW_UNITS.scale == (1.0, 1.0, 1.0)
    assert (f.amplitude, f.sigma_sp, f.eps) == (1.0, 1.0, 0.3)
    assert not f.normalize_weights and not f.attach_weights  # the literal JC12 eq. 5 sum
    assert (f.noise, f.sigma_se, f.kernel) == (0.2, 0.1, "interpolated")  # not stated: tuned
    p = variant_learner("pd_novelty", tuned)
    assert p == tuned.replace(pd_novelty=True)
    with pytest.raises(ValueError, match="variant"):
        variant_learner("literal", tuned)


def test_variant_claims_are_undetermined_when_the_variant_diverged():
    from geoq.experiments.paper.report import _variant_lines

    budgets = [5, 50]
    mse_euc = dict.fromkeys(budgets, 1.0)
    nv = dict.fromkeys(budgets, 0.2)
    rows = _rows(dict.fromkeys(budgets, 2.0), mse_euc, nv, nv)
    for r in rows:
        r["mse_refit"], r["normalized_variance_refit"], r["n_bv"] = r["mse"], 0.2, 5
    rows = [r | {"mse_constant": 10.0} for r in rows]
    variant = [
        r | {"variant": "pd_novelty", "mse": float("inf")} for r in rows if r["kernel"] == "nearest"
    ]
    text = "\n".join(_variant_lines(rows, variant))
    assert "not finite" in text  # the online MSE table
    assert "`nearest` 16 online / 0 refit of 16" in text
    online = [ln for ln in text.splitlines() if "| online | `nearest` |" in ln]
    assert online and all(
        ("undetermined" in ln) != ("variance" in ln) for ln in online
    )  # MSE claims undetermined; the variance claim still tested
    refit = [ln for ln in text.splitlines() if "| refit | `nearest` |" in ln]
    assert refit and not any("undetermined" in ln for ln in refit)


def test_a_kernel_run_at_part_of_the_grid_is_tested_at_its_own_budgets():
    from geoq.experiments.paper.report import _table

    grid = [5, 10, 20, 35, 50, 75, 100, 150, 200]  # lowest third: 5, 10, 20
    mse_euc = dict(zip(grid, [4.0, 3.0, 2.0, 1.5, 1.0, 0.8, 0.5, 0.5, 0.5], strict=True))
    mse_geo = dict(zip(grid, [2.0, 3.5, 1.0, 1.5, 1.3, 0.8, 0.5, 0.5, 0.5], strict=True))
    nv = dict.fromkeys(grid, 0.2)
    rows = _rows(mse_geo, mse_euc, {b: 0.3 for b in grid}, nv)
    part = [10, 20, 50, 200]
    rows += [r | {"kernel": "resistance"} for r in rows if r["kernel"] == "nearest"]
    rows = [r for r in rows if r["kernel"] != "resistance" or r["max_bv"] in part]
    verdicts = assess_claims(rows)
    full, sub = verdicts["nearest"], verdicts["resistance"]
    # The same paired differences where both ran; "small" is the grid's lowest third.
    assert list(full[0]["evidence"]) == [5, 10, 20]
    assert list(sub[0]["evidence"]) == [10, 20]
    for b in (10, 20):
        assert sub[0]["evidence"][b] == full[0]["evidence"][b]
    assert full[0]["verdict"] == "contradicted" and sub[0]["verdict"] == "contradicted"
    assert full[3]["worse_at"] == [10, 50] and sub[3]["worse_at"] == [10, 50]
    assert sub[1]["threshold"] == 200 and full[1]["threshold"] == 75
    assert sub[2]["verdict"] == "supported" and list(sub[2]["evidence"]) == part
    table = _table(rows, "mse")
    assert table[0] == "| max_bv | euclidean | nearest | resistance |"
    assert table[2 + grid.index(5)].endswith("| - |") and "| - |" not in table[2 + grid.index(10)]
