"""Hostile use of the CLI (issue 32, classes 5, 6, 8-10): usage errors exit 2 before any
work in every command, a failure is one line and never a traceback, warnings are one line,
and an earlier run is never replaced or mixed without ``--overwrite``."""

from __future__ import annotations

import json
import os
import sys
import types
import warnings
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from tests._fuzz import fuzz_settings
from typer.testing import CliRunner

from geoq.cli import app

RUNNER = CliRunner()
WIDE = {"COLUMNS": "200", "NO_COLOR": "1"}


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Stand-ins for the library calls of train, bench-control and suite that record them."""
    made: list[str] = []
    import geoq.experiments.control.benchmark as control
    import geoq.experiments.control.training as training

    monkeypatch.setattr(training, "train", lambda *a, **k: made.append("train") or _Agent())
    monkeypatch.setattr(control, "run_control_benchmark", lambda *a, **k: made.append("bench"))
    suite = types.ModuleType("geoq.experiments.suite.run")
    suite.run_suite = lambda *a, **k: made.append("suite") or Path("SUITE.md")  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "geoq.experiments.suite.run", suite)
    return made


class _Agent:
    episodes = ()
    num_timesteps = 0


def _run(*args: str) -> Any:
    return RUNNER.invoke(app, list(args), env=WIDE)


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["train", "--env", "Nope-v0"], "'--env'"),
        (["train", "--env", "CartPole-v1"], "'--env'"),
        (["bench-control", "--env", "Nope-v0"], "'--env'"),
        (["bench-control", "--backend", "dask", "--scheduler", ""], "'--scheduler'"),
        (["suite", "--backend", "dask", "--scheduler", ""], "'--scheduler'"),
        (["reproduce", "--backend", "dask", "--scheduler", ""], "'--scheduler'"),
        (["suite", "--scheduler", "tcp://x:1"], "'--scheduler'"),
    ],
)
def test_usage_errors_exit_2_in_every_command(
    tmp_path: Path, calls: list[str], args: list[str], option: str
) -> None:
    result = _run(*args, "--out", str(tmp_path / "o"), "--no-progress")
    assert result.exit_code == 2, result.output
    assert option in result.output and "Traceback" not in result.output
    assert calls == []


@pytest.mark.parametrize("command", ["train", "bench-control", "suite", "reproduce"])
def test_an_out_that_cannot_be_made_or_is_empty_is_a_usage_error(
    tmp_path: Path, calls: list[str], command: str
) -> None:
    (tmp_path / "file").write_text("x")
    for out in ("", str(tmp_path / "file" / "sub")):
        result = _run(command, "--out", out, "--no-progress")
        assert result.exit_code == 2 and "'--out'" in result.output, result.output
    assert calls == []


@pytest.mark.parametrize(
    ("config", "match"),
    [
        ('{"lengthscale": [0.1, 0.2, 0.3, 0.4, 0.5]}', "lengthscale has 5 entries"),
        ('{"hyperparameters": "evidence"}', "needs kernel='euclidean'"),  # with --kernel nearest
        ('{"seed": 3}', "unknown GPQConfig"),
        ("[" * 50_000 + "]" * 50_000, "nested too deeply"),
        ('{"beta": 1e308}', "beta"),
        ('{"lengthscale": "0.3"}', "lengthscale"),
    ],
)
def test_the_config_is_checked_by_the_agent_itself(
    tmp_path: Path, calls: list[str], config: str, match: str
) -> None:
    path = tmp_path / "c.json"
    path.write_text(config)
    for command in ("train", "bench-control"):
        result = _run(command, "--out", str(tmp_path / "o"), "--kernel", "nearest", "--config",
                      str(path), "--no-progress")  # fmt: skip
        assert result.exit_code == 2, result.output
        assert "'--config'" in result.output and match in result.output
        assert "Traceback" not in result.output
    assert calls == []


@pytest.mark.parametrize(
    ("max_bv", "reason"),
    [
        ('"10"', "got '10': not a number (a string; write 10 without quotes)"),
        ("true", "got True: a bool, not an integer"),
        ("20.0", "got 20.0: not an integer (a float; write 20)"),
        ("0", "got 0: below 1 (a GP needs at least one basis vector)"),
        ("6000", "got 6000: above 5000 (a GP of more basis vectors needs gigabytes)"),
    ],
)
def test_a_bad_max_bv_in_the_config_says_what_is_wrong_with_it(
    tmp_path: Path, calls: list[str], max_bv: str, reason: str
) -> None:
    """B13: the budget's own reason, the gigabytes note only for an integer above 5000."""
    path = tmp_path / "c.json"
    path.write_text(f'{{"max_bv": {max_bv}}}')
    for command in ("train", "bench-control"):
        result = _run(command, "--out", str(tmp_path / "o"), "--config", str(path),
                      "--no-progress")  # fmt: skip
        assert result.exit_code == 2, result.output
        assert "'--config'" in result.output and "Traceback" not in result.output
        text = " ".join(result.output.split())
        assert f"max_bv must be an integer in [1, 5000], {reason}" in text, text
        assert ("gigabytes" in text) == (max_bv == "6000")
    assert calls == []


