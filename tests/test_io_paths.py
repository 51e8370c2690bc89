"""Special paths and whole runs (issue 32, classes 6 and 7): a write follows symbolic links,
never replaces a FIFO, a device or a directory, keeps an existing file's mode; a run of
several files replaces an earlier one only with ``overwrite`` and never mixes two."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from tests._fuzz import fuzz_settings

from geoq._io import (
    ArchiveError,
    atomic_write_text,
    check_run_dir,
    load_archive,
    output_path,
    save_archive,
    staged_run,
)

RUN = ("a.txt", "b.txt", "c.txt")


def test_a_symlink_is_written_through_and_stays_a_link(tmp_path: Path) -> None:
    target = tmp_path / "real.txt"
    target.write_text("old")
    link = tmp_path / "link.txt"
    link.symlink_to(target)
    atomic_write_text(link, "new")
    assert link.is_symlink() and target.read_text() == "new"
    dangling = tmp_path / "dangling.txt"
    dangling.symlink_to(tmp_path / "later.txt")
    atomic_write_text(dangling, "x")
    assert dangling.is_symlink() and (tmp_path / "later.txt").read_text() == "x"
    chain = tmp_path / "chain.txt"
    chain.symlink_to(link)  # a link to a link
    atomic_write_text(chain, "chained")
    assert target.read_text() == "chained" and chain.is_symlink() and link.is_symlink()


def test_a_loop_of_links_a_fifo_and_a_device_are_never_replaced(tmp_path: Path) -> None:
    loop = tmp_path / "loop"
    loop.symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(loop)
    with pytest.raises(FileExistsError, match="loop of symbolic links"):
        atomic_write_text(loop, "x")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(FileExistsError, match="FIFO, not a regular file"):
        atomic_write_text(fifo, "x")  # never opened: a FIFO would block
    assert stat.S_ISFIFO(fifo.stat().st_mode)
    with pytest.raises(FileExistsError, match="FIFO"):
        save_archive(fifo, "K", 1, {"v": [1]})
    with pytest.raises(ArchiveError, match="not a regular file"):
        load_archive(fifo, "K", 1)  # not opened either
    if Path("/dev/null").exists():
        with pytest.raises(FileExistsError, match="device"):
            output_path("/dev/null")
    link = tmp_path / "to-fifo"
    link.symlink_to(fifo)
    with pytest.raises(FileExistsError, match="FIFO"):
        atomic_write_text(link, "x")
    assert link.is_symlink()


def test_an_existing_file_keeps_its_mode(tmp_path: Path) -> None:
    path = tmp_path / "secret.txt"
    path.write_text("old")
    path.chmod(0o600)
    atomic_write_text(path, "new")
    assert stat.S_IMODE(path.stat().st_mode) == 0o600 and path.read_text() == "new"


def _write_run(out: Path, tag: str, names: tuple[str, ...], fail_after: int | None,
               overwrite: bool) -> None:  # fmt: skip
    with staged_run(out, RUN, overwrite=overwrite) as staging:
        for i, name in enumerate(names):
            if fail_after is not None and i == fail_after:
                raise RuntimeError("disk full")
            atomic_write_text(staging / name, tag)


def test_an_earlier_run_is_replaced_only_with_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "run"
    _write_run(out, "1", RUN, None, False)
    with pytest.raises(FileExistsError, match=r"earlier run \(a.txt, b.txt, c.txt\).*overwrite"):
        _write_run(out, "2", RUN, None, False)
    with pytest.raises(FileExistsError, match="earlier run"):
        check_run_dir(out, RUN, overwrite=False)
    _write_run(out, "2", ("a.txt", "b.txt"), None, True)  # c.txt was the old run's: removed
    assert sorted(p.name for p in out.iterdir()) == ["a.txt", "b.txt"]
    assert {p.read_text() for p in out.iterdir()} == {"2"}
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError, match="not a directory"):
        check_run_dir(tmp_path / "file", RUN, overwrite=True)


def test_a_run_file_that_is_a_link_is_written_through(tmp_path: Path) -> None:
    out, elsewhere = tmp_path / "run", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (elsewhere / "a.txt").write_text("old")
    (out / "a.txt").symlink_to(elsewhere / "a.txt")
    _write_run(out, "new", RUN, None, True)
    assert (out / "a.txt").is_symlink() and (elsewhere / "a.txt").read_text() == "new"
    assert sorted(p.name for p in elsewhere.iterdir()) == ["a.txt"]  # no temporary left


@fuzz_settings(30)
@given(runs=st.lists(st.tuples(st.sets(st.sampled_from(RUN), min_size=1),
                               st.one_of(st.none(), st.integers(0, 2)), st.booleans()),
                     min_size=1, max_size=5))  # fmt: skip
def test_a_folder_never_mixes_two_runs(
    tmp_path_factory: pytest.TempPathFactory,
    runs: list[tuple[set[str], int | None, bool]],
) -> None:
    """Whatever sequence of runs, failures and refusals: the folder holds one whole run
    (every file of the last run that succeeded, nothing else) or nothing."""
    out = tmp_path_factory.mktemp("runs") / "out"
    last: tuple[str, set[str]] | None = None
    for i, (names, fail_after, overwrite) in enumerate(runs):
        ordered = tuple(sorted(names))
        try:
            _write_run(out, str(i), ordered, fail_after, overwrite)
        except (RuntimeError, FileExistsError):
            pass
        else:
            if fail_after is None or fail_after >= len(ordered):
                last = (str(i), names)
        files = sorted(p.name for p in out.iterdir()) if out.exists() else []
        if last is None:
            assert files == []
        else:
            assert files == sorted(last[1]) and {(out / f).read_text() for f in files} == {last[0]}


def test_a_run_over_a_fifo_is_refused_before_any_work(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    os.mkfifo(out / "b.txt")
    with pytest.raises(FileExistsError, match="FIFO"):
        check_run_dir(out, RUN, overwrite=True)
