"""The covariances of the stored next states x candidate actions with the basis, kept
between fitted-Q phases.

A fitted-Q phase needs ``k([s'_i, a_k], BV_j)`` for every stored transition ``i``,
candidate ``k`` and basis vector ``j``: ``[N K, m]``, the largest cost of a phase once
thousands of transitions are stored (1.1 of 1.5 s at 10,000 transitions and 200 BVs).
From one phase to the next most transitions and most basis vectors are the same,
and an entry of a kernel that does not follow its basis (the squared exponential)
depends only on its two inputs, so those entries are copied instead of recomputed:
the matrix is the same to the bit as computing it afresh.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from geoq._typing import FloatArray, IntArray
from geoq.kernels.base import Kernel

__all__ = ["NextStateCovariances"]


@numba.njit(cache=True, nogil=True)
def _copy_columns(
    src: FloatArray,
    src_row0: int,
    src_cols: IntArray,
    dst: FloatArray,
    dst_row0: int,
    dst_cols: IntArray,
    n_rows: int,
) -> None:  # pragma: no cover - compiled
    """``dst[dst_row0 + i, dst_cols] = src[src_row0 + i, src_cols]`` for ``i < n_rows``,
    row by row (numpy's fancy column indexing of a [200k, 200] matrix took 1 s)."""
    for i in range(n_rows):
        for j in range(src_cols.shape[0]):
            dst[dst_row0 + i, dst_cols[j]] = src[src_row0 + i, src_cols[j]]


class NextStateCovariances:
    """``k(candidate inputs of S2, basis)`` ``[N K, m]``, reusing the previous phase's entries.

    Transitions are identified by their absolute index in the agent's buffer (which
    only grows: the fitted-Q window slides forward), basis vectors by their bytes.
    Memory: the previous phase's matrix is held between phases.
    """

    def __init__(self) -> None:
        self.clear()

    def clear(self) -> None:
        """Forget everything (the inputs' scaling or the kernel changed)."""
        self._first = 0
        self._n = 0
        self._columns: dict[bytes, int] = {}
        self._K: FloatArray | None = None

    def get(
        self,
        kernel: Kernel,
        candidate_inputs: Callable[[FloatArray], FloatArray],
        next_states: FloatArray,
        first: int,
        basis: FloatArray,
        n_candidates: int,
    ) -> FloatArray:
        """The covariances ``[N K, m]`` of ``candidate_inputs(next_states)`` with ``basis``.

        ``next_states`` ``[N, d_s]`` are the transitions ``first, ..., first + N - 1`` of
        the buffer; ``candidate_inputs`` maps ``[n, d_s]`` states to their ``[n K, d]``
        inputs (state-major). ``kernel`` must not follow its basis (``tracks_basis``).
        """
        if kernel.tracks_basis:
            raise ValueError("a kernel that follows its basis cannot reuse covariances")
        N, K, m = next_states.shape[0], int(n_candidates), basis.shape[0]
        out = np.empty((N * K, m))
        lo, hi = max(first, self._first), min(first + N, self._first + self._n)
        old = self._K
        if old is None or hi <= lo:
            lo = hi = first  # nothing to reuse
        else:
            cols = np.array([self._columns.get(b.tobytes(), -1) for b in basis], dtype=np.intp)
            have = cols >= 0
            if np.any(have):
                _copy_columns(
                    old, (lo - self._first) * K, cols[have], out, (lo - first) * K,
                    np.flatnonzero(have), (hi - lo) * K,
                )  # fmt: skip
            if not np.all(have):
                new = kernel.to_basis(
                    candidate_inputs(next_states[lo - first : hi - first]), basis[~have]
                )
                _copy_columns(
                    new, 0, np.arange(new.shape[1]), out, (lo - first) * K,
                    np.flatnonzero(~have), (hi - lo) * K,
                )  # fmt: skip
        if lo > first:
            out[: (lo - first) * K] = kernel.to_basis(
                candidate_inputs(next_states[: lo - first]), basis
            )
        if hi < first + N:
            out[(hi - first) * K :] = kernel.to_basis(
                candidate_inputs(next_states[hi - first :]), basis
            )
        self._first, self._n, self._K = first, N, out
        self._columns = {b.tobytes(): j for j, b in enumerate(basis)}
        return out
