"""The BLAS threading policy: small dense linear algebra runs on one BLAS thread.

The library decides its threads, not the caller's environment. Threaded BLAS on
the matrices of a sparse GP (a few hundred rows) is slower than one thread (the
measurements: ``docs/design-notes.md``). So:

* the GP's batch entry points (``SparseOnlineGP.fit``, ``partial_fit``,
  ``refit``) run under :func:`one_blas_thread`, and so does everything they call
  (kernel hooks, resyncs, the resistance updates);
* ``SparseOnlineGP.update`` (one point) is *not* wrapped: entering costs a
  noticeable part of an SE update that calls no BLAS at all. What it calls
  that uses BLAS on matrices of the BV set's size is wrapped instead: the
  resync (``_resync_q``, O(m^3), after every change with the resistance kernel)
  and the resistance kernel's node updates and recomputation;
* ``SparseOnlineGP.predict`` on up to ``SMALL_BATCH`` = 4096 points (an agent
  asks for a few points per step) runs on one thread;
* everything else (``predict`` on more points, the exact GP on 1e4 points, a
  user's own numpy) keeps the caller's setting, so large products may use every
  core.

Entering and leaving costs one get and two sets of the thread count per BLAS
library (numpy and scipy each bring an OpenBLAS), far less than
``threadpoolctl.threadpool_limits``, which scans the loaded libraries at every
call (``benchmarks/bench_threads.py`` measures both): the BLAS libraries are
found once, on first use, by a cached :class:`threadpoolctl.ThreadpoolController`.
Nested entries cost a counter increment. The setting is process-wide (OpenBLAS
has no per-thread setting): while any Python thread is inside, BLAS calls of
other threads also run on one thread; the caller's counts are restored when the
last one leaves (threadpoolctl lets only one Python thread set OpenBLAS's count:
from another thread the limit is a no-op, never an error). A BLAS library loaded
after the first use is not limited (numpy's and scipy's are: the first use
imports ``scipy.linalg`` before looking).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any, ParamSpec, TypeVar

import numpy as np

__all__ = [
    "SMALL_BATCH",
    "blas_controllers",
    "one_blas_thread",
    "single_blas_thread",
    "single_blas_thread_for_small_batches",
]

P = ParamSpec("P")
R = TypeVar("R")

_controllers: list[Any] | None = None

#: Batches of up to this many rows are small: one BLAS thread (``predict``).
SMALL_BATCH = 4096


def blas_controllers() -> list[Any]:
    """threadpoolctl's controllers of the loaded BLAS libraries (found once, then cached)."""
    global _controllers
    if _controllers is None:
        import scipy.linalg  # noqa: F401 - scipy's own BLAS must be loaded to be found
        from threadpoolctl import ThreadpoolController

        found = ThreadpoolController().lib_controllers
        _controllers = [c for c in found if c.user_api == "blas"]
    return _controllers


class _OneBlasThread:
    """Process-wide, reentrant: the first entry saves the BLAS thread counts and sets 1,
    the last exit restores them."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._depth = 0
        self._saved: list[tuple[Any, int]] = []

    def __enter__(self) -> None:
        with self._lock:
            if self._depth == 0:
                self._saved = [(c, c.get_num_threads()) for c in blas_controllers()]
                for c, n in self._saved:
                    if n != 1:
                        c.set_num_threads(1)
            self._depth += 1

    def __exit__(self, *exc: object) -> None:
        with self._lock:
            self._depth -= 1
            if self._depth == 0:
                for c, n in self._saved:
                    if n != 1:
                        c.set_num_threads(n)
                self._saved = []


_ONE = _OneBlasThread()


def one_blas_thread() -> AbstractContextManager[None]:
    """Context manager: the block runs with one BLAS thread (module docstring)."""
    return _ONE


def single_blas_thread(fn: Callable[P, R]) -> Callable[P, R]:
    """Decorator: ``fn`` runs under :func:`one_blas_thread`."""

    @functools.wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with _ONE:
            return fn(*args, **kwargs)

    return wrapper


def single_blas_thread_for_small_batches(fn: Callable[P, R]) -> Callable[P, R]:
    """Decorator for methods ``fn(self, X, ...)``: one BLAS thread when ``X`` has at most
    :data:`SMALL_BATCH` rows, the caller's setting for larger batches."""

    @functools.wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        X: Any = args[1] if len(args) > 1 else kwargs.get("X")
        if len(np.shape(X)) == 0 or np.shape(X)[0] > SMALL_BATCH:
            return fn(*args, **kwargs)
        with _ONE:
            return fn(*args, **kwargs)

    return wrapper
