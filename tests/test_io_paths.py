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
    check_output_file,
    check_run_dir,
    check_writable_dir,
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


# Unwritable places (B14): /proc and /sys take no new files, even from root (to whom
# os.access says yes); a file where a directory is expected takes none either. chmod
# would not do: the tests may run as root.
PSEUDO = [d for d in ("/proc", "/proc/self", "/sys", "/sys/kernel") if os.path.isdir(d)]
PLACES = ("dir", "file", "fifo", "dangling-link", *PSEUDO)


def _place(tmp: Path, kind: str) -> Path:
    if kind in PSEUDO:
        return Path(kind)
    path = tmp / kind
    if kind == "dir":
        path.mkdir()
    elif kind == "file":
        path.write_text("x")
    elif kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to(tmp / "nowhere")
    return path


def _really_writes(path: Path, run: bool) -> bool:
    """The oracle: what the write itself does (a run: its directory made, a file made
    in it; a file: atomic_write_text, which makes missing directories)."""
    try:
        if run:
            os.makedirs(path, exist_ok=True)
            with open(path / "a.txt", "x") as fh:
                fh.write("x")
        else:
            atomic_write_text(path, "x")
    except OSError:
        return False
    return True


@fuzz_settings(80)
@given(
    place=st.sampled_from(PLACES),
    parts=st.lists(st.sampled_from(["geoq-a", "geoq-b"]), max_size=2),
    name=st.sampled_from(["out.gif", ""]),
    run=st.booleans(),
)
def test_an_output_is_refused_up_front_exactly_when_writing_it_fails(
    tmp_path_factory: pytest.TempPathFactory, place: str, parts: list[str], name: str, run: bool
) -> None:
    """check_output_file / check_run_dir raise (before any work) iff the write itself would
    fail, whatever the place: a writable directory, a file, a FIFO or a dangling link on the
    way, /proc, /sys. No probe file is left behind."""
    tmp = tmp_path_factory.mktemp("w")
    path = _place(tmp, place).joinpath(*parts, name) if parts or name else _place(tmp, place)
    try:
        if run:
            check_run_dir(path, RUN, overwrite=True)
        else:
            check_output_file(path)
    except OSError as exc:
        refused: OSError | None = exc
    else:
        refused = None
    assert not [p for p in tmp.rglob(".geoq-write-test-*")]
    writes = _really_writes(path, run)
    assert (refused is None) == writes, (path, refused)
    if refused is not None and place in PSEUDO and not isinstance(refused, IsADirectoryError):
        assert str(path) in str(refused) and "writable filesystem" in str(refused)


@pytest.mark.skipif(not PSEUDO, reason="no /proc or /sys here")
@pytest.mark.parametrize("place", PSEUDO)
def test_pseudo_filesystems_are_refused_although_os_access_may_say_yes(place: str) -> None:
    with pytest.raises(PermissionError, match=rf"cannot create files in {place} .*/proc, /sys"):
        check_writable_dir(place)
    with pytest.raises(PermissionError, match=rf"so {place}/geoq-run/deeper cannot be written"):
        check_run_dir(Path(place) / "geoq-run" / "deeper", RUN, overwrite=False)
    with pytest.raises(PermissionError, match=rf"so {place}/x.gif cannot be written"):
        check_output_file(Path(place) / "x.gif", create=False)


def test_a_missing_directory_or_a_file_on_the_way_is_named(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError, match=r"file is not a directory, so .*file/x.gif"):
        check_output_file(tmp_path / "file" / "x.gif")
    with pytest.raises(NotADirectoryError, match=r"so .*file/a cannot be made for .*a/x.gif"):
        check_output_file(tmp_path / "file" / "a" / "x.gif")
    with pytest.raises(FileNotFoundError, match=r"directory .*/new does not exist.*create it"):
        check_output_file(tmp_path / "new" / "x.gif", create=False)
    assert check_output_file(tmp_path / "new" / "x.gif") == tmp_path / "new" / "x.gif"
    assert not (tmp_path / "new").exists()  # checked, not made
    check_writable_dir(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # the probe is gone