OPTIONS = st.lists(
    st.one_of(
        st.tuples(st.just("--env"), st.sampled_from(["geoq/TwoRooms-v0", "Nope", "", "CartPole-v1",
                                                     "MountainCarContinuous-v0"])),
        st.tuples(st.just("--kernel"), st.sampled_from(["nearest", "rbf", "", "EUCLIDEAN"])),
        st.tuples(st.just("--seed"), st.sampled_from(["0", "-1", "1.5", "x", "99999999999"])),
        st.tuples(st.just("--timesteps"), st.sampled_from(["1", "0", "-5", "1e3"])),
        st.tuples(st.just("--eval-every"), st.sampled_from(["0", "-1", "10"])),
        st.tuples(st.just("--config"), st.sampled_from(['{"gamma": 2}', '{"max_bv": 20}', "[]",
                                                        '{"gamma": true}', "{", '{"noise": 1}'])),
    ),
    max_size=4,
)  # fmt: skip


@fuzz_settings(40)
@given(options=OPTIONS)
def test_train_options_are_a_usage_error_or_reach_the_library(
    options: list[tuple[str, str]], tmp_path_factory: pytest.TempPathFactory
) -> None:
    tmp = tmp_path_factory.mktemp("cli")
    args = ["train", "--out", str(tmp / "o"), "--no-progress"]
    for name, value in options:
        if name == "--config":
            (tmp / "c.json").write_text(value)
            value = str(tmp / "c.json")
        args += [name, value]
    made: list[str] = []
    import geoq.experiments.control.training as training

    original = training.train
    training.train = lambda *a, **k: made.append("train") or _Agent()  # type: ignore[assignment]
    try:
        result = _run(*args)
    finally:
        training.train = original
    assert "Traceback" not in result.output
    assert result.exit_code in (0, 2), result.output
    assert (result.exit_code == 0) == (made == ["train"]), result.output


def test_train_refuses_an_earlier_run_and_overwrite_replaces_it_whole(tmp_path: Path) -> None:
    out, cfg = tmp_path / "run", tmp_path / "c.json"
    cfg.write_text('{"max_bv": 10, "n_candidates": 5}')
    base = ["train", "--env", "geoq/TwoRooms-v0", "--timesteps", "30", "--out", str(out),
            "--config", str(cfg), "--no-progress"]  # fmt: skip
    assert _run(*base, "--eval-every", "20", "--eval-episodes", "1").exit_code == 0
    assert (out / "evaluations.csv").exists()
    first = (out / "agent.npz").read_bytes()
    result = _run(*base, "--seed", "1", "--eval-every", "0")
    assert (
        result.exit_code == 2 and "earlier run" in result.output and "--overwrite" in result.output
    )
    assert (out / "agent.npz").read_bytes() == first  # untouched
    result = _run(*base, "--seed", "1", "--eval-every", "0", "--overwrite")
    assert result.exit_code == 0, result.output
    assert not (out / "evaluations.csv").exists()  # the old run's file: not mixed in
    assert json.loads((out / "config.json").read_text())["seed"] == 1
    from geoq.experiments.control.training import TRAIN_FILES

    names = {p.name for p in out.iterdir()}
    assert names <= set(TRAIN_FILES) - {"evaluations.csv"}  # nothing else, nothing hidden
    assert {"agent.npz", "config.json", "learning_curve.csv", "learning_curve.png"} <= names


