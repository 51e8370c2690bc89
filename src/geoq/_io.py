"""Atomic file writes, runs written whole, and versioned ``.npz`` archives.

A result is either entirely on disk or not at all: every write goes to a
temporary file in the destination directory, is flushed and fsync'ed, then
renamed over the target (``os.replace`` is atomic on POSIX and Windows).

What a write replaces (:func:`output_path`): a regular file, or the regular file a
symbolic link points to (the link is written through and stays a link); a
directory, a FIFO, a device or a socket is never replaced (``FileExistsError`` /
``IsADirectoryError``). An existing file keeps its permission bits, as with
``open(path, "w")``. A run of several files (:func:`staged_run`) is written into a
staging directory first and moved into place only once every file is written, so
a failure leaves the earlier run whole; writing over an earlier run needs
``overwrite=True``.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import stat
import tempfile
import threading
import zipfile
from collections.abc import Collection, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "FORMAT_KEY",
    "ArchiveError",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_text",
    "check_output_file",
    "check_run_dir",
    "check_writable_dir",
    "load_archive",
    "output_path",
    "save_archive",
    "staged_run",
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


def output_path(path: str | os.PathLike[str]) -> Path:
    """The regular file a write to ``path`` replaces: ``path`` itself, or, for a symbolic
    link, the file it points to (followed to the end; it need not exist yet).

    Raises ``IsADirectoryError`` for a directory, ``FileExistsError`` for anything else
    that is not a regular file (a FIFO, a device, a socket, a loop of links): geoq
    replaces regular files only.
    """
    p = Path(path)
    if p.is_symlink():
        resolved = Path(os.path.realpath(p))
        if resolved.is_symlink():
            raise FileExistsError(f"{p} is a loop of symbolic links; give a file path")
        p = resolved
    try:
        mode = p.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):  # new; under a file: check_output_file
        return p
    if stat.S_ISDIR(mode):
        raise IsADirectoryError(f"{p} is a directory; give a file path")
    if not stat.S_ISREG(mode):
        kind = (
            "a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "a device"
        )
        raise FileExistsError(
            f"{p} exists and is {kind}, not a regular file; geoq replaces regular files only: "
            "give another path"
        )
    return p


def _file_mode(target: Path) -> int:
    """The mode ``open(target, "w")`` leaves: an existing file's own, else 0o666 - umask."""
    try:
        return stat.S_IMODE(target.stat().st_mode)
    except FileNotFoundError:
        return 0o666 & ~_umask()


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temp file + fsync + rename); returns ``path``.

    A symbolic link is written through (:func:`output_path`); the file gets the mode a
    plain ``open(path, "w")`` would give it (an existing file keeps its own, a new one
    ``0o666`` minus the umask), not the ``0o600`` of the temporary file.
    """
    target = output_path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, _file_mode(target))
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(path)


def check_writable_dir(
    directory: str | os.PathLike[str],
    target: str | os.PathLike[str] | None = None,
    *,
    create: bool = True,
) -> None:
    """An ``OSError`` unless files can be written in ``directory`` (for ``target``, named in
    the message; default: the directory itself).

    ``directory`` is a directory, or, with ``create``, can be made one: its nearest
    existing ancestor is a directory (``NotADirectoryError`` otherwise;
    ``FileNotFoundError`` for a missing one without ``create``). Writability is tested for
    real, by creating and removing a temporary file in ``directory`` or that ancestor:
    ``os.access`` says yes to root for everything, and to anyone on /proc and /sys, where
    no file can be created (``PermissionError``, also for a read-only mount, a full disk).
    """
    d = Path(directory)
    what = d if target is None else Path(target)
    ancestor = d
    while not (ancestor.exists() or ancestor.is_symlink()) and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        if ancestor == d:
            so = f"so {what} cannot be written"
        else:
            so = f"so {d} cannot be made" + ("" if what == d else f" for {what}")
        raise NotADirectoryError(f"{ancestor} is not a directory, {so}; give a path in a directory")
    if ancestor != d and not create:
        raise FileNotFoundError(f"the directory {d} does not exist, so {what} cannot be "
                                "written; create it first")  # fmt: skip
    try:
        fd, probe = tempfile.mkstemp(dir=ancestor, prefix=".geoq-write-test-")
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise PermissionError(
            f"cannot create files in {ancestor} ({reason}), so {what} cannot be written: give "
            "a path on a writable filesystem (not /proc, /sys or a read-only directory)"
        ) from exc
    os.close(fd)
    Path(probe).unlink(missing_ok=True)


def check_output_file(path: str | os.PathLike[str], *, create: bool = True) -> Path:
    """The file a write to ``path`` replaces (:func:`output_path`), checked before any work:
    an ``OSError`` unless it is a regular file or new, and its directory can receive it
    (:func:`check_writable_dir`; ``create``: a missing directory may be made)."""
    target = output_path(path)
    check_writable_dir(target.parent, path, create=create)
    return target


def check_run_dir(out: str | os.PathLike[str], names: Collection[str], overwrite: bool) -> None:
    """An ``OSError`` unless ``out`` can receive a run of the files ``names``: it is a
    directory or can be made one, files can be written there (:func:`check_writable_dir`:
    tested with a temporary file), and it holds none of them unless ``overwrite``
    (``FileExistsError``)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out} exists and is not a directory; give a directory")
    check_writable_dir(out)
    earlier = sorted(n for n in names if (out / n).exists() or (out / n).is_symlink())
    for name in earlier:  # replaced later: regular files only (or links to them)
        output_path(out / name)
    if earlier and not overwrite:
        raise FileExistsError(
            f"{out} holds an earlier run ({', '.join(earlier)}); give another directory, or "
            "pass overwrite=True (--overwrite) to replace that run"
        )


