"""An env of the user's own, named as ``gymnasium.make`` names it: ``"module:Id"``, the
module imported first so that it registers ``Id`` (:func:`geoq.agents._env.is_registered`),
in the agent, the CLI and a parallel sweep's workers."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium
import pytest
from typer.testing import CliRunner

from geoq.agents import GPQAgent
from geoq.agents._env import is_registered
from geoq.cli import app

TASKS = """
import gymnasium
if "{id}" not in gymnasium.registry:
    gymnasium.register(id="{id}", entry_point="geoq.envs.swing_up:PendulumSwingUpEnv",
                       max_episode_steps=10)
"""


def _module(tmp_path: Path, name: str, env_id: str, body: str = TASKS) -> None:
    (tmp_path / f"{name}.py").write_text(body.format(id=env_id))


def test_a_module_prefix_is_imported_and_registers_its_env(tmp_path, monkeypatch) -> None:
    _module(tmp_path, "geoq_user_tasks_a", "geoquser/SwingA-v0")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert "geoquser/SwingA-v0" not in gymnasium.registry
    assert not is_registered("geoquser/SwingA-v0")  # not imported yet: unknown
    assert is_registered("geoq_user_tasks_a:geoquser/SwingA-v0")
    assert is_registered("geoquser/SwingA-v0")  # the import registered it
    agent = GPQAgent("geoq_user_tasks_a:geoquser/SwingA-v0", max_bv=10, seed=0).learn(12)
    assert agent.env_id == "geoquser/SwingA-v0" and agent.num_timesteps == 12


def test_a_module_that_cannot_be_found_is_not_registered_and_other_errors_say_so(
    tmp_path, monkeypatch
) -> None:
    assert not is_registered("geoq_no_such_module:Swing-v0")
    with pytest.raises(ValueError, match="'module:Id'"):
        GPQAgent("geoq_no_such_module:Swing-v0")
    _module(tmp_path, "geoq_user_tasks_broken", "x", body="raise RuntimeError('broken {id}')")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(RuntimeError, match="broken x"):  # the module's own error, not hidden
        is_registered("geoq_user_tasks_broken:X-v0")
    _module(tmp_path, "geoq_user_tasks_needs", "x", body="import geoq_no_such_dependency  # {id}")
    with pytest.raises(ModuleNotFoundError, match="geoq_no_such_dependency"):
        is_registered("geoq_user_tasks_needs:X-v0")  # its own missing import, said
    _module(tmp_path, "geoq_user_tasks_empty", "x", body="# registers nothing {id}")
    assert not is_registered("geoq_user_tasks_empty:geoquser/Missing-v0")
    for env_id, said in [("geoq_user_tasks_broken:X-v0", "broken x"),
                         ("geoq_no_such_module:X-v0", "'module:Id'")]:  # fmt: skip
        result = CliRunner().invoke(app, ["train", "--env", env_id, "--out", str(tmp_path / "o")])
        assert result.exit_code == 2 and said in result.output, result.output
        assert "'--env'" in result.output and "Traceback" not in result.output


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="-j 2 is capped to one job on one core")
def test_bench_control_runs_a_user_env_in_its_parallel_workers(tmp_path: Path) -> None:
    """A fresh ``geoq`` process and its loky workers each import the module; without the
    prefix the id is unknown there, and the usage error says how to name it."""
    _module(tmp_path, "geoq_user_tasks_b", "geoquser/SwingB-v0")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    exe = Path(sys.executable).with_name("geoq")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "geoq.cli"]
    args = ["bench-control", "--seeds", "2", "--timesteps", "20", "--eval-every", "10",
            "--eval-episodes", "1", "-j", "2", "--no-progress", "--config",
            str(tmp_path / "config.json")]  # fmt: skip
    (tmp_path / "config.json").write_text('{"max_bv": 10}')
    unknown = subprocess.run([*cmd, *args, "--env", "geoquser/SwingB-v0", "--out",
                              str(tmp_path / "no")], env=env, capture_output=True,
                             text=True, timeout=120)  # fmt: skip
    assert unknown.returncode == 2 and "'module:Id'" in unknown.stderr, unknown.stderr
    done = subprocess.run([*cmd, *args, "--env", "geoq_user_tasks_b:geoquser/SwingB-v0", "--out",
                           str(tmp_path / "run")], env=env, capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert len(list((tmp_path / "run" / "cells").glob("*.json"))) == 2
