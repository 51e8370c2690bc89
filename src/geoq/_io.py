"""Atomic file writes and versioned ``.npz`` archives.

A result is either entirely on disk or not at all: every write goes to a
temporary file in the destination directory, is flushed and fsync'ed, then
renamed over the target (``os.replace`` is atomic on POSIX and Windows).
"""

from __future__ import annotations

import io
import json
import os
import tempfile
import threading
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "FORMAT_KEY",
    "ArchiveError",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_text",
    "load_archive",
    "save_archive",
]

#: Name of the entry that identifies a geoq archive and its format version.
FORMAT_KEY = "__geoq_format__"


class ArchiveError(ValueError):
    """A saved file is missing, truncated, tampered with or from another version."""


_UMASK_LOCK = threading.Lock()


def _umask() -> int:
    """The process umask (read by setting and restoring it; Python has no getter)."""
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temp file + fsync + rename).

    The file gets the mode a plain ``open(path, "w")`` would give it
    (``0o666`` minus the umask), not the ``0o600`` of the temporary file.
    """
    target = Path(path)
    if target.is_dir():
        raise IsADirectoryError(f"{target} is a directory; give a file path")
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | os.PathLike[str], obj: Any) -> Path:
    """Write ``obj`` as indented, key-sorted JSON atomically."""
    return atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=True) + "\n")


def save_archive(
    path: str | os.PathLike[str], kind: str, version: int, arrays: Mapping[str, Any]
) -> Path:
    """Save ``arrays`` as a versioned ``.npz`` archive, atomically.

    Parameters
    ----------
    kind : what the archive holds, e.g. ``"SparseOnlineGP"``; checked on load.
    version : integer format version of ``kind``; a loader refuses newer ones.
    arrays : name -> array (or anything ``np.asarray`` turns into a non-object array).
    """
    header = {"kind": kind, "version": int(version)}
    payload: dict[str, np.ndarray] = {FORMAT_KEY: np.asarray(json.dumps(header))}
    for name, value in arrays.items():
        arr = np.asarray(value)
        if arr.dtype == object:
            raise TypeError(f"archive entry {name!r} has dtype object; it cannot be saved safely")
        payload[name] = arr
    buffer = io.BytesIO()
    np.savez(buffer, **payload)  # type: ignore[arg-type]
    return atomic_write_bytes(path, buffer.getvalue())


def _check_declared_sizes(p: Path) -> None:
    """ArchiveError for an entry whose ``.npy`` header declares more data than it holds.

    numpy allocates what the header declares before reading: a tampered shape would ask
    for any amount of memory (``MemoryError``). The headers are read first, without
    allocating, and each declared size is checked against the entry's size in the zip.
    """
    with zipfile.ZipFile(p) as zf:
        for info in zf.infolist():
            with zf.open(info) as fh:
                try:
                    major, _ = np.lib.format.read_magic(fh)
                    read_header = (
                        np.lib.format.read_array_header_1_0
                        if major == 1
                        else np.lib.format.read_array_header_2_0
                    )
                    shape, _, dtype = read_header(fh)
                    header_end = fh.tell()
                except (ValueError, OSError, EOFError) as exc:
                    raise ArchiveError(
                        f"{p}: entry {info.filename!r} has no valid array header ({exc}); "
                        "the file is tampered or corrupt"
                    ) from exc
            count = 1
            for n in shape:
                count *= int(n)
            declared = count * dtype.itemsize
            held = info.file_size - header_end
            if dtype.hasobject or declared > held:
                raise ArchiveError(
                    f"{p}: entry {info.filename!r} declares shape {shape} of {dtype} "
                    f"({declared} bytes) but holds {held} bytes; the file is tampered or "
                    "corrupt, save the model again"
                )


def load_archive(
    path: str | os.PathLike[str], kind: str, max_version: int
) -> tuple[int, dict[str, np.ndarray]]:
    """Load an archive written by :func:`save_archive`; return ``(version, arrays)``.

    Raises :class:`ArchiveError` with what went wrong and what to do when the
    file is missing, not a geoq archive, truncated or corrupt, of another kind,
    or written by a newer format version than this geoq understands.
    """
    p = Path(path)
    if p.is_dir():
        raise ArchiveError(f"{p} is a directory, not a saved model; give the .npz file inside it")
    if not p.is_file():
        raise ArchiveError(f"{p}: no such file")
    try:
        with open(p, "rb") as fh:
            magic = fh.read(6)
        if magic == b"\x93NUMPY":
            raise ArchiveError(
                f"{p}: a .npy array, not a .npz archive; geoq saves models as .npz with save()"
            )
        if magic[:2] != b"PK":
            raise ArchiveError(
                f"{p}: cannot read it as a .npz archive (it does not start like a zip file); "
                "the file is truncated or corrupt, or not a saved model"
            )
        _check_declared_sizes(p)
        with np.load(p, allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in npz.files}
    except ArchiveError:
        raise
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, KeyError) as exc:
        raise ArchiveError(
            f"{p}: cannot read it as a .npz archive ({exc}); the file is truncated or corrupt, "
            "save the model again"
        ) from exc
    if FORMAT_KEY not in arrays:
        raise ArchiveError(f"{p}: not a geoq archive (no {FORMAT_KEY} entry)")
    try:
        header = json.loads(str(arrays.pop(FORMAT_KEY)))
        found_kind, version = str(header["kind"]), int(header["version"])
    except (ValueError, KeyError, TypeError) as exc:
        raise ArchiveError(f"{p}: corrupt geoq archive header ({exc})") from exc
    if found_kind != kind:
        raise ArchiveError(f"{p}: holds a {found_kind!r}, expected a {kind!r}")
    if version > max_version:
        raise ArchiveError(
            f"{p}: format version {version} is newer than this geoq supports ({max_version}); "
            "upgrade geoq to load it"
        )
    return version, arrays