@contextmanager
def staged_run(
    out: str | os.PathLike[str], names: Collection[str], *, overwrite: bool = False
) -> Iterator[Path]:
    """A directory to write a run's files into; on success they replace the run in ``out``.

    ``names`` are the files a run of this kind may hold. The files written into the
    staging directory (a hidden directory inside ``out``) are moved into ``out`` only
    when the ``with`` block ends without an error, after every destination was
    checked (:func:`output_path`); files of ``names`` the new run did not write are
    then removed, so two runs never mix. On an error the staging directory is
    removed and ``out`` is as it was (a directory made for the run is removed again).
    """
    out = Path(out)
    check_run_dir(out, names, overwrite)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=out, prefix=".staging-"))
    elsewhere: list[Path] = []  # copies next to targets outside out (written-through links)
    try:
        yield staging
        written = sorted(p.name for p in staging.iterdir())
        unknown = sorted(set(written) - set(names))
        if unknown:
            raise ValueError(f"files {unknown} are not part of this kind of run")
        targets = {n: output_path(out / n) for n in written}
        moves = []
        for name, target in targets.items():  # every new file next to its target first
            src = staging / name
            if target.parent.resolve() != out.resolve():
                fd, copy = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.")
                os.close(fd)
                elsewhere.append(Path(copy))
                shutil.copyfile(src, copy)
                src = Path(copy)
            os.chmod(src, _file_mode(target))
            moves.append((src, target))
        for src, target in moves:  # then renames only
            os.replace(src, target)
        for name in sorted(set(names) - set(written)):
            if (out / name).is_symlink() or (out / name).is_file():
                (out / name).unlink()
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        for leftover in elsewhere:
            leftover.unlink(missing_ok=True)
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise
    shutil.rmtree(staging, ignore_errors=True)


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
    if not p.exists():
        raise ArchiveError(f"{p}: no such file")
    if not p.is_file():
        raise ArchiveError(f"{p} is not a regular file (a FIFO, a device?); give a saved model")
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
