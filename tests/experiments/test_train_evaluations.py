"""Greedy evaluations while learning (``EvalCallback``, ``geoq train --eval-every``)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from geoq.agents import GPQAgent
from geoq.cli import app
from geoq.experiments.control.evaluation import EVAL_COLUMNS, EvalCallback, evaluate_agent
from geoq.experiments.control.plotting import plot_training_with_evaluations

ENV = "geoq/PendulumSwingUp-v0"  # 250-step episodes
TINY = {"max_bv": 20, "n_candidates": 5, "train_every": 100}


def _agent() -> GPQAgent:
    return GPQAgent(ENV, seed=1, **TINY)  # type: ignore[arg-type]


def test_evaluations_come_after_the_episode_that_passes_each_multiple_and_at_the_end() -> None:
    agent = _agent()
    cb = EvalCallback(agent, eval_every=300, n_episodes=2, seed=5)
    agent.learn(760, callback=cb)
    cb.finish()
    assert [r["timesteps"] for r in cb.rows] == [500, 750, 760]
    assert list(cb.rows[0]) == list(EVAL_COLUMNS)
    final = evaluate_agent(agent, ENV, 2, seed=5)  # the same resets as the callback's
    assert cb.rows[-1]["mean_return"] == pytest.approx(float(np.mean(final.returns)), abs=0)
    assert cb.rows[-1]["success"] == final.success_rate
    cb.finish()  # nothing new to evaluate
    assert len(cb.rows) == 3


def test_evaluations_do_not_change_what_the_agent_learns() -> None:
    plain, watched = _agent(), _agent()
    plain.learn(520)
    cb = EvalCallback(watched, eval_every=250, n_episodes=3)
    watched.learn(520, callback=cb)
    assert len(cb.rows) == 2
    assert [e.ret for e in plain.episodes] == [e.ret for e in watched.episodes]
    np.testing.assert_array_equal(plain.gp.alpha, watched.gp.alpha)
    assert plain.rng.bit_generator.state == watched.rng.bit_generator.state


def test_eval_callback_refuses_a_zero_interval() -> None:
    with pytest.raises(ValueError, match="eval_every"):
        EvalCallback(_agent(), eval_every=0)


def test_geoq_train_writes_the_evaluations_beside_the_training_curve(tmp_path: Path) -> None:
    base = ["train", "--env", ENV, "--timesteps", "300", "--seed", "2", "--no-progress"]
    cfg = tmp_path / "tiny.json"
    cfg.write_text('{"max_bv": 20, "n_candidates": 5, "train_every": 100}')
    out = tmp_path / "run"
    args = [*base, "--out", str(out), "--config", str(cfg), "--eval-every", "250",
            "--eval-episodes", "2"]  # fmt: skip
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader((out / "evaluations.csv").open()))
    assert [r["timesteps"] for r in rows] == ["250", "300"]
    assert all(r["episodes"] == "2" and math.isfinite(float(r["mean_return"])) for r in rows)
    assert list(rows[0]) == list(EVAL_COLUMNS)
    train_rows = list(csv.DictReader((out / "learning_curve.csv").open()))
    assert list(train_rows[0]) == ["timesteps", "episode", "return", "success"]
    assert (out / "learning_curve.png").stat().st_size > 10_000

    off = tmp_path / "off"
    args = [*base, "--out", str(off), "--config", str(cfg), "--eval-every", "0"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert not (off / "evaluations.csv").exists()
    assert (off / "learning_curve.png").is_file()


def test_the_plot_shows_the_evaluations_and_a_success_panel_only_when_reported() -> None:
    rows = [
        {"timesteps": t, "mean_return": m, "return_low": m - 1, "return_high": m + 1,
         "success": s, "episodes": 4}
        for t, m, s in [(250, -50.0, 0.0), (500, 120.0, 1.0)]
    ]  # fmt: skip
    fig = plot_training_with_evaluations([250, 500], [-150.0, -20.0], rows, ENV)
    returns, success = fig.axes
    lines = {line.get_label(): line for line in returns.get_lines()}
    np.testing.assert_array_equal(lines["greedy evaluation (4 episodes)"].get_ydata(), [-50, 120])
    np.testing.assert_array_equal(lines["training episodes (exploring)"].get_ydata(), [-150, -20])
    np.testing.assert_array_equal(success.get_lines()[0].get_ydata(), [0.0, 1.0])
    for r in rows:
        r["success"] = float("nan")
    assert len(plot_training_with_evaluations([250], [-1.0], rows, "x").axes) == 1
