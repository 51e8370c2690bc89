"""Control experiments end to end on tiny budgets: train -> files, evaluate, benchmark, report."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import geoq  # noqa: F401  (registers the envs)
from geoq.agents import GPQAgent
from geoq.cli import app
from geoq.experiments.control.benchmark import (
    HandMadeController,
    control_report,
    run_control_benchmark,
    steps_to_success,
)
from geoq.experiments.control.evaluation import Evaluation, evaluate_agent, evaluation_success

RUNNER = CliRunner()
ENV = "geoq/PendulumSwingUp-v0"


def test_geoq_train_writes_every_output_and_evaluate_reads_it(tmp_path: Path) -> None:
    out = tmp_path / "run"
    cfg = tmp_path / "agent.json"
    cfg.write_text(json.dumps({"max_bv": 30, "train_every": 100}))
    args = ["train", "--env", ENV, "--kernel", "nearest", "--timesteps", "260", "--seed", "3",
            "--out", str(out), "--config", str(cfg), "--no-progress"]  # fmt: skip
    result = RUNNER.invoke(app, args)
    assert result.exit_code == 0, result.output
    for name in ("learning_curve.csv", "learning_curve.png", "visits.png", "agent.npz",
                 "config.json"):  # fmt: skip
        assert (out / name).is_file(), name  # visits.png: the swing-up's observation is 2-D
    rows = list(csv.DictReader((out / "learning_curve.csv").open()))
    assert [list(r) for r in rows] == [["timesteps", "episode", "return", "success"]]
    assert rows[0]["timesteps"] == "250" and rows[0]["success"] in ("0", "1")
    config = json.loads((out / "config.json").read_text())
    assert config["agent"]["kernel"] == "nearest" and config["agent"]["max_bv"] == 30
    assert config["seed"] == 3 and config["env"] == ENV

    result = RUNNER.invoke(app, ["evaluate", str(out / "agent.npz"), "--episodes", "3"])
    assert result.exit_code == 0, result.output
    assert "mean return" in result.output and "success rate" in result.output


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--timesteps", "0"], "timesteps"),
        (["--kernel", "rbf"], "kernel"),
        (["--out", ""], "output directory"),
    ],
)
def test_geoq_train_usage_errors(extra: list[str], match: str, tmp_path: Path) -> None:
    args = ["train", "--out", str(tmp_path / "x"), "--no-progress", *extra]
    result = RUNNER.invoke(app, args, env={"COLUMNS": "200", "NO_COLOR": "1"})
    assert result.exit_code == 2
    assert match in result.output


def test_geoq_train_rejects_a_bad_config_up_front(tmp_path: Path) -> None:
    cfg = tmp_path / "bad.json"
    for content, match in (('{"gamma": 2}', "gamma"), ('{"bogus": 1}', "bogus"), ("[1]", "object")):
        cfg.write_text(content)
        result = RUNNER.invoke(
            app, ["train", "--out", str(tmp_path / "o"), "--config", str(cfg), "--no-progress"],
            env={"COLUMNS": "200"},
        )  # fmt: skip
        assert result.exit_code == 2, result.output
        assert match in result.output
        assert not (tmp_path / "o").exists()


def test_evaluation_of_the_hand_made_controller_succeeds_everywhere() -> None:
    ev = evaluate_agent(HandMadeController(), n_episodes=4, seed=0)
    assert ev.success_rate == 1.0
    assert np.all(ev.returns > 150)  # upright after about 49 of 250 steps
    again = evaluate_agent(HandMadeController(), n_episodes=4, seed=0)
    np.testing.assert_array_equal(ev.returns, again.returns)


def test_untrained_agent_fails_the_evaluation() -> None:
    agent = GPQAgent(ENV, max_bv=20, seed=0)
    ev = evaluate_agent(agent, n_episodes=3)
    assert ev.success_rate == 0.0 and ev.returns.shape == (3,)


def test_benchmark_is_resumable_and_reports(tmp_path: Path) -> None:
    kw = dict(
        env_id=ENV, kernels=["euclidean"], seeds=2, timesteps=120, eval_every=60,
        eval_episodes=2, configs=[{"max_bv": 20, "train_every": 60}], progress=False,
    )  # fmt: skip
    rows = run_control_benchmark(tmp_path, **kw)  # type: ignore[arg-type]
    assert [r["checkpoints"] for r in rows] == [[60, 120], [60, 120]]
    for name in ("control.csv", "learning_curves.png", "CONTROL.md", "cells"):
        assert (tmp_path / name).exists()
    stamp = {p: p.stat().st_mtime_ns for p in (tmp_path / "cells").glob("*.json")}
    again = run_control_benchmark(tmp_path, **kw)  # type: ignore[arg-type]
    assert again == rows
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "cells").glob("*.json")} == stamp
    report = (tmp_path / "CONTROL.md").read_text()
    assert "euclidean[max_bv=20,train_every=60]" in report
    assert "hand-made controller" in report and "success rate 1.00" in report


def test_steps_to_success_and_report() -> None:
    row = {"label": "k", "checkpoints": [250, 500, 750], "eval_success": [0.0, 0.95, 0.5],
           "eval_return": [1.0, 2.0, 3.0], "ms_per_step": 1.0}  # fmt: skip
    assert steps_to_success(row) == 500
    assert math.isinf(steps_to_success(row, threshold=0.99))
    text = control_report([row, dict(row, eval_success=[0.0, 0.0, 0.0])], "T")
    assert "| k | 2 |" in text and "1/2" in text


def test_success_of_tasks_without_is_success_is_a_mean_return_threshold() -> None:
    nan = np.full(3, np.nan)
    ev_hi = Evaluation(returns=np.array([95.0, 92.0, 85.0]), successes=nan)  # mean 90.67
    ev_lo = Evaluation(returns=np.array([95.0, 92.0, 80.0]), successes=nan)  # mean 89
    assert evaluation_success(ev_hi, "MountainCarContinuous-v0") == 1.0
    assert evaluation_success(ev_lo, "MountainCarContinuous-v0") == 0.0
    assert evaluation_success(
        Evaluation(returns=np.array([-150.0, -170.0]), successes=np.full(2, np.nan)), "Pendulum-v1"
    ) == 1.0  # fmt: skip
    reported = Evaluation(returns=np.zeros(4), successes=np.array([1.0, 1.0, 0.0, 1.0]))
    assert evaluation_success(reported, "geoq/TwoRooms-v0") == 0.75
    assert math.isnan(evaluation_success(Evaluation(np.zeros(2), np.full(2, np.nan)), "X-v0"))
    text = control_report([], "t", env_id="MountainCarContinuous-v0")
    assert "mean return is >= 90" in text


@pytest.mark.parametrize(
    ("option", "value"), [("--replay", "graf"), ("--exploration", "eps"), ("--baseline", "ppo")]
)
def test_bench_control_refuses_unknown_choices(tmp_path: Path, option: str, value: str) -> None:
    result = RUNNER.invoke(app, ["bench-control", "--out", str(tmp_path / "b"), option, value])
    assert result.exit_code == 2
    assert f"'{value}' is not one of" in result.output and option in result.output
