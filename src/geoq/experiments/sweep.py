"""A resumable, parallel map over the cells of an experiment sweep.

:func:`run_sweep` applies ``fn(cell) -> row`` to every cell of a sweep and
returns the rows in the cells' order. It is built for long sweeps that must
survive being killed and must scale from one core to a cluster:

* **One file per cell, written the moment it finishes.** Each finished cell is
  stored as ``<store_dir>/<key>.json`` (``{"format", "key", "spec", "row"}``)
  with :func:`geoq._io.atomic_write_json` (temp file + fsync + rename), so a
  file is either complete or absent. A killed sweep loses only the cells that
  were in flight.
* **Resume.** On a rerun, a cell whose file exists, parses, and stores the
  same spec is not recomputed. A corrupt, truncated or foreign file is
  recomputed and overwritten.
* **The same results whatever the backend.** Cells carry their own seeds;
  nothing here touches a global random state. Rows go through a JSON round
  trip before they are returned, so a freshly computed row and one read back
  from disk are equal (tuples become lists, numpy scalars become Python
  scalars).
* **Parallel without oversubscription.** ``backend="loky"`` runs the cells in
  ``jobs`` joblib/loky worker processes whose native thread pools (BLAS,
  OpenMP, numba, numexpr) are limited to one thread each through joblib's
  ``inner_max_num_threads`` (environment variables set when the workers
  start), plus a :func:`threadpoolctl.threadpool_limits` around each call.
  ``backend="dask"`` submits the same cells to a Dask distributed cluster
  (``scheduler=ADDRESS``) or to a :class:`distributed.LocalCluster` sized to
  the machine; the driver still writes each finished cell.

Example
-------
>>> rows = run_sweep(cells, run_one_cell, "results/fig3_cells", jobs=2)  # doctest: +SKIP

``fn`` must be a module-level function (workers import it by name), cells
JSON-serialisable mappings or dataclass instances, rows mappings of
JSON-serialisable values.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
import os
import re
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from geoq._io import atomic_write_json

__all__ = [
    "BACKENDS",
    "CELL_FORMAT",
    "cap_jobs",
    "cell_key",
    "cell_spec",
    "load_cell",
    "run_sweep",
]

#: Version of the per-cell JSON file layout.
CELL_FORMAT = 1

#: Backends accepted by :func:`run_sweep`.
BACKENDS = ("loky", "dask")

#: Environment variables that size native thread pools; set to "1" in the
#: workers of a LocalCluster started here (loky gets them from joblib's
#: ``inner_max_num_threads``, which sets the same list).
_THREAD_ENV_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMBA_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)

_MAX_PREFIX = 60
_HASH_CHARS = 16


# --------------------------------------------------------------------------- cells
def _jsonable(obj: Any, where: str) -> Any:
    """Return ``obj`` made JSON-native.

    Tuples become lists, numpy scalars and arrays Python numbers and lists,
    enums their value, paths strings; anything else that is not a JSON type
    raises :class:`TypeError` naming where it is.
    """
    if isinstance(obj, Mapping):
        out = {}
        for k, v in obj.items():
            if not isinstance(k, str):
                raise TypeError(f"{where}: key {k!r} is not a string; JSON objects need str keys")
            out[k] = _jsonable(v, f"{where}.{k}")
        return out
    if isinstance(obj, list | tuple):
        return [_jsonable(v, f"{where}[{i}]") for i, v in enumerate(obj)]
    if obj is None or isinstance(obj, bool | int | float | str):
        return obj
    if isinstance(obj, enum.Enum):
        return _jsonable(obj.value, where)
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    item = getattr(obj, "item", None)  # numpy scalar or 0-d array
    tolist = getattr(obj, "tolist", None)  # numpy array
    if callable(tolist) and getattr(obj, "ndim", 0) > 0:
        return _jsonable(tolist(), where)
    if callable(item):
        return _jsonable(item(), where)
    raise TypeError(
        f"{where} = {obj!r} of type {type(obj).__name__} is not JSON-serialisable; "
        "use numbers, strings, booleans, None, lists and str-keyed dicts"
    )


def cell_spec(cell: Any) -> dict[str, Any]:
    """Return the JSON-native dict that identifies ``cell``.

    ``cell`` is a mapping with string keys or a dataclass instance
    (converted with :func:`dataclasses.asdict`); values must be
    JSON-serialisable (numpy scalars are converted). A dataclass field declared
    with ``field(metadata={"key": False})`` (e.g. the directory a cell reads its
    inputs from) is left out: it does not change what the cell computes, and a
    results folder moved elsewhere must keep its keys.
    """
    if dataclasses.is_dataclass(cell) and not isinstance(cell, type):
        raw: Any = dataclasses.asdict(cell)
        for f in dataclasses.fields(cell):
            if not f.metadata.get("key", True):
                raw.pop(f.name)  # where to find things, not what is computed
    elif isinstance(cell, Mapping):
        raw = cell
    else:
        raise TypeError(
            f"a sweep cell must be a mapping or a dataclass instance, got {type(cell).__name__}"
        )
    spec = _jsonable(raw, "cell")
    # Canonical form: what a JSON round trip gives back.
    return dict(json.loads(_canonical(spec)))


def _canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=True)


def _slug(value: Any) -> str:
    text = str(value).lower() if isinstance(value, bool) else str(value)
    return re.sub(r"[^A-Za-z0-9._]+", "-", text).strip("-._")


def cell_key(cell: Any) -> str:
    """Return a stable, filename-safe key for ``cell``.

    A readable prefix built from the spec's scalar values (in sorted key
    order, e.g. ``kernel-nearest_max_bv-5_seed-3``) followed by the first 16
    hex digits of the SHA-256 of the spec's canonical JSON. Two cells have the
    same key exactly when their specs are equal (up to hash collisions).
    """
    spec = cell_spec(cell)
    digest = hashlib.sha256(_canonical(spec).encode("utf-8")).hexdigest()[:_HASH_CHARS]
    parts = []
    for name in sorted(spec):
        value = spec[name]
        if value is None or isinstance(value, bool | int | float | str):
            part = f"{_slug(name)}-{_slug(value)}".strip("-")
            if part:
                parts.append(part)
    prefix = "_".join(parts)[:_MAX_PREFIX].rstrip("_-.")
    return f"{prefix}__{digest}" if prefix else digest


def load_cell(path: str | os.PathLike[str], spec: Mapping[str, Any]) -> dict[str, Any] | None:
    """Return the row stored at ``path`` for ``spec``, or ``None`` if it must be (re)computed.

    ``None`` when the file is missing, not valid JSON (truncated or corrupt),
    of another format version, or stores another spec.
    """
    p = Path(path)
    try:
        with p.open(encoding="utf-8") as fh:
            record = json.load(fh)
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("format") != CELL_FORMAT:
        return None
    row = record.get("row")
    if not isinstance(row, dict) or _canonical(record.get("spec")) != _canonical(dict(spec)):
        return None
    return row


# --------------------------------------------------------------------------- workers
def _limit_native_threads() -> Any:
    """Context manager limiting BLAS/OpenMP pools of the current process to one thread."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1)


