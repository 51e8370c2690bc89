"""The control suite: goal verdicts against hand-computed figures, the runner end to end on
tiny stand-in protocols (files, skipped tasks, resume, indicative runs), the CLI's errors."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats
from typer.testing import CliRunner

import geoq  # noqa: F401  (registers the envs)
import geoq.experiments.control.benchmark as control
import geoq.experiments.control.suite as suite
from geoq.cli import app
from geoq.envs import TWO_ROOMS_ID
from geoq.experiments.control.suite import (
    CONTROL_SUITE,
    ControlGoal,
    control_goal,
    control_goals,
    goal_verdict,
    run_control_suite,
)

RUNNER = CliRunner()


def _no_constants(name: str) -> None:
    raise AssertionError(f"control_suite.json holds {name}, which strict JSON has not")


def _row(successes: list[float], returns: list[float], every: int = 100) -> dict[str, Any]:
    n = len(successes)
    return {"checkpoints": [every * (i + 1) for i in range(n)], "eval_success": successes,
            "eval_return": returns, "ms_per_step": 2.0}  # fmt: skip


def _goal(kind: Any, target: float) -> ControlGoal:
    return ControlGoal("geoq/TwoRooms-v0", 5, 500, 100, 2, kind, target, "test")


def test_median_steps_is_the_median_first_checkpoint_of_success() -> None:
    rows = [
        _row([0.0, 0.95, 1.0], [0, 0, 0]),  # 200
        _row([0.0, 0.0, 0.9], [0, 0, 0]),  # 300
        _row([0.91, 0.0, 0.0], [0, 0, 0]),  # 100: a later fall-back does not undo it
        _row([0.0, 0.5, 0.89], [0, 0, 0]),  # never
        _row([0.0, 0.0, 0.0], [0, 0, 0]),  # never
    ]
    v = goal_verdict(_goal("median_steps", 300), rows)
    assert v["value"] == 300 and v["reached"] == 3 and v["met"]
    assert not goal_verdict(_goal("median_steps", 299), rows)["met"]
    assert v["low"] <= v["value"] <= v["high"] == math.inf


def test_seeds_reaching_uses_the_exact_binomial_interval() -> None:
    rows = [_row([1.0], [0])] * 7 + [_row([0.0], [0])] * 3
    v = goal_verdict(_goal("seeds_reaching", 0.7), rows)
    ci = stats.binomtest(7, 10).proportion_ci(confidence_level=0.95, method="exact")
    assert v["value"] == 0.7 and v["met"]
    assert v["low"] == pytest.approx(ci.low) and v["high"] == pytest.approx(ci.high)
    assert not goal_verdict(_goal("seeds_reaching", 0.8), rows)["met"]
    none = goal_verdict(_goal("seeds_reaching", 0.7), [_row([0.0], [0])] * 4)
    assert none["value"] == 0.0 and none["low"] == 0.0 and not none["met"]


def test_median_return_reads_the_last_checkpoint() -> None:
    rows = [_row([math.nan] * 2, [5.0, r]) for r in (-9.0, -4.0, -6.0, 100.0, -5.0)]
    v = goal_verdict(_goal("median_return", -5.0), rows)
    assert v["value"] == float(np.median([-9.0, -4.0, -6.0, 100.0, -5.0])) == -5.0
    assert v["met"] and v["reached"] == 0
    assert not goal_verdict(_goal("median_return", -4.9), rows)["met"]
    with pytest.raises(ValueError, match="no benchmark rows"):
        goal_verdict(_goal("median_return", 0.0), [])


def test_the_registry_holds_the_issues_protocols() -> None:
    assert control_goal("Pendulum-v1").kind == "seeds_reaching"
    assert [g.env_id for g in CONTROL_SUITE][:3] == [
        "geoq/PendulumSwingUp-v0", "MountainCarContinuous-v0", "Pendulum-v1"]  # fmt: skip
    assert {g.extra for g in CONTROL_SUITE} == {None, "mujoco"}
    with pytest.raises(ValueError, match="not a task of the control suite; known: geoq/"):
        control_goal("CartPole-v1")


def test_a_named_task_without_its_extra_is_an_error(monkeypatch: pytest.MonkeyPatch) -> None:
    missing = ControlGoal("Reacher-v5", 1, 10, 10, 1, "median_return", 0, "t", "no_such_mod_xyz")
    monkeypatch.setattr(suite, "CONTROL_SUITE", (missing,))
    with pytest.raises(ValueError, match=r"needs the optional extra no_such_mod_xyz: pip install"):
        control_goals(["Reacher-v5"])
    assert control_goals(None) == [missing]  # all tasks: the report skips it instead


@pytest.fixture
def tiny_suite(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """A one-task suite on TwoRooms (2 seeds, 40 steps) plus a task whose extra is missing;
    returns the list of seeds whose cell actually ran."""
    goals = (
        ControlGoal(TWO_ROOMS_ID, 2, 40, 20, 2, "median_steps", 40, "test"),
        ControlGoal("Reacher-v5", 2, 40, 20, 2, "median_return", -5, "t", "no_such_mod_xyz"),
    )
    monkeypatch.setattr(suite, "CONTROL_SUITE", goals)
    ran: list[int] = []
    real = control.control_cell

    def counted(cell: control.ControlCell) -> dict[str, Any]:
        ran.append(cell.seed)
        return real(cell)

    monkeypatch.setattr(control, "control_cell", counted)
    return ran


def test_the_suite_writes_its_report_skips_and_resumes(
    tmp_path: Path, tiny_suite: list[int]
) -> None:
    out = tmp_path / "suite"
    summary = run_control_suite(out, progress=False)
    assert sorted(tiny_suite) == [0, 1]
    first, skipped = summary["tasks"]
    assert skipped["env_id"] == "Reacher-v5" and "no_such_mod_xyz" in skipped["skipped"]
    rows = [json.loads(p.read_text()) for p in sorted((out / "geoq-TwoRooms-v0" / "cells")
                                                       .glob("*.json"))]  # fmt: skip
    assert len(rows) == 2
    expected = goal_verdict(suite.CONTROL_SUITE[0], [r["row"] for r in rows])
    assert first["value"] == expected["value"] and first["met"] == expected["met"]
    stored = json.loads((out / "control_suite.json").read_text(), parse_constant=_no_constants)
    assert stored["tasks"][0]["met"] == first["met"] and stored["tasks"][1] == skipped
    value = stored["tasks"][0]["value"]
    assert value == first["value"] if math.isfinite(first["value"]) else value is None
    report = (out / "CONTROL_SUITE.md").read_text()
    assert "| geoq/TwoRooms-v0 |" in report and "skipped: needs the optional extra" in report
    assert "indicative" not in report
    run_control_suite(out, progress=False)  # a rerun resumes: no cell runs again
    assert sorted(tiny_suite) == [0, 1]


def test_fewer_seeds_make_an_indicative_run_and_other_settings_are_refused(
    tmp_path: Path, tiny_suite: list[int]
) -> None:
    out = tmp_path / "suite"
    summary = run_control_suite(out, seeds=1, progress=False)
    assert summary["tasks"][0]["seeds"] == 1 and summary["tasks"][0]["protocol_seeds"] == 2
    assert "1 (protocol 2: indicative)" in (out / "CONTROL_SUITE.md").read_text()
    with pytest.raises(FileExistsError, match="other settings"):
        run_control_suite(out, progress=False)  # 2 seeds into the 1-seed report
    assert tiny_suite == [0]
    with pytest.raises(ValueError, match="seeds must be an integer >= 1"):
        run_control_suite(out, seeds=0)


def test_cli_control_suite_refuses_an_unknown_task(tmp_path: Path) -> None:
    result = RUNNER.invoke(app, ["control-suite", "--task", "CartPole-v1", "--out",
                                 str(tmp_path / "o")])  # fmt: skip
    assert result.exit_code == 2 and "not a task of the control suite" in result.output
    result = RUNNER.invoke(app, ["control-suite", "--baseline", "ppo", "--out",
                                 str(tmp_path / "o")])  # fmt: skip
    assert result.exit_code == 2 and "'ppo' is not one of" in result.output


def test_the_report_writes_four_digits_and_no_exponent() -> None:
    task = {"env_id": "Reacher-v5", "goal": "g", "source": "s", "seeds": 5,
            "protocol_seeds": 5, "value": -9.600932, "low": -math.inf, "high": math.inf,
            "reached": 0, "met": False, "ms_per_step": 23.46}  # fmt: skip
    steps = dict(task, env_id="MountainCarContinuous-v0", value=10_000.0, low=5_000.0)
    report = suite.control_suite_report([task, steps], baselines=[])
    assert "| -9.601 [-inf, inf] |" in report and "| 10000 [5000, inf] |" in report
    assert "fewer than 6 seeds" in report
