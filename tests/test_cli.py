"""Tests of the ``geoq`` command line plumbing: help, validation, exit codes, options -> call.

The end-to-end ``geoq reproduce`` run (files, columns, figures) is tested with
the experiments; here a *recording stand-in* replaces
``geoq.experiments.paper.reproduce`` so that the tests check what the CLI passes to
the library and how it reports failures, independently of the science.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import types
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

import geoq
from geoq.cli import app

RUNNER = CliRunner()
WIDE = {"COLUMNS": "200", "NO_COLOR": "1"}  # rich wraps help to the terminal width


def _invoke(*args: str) -> Any:
    return RUNNER.invoke(app, list(args), env=WIDE)


@pytest.fixture
def recorded(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """A stand-in ``geoq.experiments.paper.reproduce`` that records its keyword arguments."""
    calls: list[dict[str, Any]] = []

    def reproduce(**kwargs: Any) -> None:
        calls.append(kwargs)
        if kwargs["out"].name == "boom":
            raise RuntimeError("cell 3 failed:\nsingular matrix")
        if kwargs["out"].name == "ctrl-c":
            raise KeyboardInterrupt
        if kwargs["out"].name == "killed":  # what SIGTERM would run, without killing pytest
            handler = signal.getsignal(signal.SIGTERM)
            assert callable(handler), "no SIGTERM handler while the command runs"
            handler(signal.SIGTERM, None)

    module = types.ModuleType("geoq.experiments.paper.reproduce")
    module.reproduce = reproduce  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "geoq.experiments.paper.reproduce", module)
    return calls


def test_help_lists_the_commands() -> None:
    result = _invoke("--help")
    assert result.exit_code == 0, result.output
    for command in ("reproduce", "version", "info"):
        assert command in result.output


def test_no_arguments_shows_help() -> None:
    result = _invoke()
    assert "reproduce" in result.output and "Usage" in result.output


def test_reproduce_help_explains_every_option() -> None:
    result = _invoke("reproduce", "--help")
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    for option in (
        "--out",
        "--scale",
        "quick|paper",
        "--jobs",
        "--backend",
        "loky|dask",
        "--scheduler",
        "ADDRESS",
        "--seed",
        "ROOT_SEED",
        "--no-progress",
    ):
        assert option in text, option
    for phrase in ("resumes", "SeedSequence", "geoq[dask]", "fig3.csv", "REPORT.md"):
        assert phrase in text, phrase


def test_version_command_and_flag_print_the_package_version() -> None:
    assert _invoke("version").output.strip() == geoq.__version__
    assert _invoke("--version").output.strip() == f"geoq {geoq.__version__}"


def test_info_lists_kernels() -> None:
    result = _invoke("info")
    assert result.exit_code == 0, result.output
    assert "kernels:" in result.output and "SquaredExponential" in result.output
    assert "environments:" in result.output


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--scale", "huge"], "'--scale'"),
        (["--jobs", "0"], "'--jobs'"),
        (["--jobs", "two"], "'--jobs'"),
        (["--backend", "ray"], "'--backend'"),
        (["--scheduler", "tcp://127.0.0.1:8786"], "'--scheduler'"),  # without --backend dask
        (["--backend", "dask", "--scheduler", " "], "'--scheduler'"),
        (["--seed", "-1"], "'--seed'"),
    ],
)
def test_bad_options_are_usage_errors(
    tmp_path: Path, recorded: list[dict[str, Any]], args: list[str], option: str
) -> None:
    result = _invoke("reproduce", "--out", str(tmp_path / "out"), *args)
    assert result.exit_code == 2, result.output
    assert option in result.output
    assert recorded == []  # the library is never called with bad options


def test_missing_out_and_out_that_is_a_file_are_usage_errors(
    tmp_path: Path, recorded: list[dict[str, Any]]
) -> None:
    assert _invoke("reproduce").exit_code == 2
    a_file = tmp_path / "file.txt"
    a_file.write_text("x")
    result = _invoke("reproduce", "--out", str(a_file))
    assert result.exit_code == 2 and "'--out'" in result.output
    assert recorded == []


def test_options_reach_the_library_call(tmp_path: Path, recorded: list[dict[str, Any]]) -> None:
    out = tmp_path / "out"
    result = _invoke("reproduce", "--out", str(out))
    assert result.exit_code == 0, result.output
    assert recorded[-1] == {
        "out": out,
        "scale": "quick",
        "jobs": 1,
        "backend": "loky",
        "scheduler": None,
        "progress": True,
    }  # no root_seed: the preset's own default applies
    result = _invoke(
        "reproduce",
        "--out",
        str(out),
        "--scale",
        "PAPER",
        "-j",
        "2",
        "--backend",
        "dask",
        "--scheduler",
        "tcp://127.0.0.1:8786",
        "--seed",
        "7",
        "--no-progress",
    )
    assert result.exit_code == 0, result.output
    assert recorded[-1] == {
        "out": out,
        "scale": "paper",
        "jobs": 2,
        "backend": "dask",
        "scheduler": "tcp://127.0.0.1:8786",
        "progress": False,
        "root_seed": 7,
    }


def test_failure_is_exit_1_with_one_line(tmp_path: Path, recorded: list[dict[str, Any]]) -> None:
    result = _invoke("reproduce", "--out", str(tmp_path / "boom"))
    assert result.exit_code == 1
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert lines == ["geoq reproduce: error: RuntimeError: cell 3 failed: singular matrix"]


@pytest.mark.parametrize(("name", "code"), [("ctrl-c", 130), ("killed", 143)])
def test_ctrl_c_and_sigterm_are_reported_interruptions(
    tmp_path: Path, recorded: list[dict[str, Any]], name: str, code: int
) -> None:
    """SIGTERM (a scheduler's time limit) is handled like Ctrl-C, and the process's own
    SIGTERM handler is back afterwards."""
    before = signal.getsignal(signal.SIGTERM)
    result = _invoke("reproduce", "--out", str(tmp_path / name))
    assert result.exit_code == code
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert lines == [
        "geoq reproduce: interrupted; finished cells are kept, rerun the same command to resume"
    ]
    assert signal.getsignal(signal.SIGTERM) is before


def _loky_workers(pid: int) -> set[int]:
    """Live loky worker processes whose parent is ``pid`` (Linux ``/proc``)."""
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            cmdline = (stat.parent / "cmdline").read_bytes()
        except OSError:  # exited meanwhile
            continue
        if int(fields[1]) == pid and fields[0] != "Z" and b"popen_loky" in cmdline:
            out.add(int(stat.parent.name))
    return out


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="-j 2 is capped to one job on one core")
def test_sigterm_stops_the_parallel_workers_too(tmp_path: Path) -> None:
    """Killed by SIGTERM, ``bench-control -j 2`` exits 143 and takes its loky workers
    with it (with SIGTERM's default action they ran on, orphaned, to the end of
    their cells)."""
    exe = Path(sys.executable).with_name("geoq")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "geoq.cli"]
    args = ["bench-control", "--out", str(tmp_path / "run"), "--seeds", "4", "--timesteps",
            "3000", "--eval-every", "1000", "--eval-episodes", "1", "-j", "2",
            "--no-progress"]  # fmt: skip
    proc = subprocess.Popen([*cmd, *args], stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while len(workers := _loky_workers(proc.pid)) < 2 and time.monotonic() < deadline:
            time.sleep(0.2)
        assert len(workers) >= 2, "the workers never started"
        time.sleep(1.0)  # let them pick up cells
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    assert "geoq bench-control: interrupted; finished cells are kept; rerun to resume" in err
    deadline = time.monotonic() + 20
    while (alive := [w for w in workers if Path(f"/proc/{w}").exists()]) and (
        time.monotonic() < deadline
    ):
        time.sleep(0.2)
    assert not alive, f"workers {alive} outlived the command"


def test_console_script_entry_point() -> None:
    exe = Path(sys.executable).with_name("geoq")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "geoq.cli"]
    proc = subprocess.run([*cmd, "--help"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "reproduce" in proc.stdout


# -- issue 12, class 5: the whole --config is checked up front; --out "" is refused ---------
@pytest.mark.parametrize(
    ("config", "field"),
    [
        ('{"budgets": 5}', "budgets"),
        ('{"learner": null}', "learner"),
        ('{"learner": {"noize": 0.1}}', "noize"),
        ('{"learner": {"noise": "0.1"}}', "learner.noise"),
        ('{"learner": {"noise": -1}}', "learner.noise"),
        ('{"learner": {"eps": 1.5}}', "learner.eps"),
        ('{"learner": {"scaling": {"scale": [1]}}}', "learner.scaling"),
        ('{"learner": {"lengthscale": [1, 2]}}', "learner.lengthscale"),
        ('{"learner": {"kernel": "resistance"}}', "learner.kernel"),
        ('{"learner": {"max_bv": 30}}', "learner.max_bv"),
        ('{"budgets": [5, 7.5]}', "budgets[1]"),
        ('{"budgets": [5, 5]}', "budgets"),
        ('{"budgets": [5, 100000]}', "budgets[1]"),
        ('{"seeds": "3"}', "seeds"),
        ('{"seeds": true}', "seeds"),
        ('{"seeds": 1e400}', "seeds"),
        ('{"seeds": 1000000000000000000000000000000}', "seeds"),
        ('{"gamma": NaN}', "gamma"),
        ('{"gamma": "0.9"}', "gamma"),
        ('{"root_seed": -1}', "root_seed"),
        ('{"graph_eps": [0.3, "a"]}', "graph_eps[1]"),
        ('{"kernels": ["euclidean", "nearest", "nearest"]}', "kernels"),
        ('{"variants": "faithful"}', "variants"),
        ('{"eval_pairs": 100000}', "eval_pairs"),
        ('{"scale": "paper"}', "scale"),
        ("[1, 2]", "JSON object"),
        ('{"seeds": ', "JSONDecodeError"),
    ],
)
def test_every_config_field_is_checked_up_front(
    tmp_path: Path, recorded: list[dict[str, Any]], config: str, field: str
) -> None:
    path = tmp_path / "c.json"
    path.write_text(config)
    result = _invoke("reproduce", "--out", str(tmp_path / "o"), "--config", str(path))
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [ln for ln in result.output.splitlines() if "Invalid value for '--config'" in ln]
    assert len(lines) == 1 and field in lines[0], result.output
    assert recorded == []  # nothing ran


def test_a_config_naming_the_scale_it_runs_is_fine(
    tmp_path: Path, recorded: list[dict[str, Any]]
) -> None:
    path = tmp_path / "c.json"
    path.write_text('{"scale": "paper", "seeds": 2}')
    result = _invoke("reproduce", "--out", str(tmp_path / "o"), "--scale", "paper", "--config",
                     str(path))  # fmt: skip
    assert result.exit_code == 0, result.output
    assert recorded[0]["config"].scale == "paper" and recorded[0]["config"].seeds == 2


@pytest.mark.parametrize("command", ["reproduce", "train", "bench-control"])
def test_an_empty_out_is_refused(command: str, recorded: list[dict[str, Any]]) -> None:
    result = _invoke(command, "--out", "")
    assert result.exit_code == 2 and "'--out'" in result.output
    assert recorded == []


def test_jobs_above_the_core_count_are_capped_with_a_warning(
    tmp_path: Path, recorded: list[dict[str, Any]], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    result = _invoke("reproduce", "--out", str(tmp_path / "o"), "--jobs", "64")
    assert result.exit_code == 0, result.output
    assert recorded[0]["jobs"] == 2
    assert "warning: --jobs=64 is more than the 2 core(s)" in result.output
    result = _invoke("reproduce", "--out", str(tmp_path / "o"), "--jobs", "2")
    assert recorded[1]["jobs"] == 2 and "warning" not in result.output


def test_a_custom_scale_label_is_kept_but_another_preset_name_is_refused() -> None:
    from geoq.experiments.paper.config import config_for_scale, config_with_overrides

    base = config_for_scale("quick")
    assert config_with_overrides(base, {"scale": "tiny", "seeds": 1}).scale == "tiny"
    assert config_with_overrides(base, {"scale": "quick"}).scale == "quick"
    with pytest.raises(ValueError, match="differs from the preset"):
        config_with_overrides(base, {"scale": "paper"})