def _call_cell(fn: Callable[[Any], Mapping[str, Any]], cell: Any, key: str) -> dict[str, Any]:
    """Run ``fn(cell)`` in a worker with native threads pinned; return the JSON-native row."""
    with _limit_native_threads():
        try:
            row = fn(cell)
        except BaseException as exc:
            exc.add_note(f"geoq sweep: raised while computing cell {key}")
            raise
    if not isinstance(row, Mapping):
        raise TypeError(f"sweep cell {key}: fn returned {type(row).__name__}; expected a dict row")
    return dict(json.loads(_canonical(_jsonable(row, f"row of cell {key}"))))


def cap_jobs(jobs: int) -> tuple[int, str | None]:
    """``(workers, warning)``: ``jobs`` capped at the number of cores, and why if it was.

    More worker processes than cores only compete for them (each sweep cell is
    single-threaded) and multiply the memory: ``jobs`` above ``os.cpu_count()`` is
    capped there, with a message saying so.
    """
    cores = os.cpu_count() or 1
    if jobs <= cores:
        return jobs, None
    return cores, (
        f"jobs={jobs} is more than the {cores} core(s) of this machine; using {cores} worker "
        "processes (more would only compete for the cores)"
    )


def _resolve_jobs(jobs: int, local: bool = True) -> int:
    if isinstance(jobs, bool) or not isinstance(jobs, int) or (jobs < 1 and jobs != -1):
        raise ValueError(f"jobs must be an integer >= 1 (or -1 for all cores), got {jobs!r}")
    if jobs == -1:
        return os.cpu_count() or 1
    if not local:  # a remote Dask cluster decides its own workers
        return jobs
    capped, message = cap_jobs(jobs)
    if message is not None:
        warnings.warn(message, UserWarning, stacklevel=3)
    return capped