def test_a_benchmark_of_other_settings_is_refused_without_overwrite(tmp_path: Path) -> None:
    from geoq.experiments.control.benchmark import check_benchmark_dir

    out = tmp_path / "b"
    out.mkdir()
    (out / "benchmark.json").write_text(json.dumps({"settings": {"seeds": 2, "env": "E"}}))
    check_benchmark_dir(out, {"seeds": 2, "env": "E"}, overwrite=False)  # the same: resumes
    with pytest.raises(FileExistsError, match=r"other settings \(seeds\)"):
        check_benchmark_dir(out, {"seeds": 3, "env": "E"}, overwrite=False)
    check_benchmark_dir(out, {"seeds": 3, "env": "E"}, overwrite=True)
    result = _run("bench-control", "--out", str(out), "--env", "E", "--no-progress")
    assert result.exit_code == 2  # the env first: nothing ran


def test_warnings_are_one_line(
    tmp_path: Path, calls: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import geoq.experiments.control.training as training

    def warn(*a: Any, **k: Any) -> Any:
        warnings.warn("first line\nsecond line", UserWarning, stacklevel=1)
        return _Agent()

    monkeypatch.setattr(training, "train", warn)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        result = _run("train", "--out", str(tmp_path / "o"), "--no-progress")
    assert result.exit_code == 0, result.output
    lines = [ln for ln in result.stderr.splitlines() if "warning" in ln]
    assert lines == ["geoq train: warning: UserWarning: first line second line"]


def test_evaluate_names_its_env_option_and_refuses_a_non_agent_file(tmp_path: Path) -> None:
    from tests.agents._tasks import PointToGoal

    from geoq.agents import GPQAgent

    path = tmp_path / "agent.npz"
    GPQAgent(PointToGoal(), max_bv=10, seed=0).learn(5).save(path)  # no registered id
    result = _run("evaluate", str(path), "--episodes", "1")
    assert result.exit_code == 2 and "pass --env ID" in result.output
    assert "env_id=" not in result.output
    result = _run("evaluate", str(path), "--env", "geoq/TwoRooms-v0")  # other spaces
    assert result.exit_code == 2 and "'--env'" in result.output
    (tmp_path / "junk.npz").write_text("junk")
    result = _run("evaluate", str(tmp_path / "junk.npz"))
    assert result.exit_code == 2 and "'AGENT'" in result.output


def test_the_console_script_never_prints_a_traceback(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import geoq.cli as cli

    def boom() -> None:
        raise RuntimeError("a bug\nsomewhere")

    monkeypatch.setattr(cli, "app", boom)
    with pytest.raises(SystemExit) as exit_info:
        cli.main()
    assert exit_info.value.code == 1
    assert capsys.readouterr().err == "geoq: internal error: RuntimeError: a bug somewhere\n"


# Unwritable output places (B14): every option that writes (--out of every command,
# evaluate's --video) is tried for real before any work, so that /proc, /sys or a file
# where a directory should be is a usage error at once, not a failure after the run.
# chmod would not make an unwritable place here: the tests may run as root.
PSEUDO = [d for d in ("/proc", "/proc/self", "/sys", "/sys/kernel") if Path(d).is_dir()]
OUT_COMMANDS = ("train", "bench-control", "control-suite", "suite", "reproduce")
_SAVED: dict[str, Path] = {}


def _saved_agent(factory: pytest.TempPathFactory) -> Path:
    if "agent" not in _SAVED:
        from geoq.agents import GPQAgent

        path = factory.mktemp("agent") / "agent.npz"
        GPQAgent("geoq/TwoRooms-v0", max_bv=10, n_candidates=5, seed=0).learn(5).save(path)
        _SAVED["agent"] = path
    return _SAVED["agent"]


def _stub_work(mp: pytest.MonkeyPatch, made: list[str]) -> None:
    """Every command's work replaced by a recorder (nothing runs, nothing is written)."""
    import geoq.experiments.control.benchmark as control
    import geoq.experiments.control.suite as control_suite
    import geoq.experiments.control.training as training
    import geoq.experiments.control.video as video
    import geoq.experiments.paper.reproduce as reproduce

    mp.setattr(training, "train", lambda *a, **k: made.append("work") or _Agent())
    mp.setattr(control, "run_control_benchmark", lambda *a, **k: made.append("work"))
    mp.setattr(control_suite, "run_control_suite", lambda *a, **k: made.append("work"))
    mp.setattr(reproduce, "reproduce", lambda *a, **k: made.append("work"))
    suite = types.ModuleType("geoq.experiments.suite.run")
    suite.run_suite = lambda *a, **k: made.append("work") or Path("SUITE.md")  # type: ignore[attr-defined]
    mp.setitem(sys.modules, "geoq.experiments.suite.run", suite)
    result = types.SimpleNamespace(summary=lambda: "summary")
    mp.setattr(control, "evaluate_agent", lambda *a, **k: made.append("work") or result)
    episode = types.SimpleNamespace(frames=[0], fps=1.0, ret=0.0)
    mp.setattr(video, "record_episode", lambda *a, **k: episode)
    mp.setattr(video, "write_gif", lambda *a, **k: None)


def _writable(directory: Path, make: bool) -> bool:
    """The oracle: a file can be made in ``directory`` (made first if ``make``)."""
    if not make and not directory.is_dir():
        return False
    try:
        os.makedirs(directory, exist_ok=True)
        with open(directory / "oracle.txt", "x") as fh:
            fh.write("x")
    except OSError:
        return False
    return True


@fuzz_settings(40)
@given(
    command=st.sampled_from([*OUT_COMMANDS, "evaluate"]),
    place=st.sampled_from(["new", "existing", "file", "file/sub", *PSEUDO]),
    sub=st.sampled_from(["", "geoq-run"]),
)
def test_every_output_is_tried_before_any_work(
    tmp_path_factory: pytest.TempPathFactory, command: str, place: str, sub: str
) -> None:
    """Exit 2 naming the option and the path, nothing run, exactly where no file can be
    made; else the command's work runs."""
    tmp = tmp_path_factory.mktemp("cli-out")
    (tmp / "existing").mkdir()
    (tmp / "file").write_text("x")
    where = (Path(place) if place in PSEUDO else tmp / place) / sub
    if command == "evaluate":
        option, target, directory = "--video", where / "v.gif", where
        args = ["evaluate", str(_saved_agent(tmp_path_factory)), "--video", str(target)]
    else:
        option, target, directory = "--out", where, where
        args = [command, "--out", str(target), "--no-progress"]
    made: list[str] = []
    with pytest.MonkeyPatch.context() as mp:
        _stub_work(mp, made)
        result = _run(*args)
    assert "Traceback" not in result.output
    if _writable(directory, make=command != "evaluate"):
        assert result.exit_code == 0 and made == ["work"], result.output
    else:
        text = " ".join(result.output.split())
        assert result.exit_code == 2 and made == [], result.output
        assert f"'{option}'" in text and str(target).rstrip("/") in text, text


@pytest.mark.skipif(not PSEUDO, reason="no /proc or /sys here")
@pytest.mark.parametrize("command", [*OUT_COMMANDS, "evaluate"])
def test_proc_and_sys_are_usage_errors_that_say_what_to_do(tmp_path: Path, command: str) -> None:
    made: list[str] = []
    junk = tmp_path / "agent.npz"
    junk.write_text("junk")  # --video is checked before the agent is even read
    with pytest.MonkeyPatch.context() as mp:
        _stub_work(mp, made)
        for place in PSEUDO:
            if command == "evaluate":
                target, option = f"{place}/geoq.gif", "'--video'"
                result = _run("evaluate", str(junk), "--video", target)
            else:
                target, option = f"{place}/geoq-run", "'--out'"
                result = _run(command, "--out", target, "--no-progress")
            text = " ".join(result.output.split())
            assert result.exit_code == 2 and option in text, text
            assert f"cannot create files in {place}" in text and f"so {target} cannot" in text
            assert "writable filesystem" in text and ".tmp" not in text
    assert made == []
