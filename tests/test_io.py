"""Atomic writes and archives: file modes follow the umask; wrong files get ArchiveError."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from geoq._io import ArchiveError, atomic_write_text, load_archive, save_archive
from geoq.gp import SparseOnlineGP
from geoq.kernels import SquaredExponential


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_written_files_respect_the_umask(umask: int, tmp_path: Path) -> None:
    old = os.umask(umask)
    try:
        text = atomic_write_text(tmp_path / "a.txt", "x")
        archive = save_archive(tmp_path / "a.npz", "K", 1, {"v": np.arange(3)})
        gp = SparseOnlineGP(SquaredExponential(0.5), noise=0.1, max_bv=5)
        gp.fit(np.arange(6.0)[:, None], np.ones(6))
        gp.save(tmp_path / "gp.npz")
        with open(tmp_path / "plain.txt", "w") as fh:  # what open() gives: the oracle
            fh.write("x")
    finally:
        os.umask(old)
    expected = stat.S_IMODE((tmp_path / "plain.txt").stat().st_mode)
    assert expected == 0o666 & ~umask
    for path in (text, archive, tmp_path / "gp.npz"):
        assert stat.S_IMODE(path.stat().st_mode) == expected, path


def test_loading_a_directory_or_a_npy_file_says_what_it_is(tmp_path: Path) -> None:
    with pytest.raises(ArchiveError, match="directory"):
        load_archive(tmp_path, "K", 1)
    with pytest.raises(ArchiveError, match="directory"):
        SparseOnlineGP.load(tmp_path)
    np.save(tmp_path / "x.npy", np.arange(4))
    with pytest.raises(ArchiveError, match=r"\.npy array, not a \.npz archive"):
        SparseOnlineGP.load(tmp_path / "x.npy")
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(ArchiveError, match="truncated or corrupt, or not a saved model"):
        load_archive(tmp_path / "notes.txt", "K", 1)
    with pytest.raises(ArchiveError, match="no such file"):
        load_archive(tmp_path / "missing.npz", "K", 1)


def test_writing_onto_a_directory_is_refused(tmp_path: Path) -> None:
    (tmp_path / "d").mkdir()
    with pytest.raises(IsADirectoryError):
        atomic_write_text(tmp_path / "d", "x")