def _iter_loky(
    fn: Callable[[Any], Mapping[str, Any]], todo: list[tuple[str, Any]], jobs: int
) -> Iterator[tuple[str, dict[str, Any]]]:
    """Yield ``(key, row)`` as cells finish, in joblib/loky workers (serial if jobs == 1)."""
    if jobs == 1:
        for key, cell in todo:
            yield key, _call_cell(fn, cell, key)
        return
    from joblib import Parallel, delayed, parallel_config

    # inner_max_num_threads=1: joblib starts the loky workers with OMP/OPENBLAS/
    # MKL/BLIS/VECLIB/NUMBA/NUMEXPR_NUM_THREADS=1, so `jobs` workers use `jobs` cores.
    with parallel_config(backend="loky", n_jobs=jobs, inner_max_num_threads=1):
        results = Parallel(return_as="generator_unordered", batch_size=1, pre_dispatch="2*n_jobs")(
            delayed(_call_cell_keyed)(fn, cell, key) for key, cell in todo
        )
        yield from results


def _call_cell_keyed(
    fn: Callable[[Any], Mapping[str, Any]], cell: Any, key: str
) -> tuple[str, dict[str, Any]]:
    return key, _call_cell(fn, cell, key)


def _iter_dask(
    fn: Callable[[Any], Mapping[str, Any]],
    todo: list[tuple[str, Any]],
    jobs: int,
    scheduler: str | None,
) -> Iterator[tuple[str, dict[str, Any]]]:
    """Yield ``(key, row)`` as cells finish on a Dask distributed cluster."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ImportError(
            "backend='dask' needs dask.distributed: pip install 'geoq[dask]'"
        ) from exc

    cluster = None
    if scheduler is None:
        n_workers = (os.cpu_count() or 1) if jobs == 1 else jobs
        cluster = LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            env={var: "1" for var in _THREAD_ENV_VARS},
        )
        client = Client(cluster)
    else:
        client = Client(scheduler)
    try:
        futures = [
            client.submit(_call_cell_keyed, fn, cell, key, key=f"geoq-cell-{key}", pure=False)
            for key, cell in todo
        ]
        try:
            for future in as_completed(futures):
                yield future.result()
        finally:
            client.cancel([f for f in futures if not f.done()])
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# --------------------------------------------------------------------------- driver
def run_sweep(
    cells: Sequence[Any],
    fn: Callable[[Any], Mapping[str, Any]],
    store_dir: str | os.PathLike[str],
    *,
    jobs: int = 1,
    backend: str = "loky",
    scheduler: str | None = None,
    progress: bool = True,
    desc: str = "",
) -> list[dict[str, Any]]:
    """Compute ``fn(cell)`` for every cell, resumably and in parallel; return rows in order.

    Parameters
    ----------
    cells : the sweep's cells, each a str-keyed mapping or a dataclass instance
        of JSON-serialisable values that identifies the computation entirely,
        seeds included. Cells must be distinct.
    fn : ``fn(cell) -> dict`` of JSON-serialisable values; a module-level
        function so that worker processes can import it. It receives the cell
        object as given.
    store_dir : directory of the per-cell files ``<cell_key(cell)>.json``;
        created if needed. Reusing it resumes the sweep.
    jobs : worker processes. ``1`` runs serially in this process; ``-1`` uses
        every core; more than ``os.cpu_count()`` is capped there with a ``UserWarning``
        (:func:`cap_jobs`). In every mode, serial included, BLAS/OpenMP pools are
        limited to one thread while ``fn`` runs, so rows do not depend on the
        number of BLAS threads. With ``backend="dask"`` and no ``scheduler``, the number of
        LocalCluster workers (``1`` means one per core); ignored with a
        ``scheduler`` (the cluster decides).
    backend : ``"loky"`` (joblib, this machine) or ``"dask"`` (Dask distributed).
    scheduler : address of a running Dask scheduler, e.g. ``"tcp://host:8786"``;
        only with ``backend="dask"``. Its workers must have geoq (and ``fn``'s
        module) installed; set ``NUMBA_NUM_THREADS=1`` in their environment
        (Dask's nanny already sets OMP/MKL/OPENBLAS_NUM_THREADS=1).
    progress : show a tqdm progress bar over cells (on stderr).
    desc : label of the progress bar.

    Returns
    -------
    list of dict : row ``i`` is ``fn(cells[i])`` after a JSON round trip, whether
        computed now or read back from ``store_dir``.

    Raises
    ------
    ValueError : bad ``jobs``/``backend``/``scheduler``, or duplicate cells.
    TypeError : a cell or row that is not JSON-serialisable.
    Exception : whatever ``fn`` raised (with a note naming the cell); cells
        finished before it stay on disk.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if scheduler is not None and backend != "dask":
        raise ValueError(
            f"scheduler={scheduler!r} needs backend='dask' (got backend={backend!r}); "
            "pass backend='dask' or drop the scheduler"
        )
    n_jobs = _resolve_jobs(jobs, local=scheduler is None)
    if not callable(fn):
        raise TypeError(f"fn must be callable, got {type(fn).__name__}")

    store = Path(store_dir)
    store.mkdir(parents=True, exist_ok=True)
    cells = list(cells)
    specs = [cell_spec(c) for c in cells]
    keys = [cell_key(s) for s in specs]
    first_index: dict[str, int] = {}
    for i, key in enumerate(keys):
        if key in first_index:
            raise ValueError(
                f"cells {first_index[key]} and {i} are identical ({specs[i]}); "
                "every sweep cell must be distinct (add a seed or a replicate index)"
            )
        first_index[key] = i

    rows: list[dict[str, Any] | None] = [
        load_cell(store / f"{key}.json", spec) for key, spec in zip(keys, specs, strict=True)
    ]
    todo = [(keys[i], cells[i]) for i, row in enumerate(rows) if row is None]

    from tqdm.auto import tqdm

    bar = tqdm(
        total=len(cells),
        initial=len(cells) - len(todo),
        desc=desc or None,
        unit="cell",
        disable=not progress,
        dynamic_ncols=True,
    )
    try:
        if todo:
            finished: Iterable[tuple[str, dict[str, Any]]]
            if backend == "loky":
                finished = _iter_loky(fn, todo, n_jobs)
            else:
                finished = _iter_dask(fn, todo, n_jobs, scheduler)
            for key, row in finished:
                i = first_index[key]
                record = {"format": CELL_FORMAT, "key": key, "spec": specs[i], "row": row}
                atomic_write_json(store / f"{key}.json", record)
                rows[i] = row
                bar.update(1)
    finally:
        bar.close()

    missing = [keys[i] for i, row in enumerate(rows) if row is None]
    if missing:  # pragma: no cover - every backend yields each submitted cell once
        raise RuntimeError(f"sweep ended with {len(missing)} cell(s) not computed: {missing[:5]}")
    return [row for row in rows if row is not None]
