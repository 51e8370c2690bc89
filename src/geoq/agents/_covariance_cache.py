"""The covariances of the stored next states x candidate actions with the basis, kept
between fitted-Q phases.

A fitted-Q phase needs ``k([s'_i, a_k], BV_j)`` for every stored transition ``i``,
candidate ``k`` and basis vector ``j``: ``[N K, m]``. The squared exponential is a
product of a state and an action factor (:func:`separable_factors`), so the agent keeps
only the state factor ``k_s(s'_i, BV_j)`` ``[N, m]`` (16 MB at 10,000 transitions and
200 BVs, against 336 MB for all 21 candidates) and forms the ``[K, m]`` action factor
per phase (:class:`~geoq.agents.fitted_q.SeparableCandidates`); the cache itself takes
any ``K`` rows per transition. From one phase to the next most transitions and most
basis vectors are the same, and an entry of a kernel that does not follow its basis
(the squared exponential) depends only on its two inputs. So the matrix lives in one
place across phases and only what is new is computed: rows for new transitions,
columns for new basis vectors. Nothing is copied per phase:

* **columns are slots.** A basis vector keeps its column (its *slot*) for as long as
  it is in the basis; a deleted one frees its slot for the next new one. The caller
  gets the slot of each basis vector and gives every other column zero weight.
* **rows are a sliding block.** Transitions ``first .. first + N - 1`` are rows
  ``[(first - row_first) K, (first + N - row_first) K)`` of a buffer that grows by
  half when full and moves its live rows to the top (one memmove) when the window has
  slid past its start.

Every entry is ``kernel.to_basis`` of its two inputs, computed once (the oracle test
compares the slot columns with a fresh ``to_basis`` bit for bit). Every entry of the
buffer is finite: it starts at zero and is only overwritten by kernel values.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numba
import numpy as np

from geoq._typing import FloatArray, IntArray
from geoq.kernels.base import Kernel
from geoq.kernels.stationary import SquaredExponential

__all__ = ["BasisCovariance", "NextStateCovariances", "StateFactor", "separable_factors"]


class BasisCovariance(Protocol):
    """What the cache needs of a kernel: ``to_basis(X [n, d'], basis [m, d]) -> [n, m]``."""

    @property
    def tracks_basis(self) -> bool: ...

    def to_basis(self, X: FloatArray, basis: FloatArray) -> FloatArray: ...


#: The row buffer grows to this multiple of the rows it must hold.
GROWTH = 1.5


@dataclass(frozen=True)
class StateFactor:
    """The state factor ``k_s`` of a product kernel, against full ``[s, a]`` basis vectors."""

    kernel: SquaredExponential
    n_state: int
    tracks_basis: bool = False

    def to_basis(self, X: FloatArray, basis: FloatArray) -> FloatArray:
        """``k_s(X, basis[:, :n_state])`` for scaled states ``X`` ``[n, n_state]``."""
        return self.kernel.to_basis(X, np.ascontiguousarray(basis[:, : self.n_state]))


def separable_factors(
    kernel: Kernel, n_state: int
) -> tuple[StateFactor, SquaredExponential] | None:
    """``k([s, a], [s', a']) = k_s(s, s') k_a(a, a')`` of a squared exponential over ``[s, a]``
    (``n_state`` state dimensions first): the state factor (with the kernel's variance)
    and the action factor (variance 1). ``None`` for any other kernel."""
    if not isinstance(kernel, SquaredExponential) or kernel.se_parameters() is None:
        return None
    state = kernel.restricted(slice(0, n_state), variance=kernel.variance)
    return StateFactor(state, n_state), kernel.restricted(slice(n_state, None))


@numba.njit(cache=True, nogil=True)
def _scatter_columns(
    src: FloatArray, dst: FloatArray, dst_row0: int, dst_cols: IntArray
) -> None:  # pragma: no cover - compiled
    """``dst[dst_row0 + i, dst_cols[j]] = src[i, j]``, row by row (numpy's fancy column
    assignment into a [200k, 200] matrix took 1 s)."""
    for i in range(src.shape[0]):
        for j in range(dst_cols.shape[0]):
            dst[dst_row0 + i, dst_cols[j]] = src[i, j]


class NextStateCovariances:
    """``k(candidate inputs of S2, basis)`` in slot columns, kept and extended across phases.

    Transitions are identified by their absolute index in the agent's buffer (which
    only grows: the fitted-Q window slides forward), basis vectors by their bytes.
    Memory: one ``[rows, slots]`` buffer, at most ``GROWTH`` x the rows of a window and
    its scratch rows; ``min_slots`` columns from the start (the GP's budget: no regrowth
    as it fills).
    """

    def __init__(self, min_slots: int = 0) -> None:
        self.min_slots = int(min_slots)
        self.clear()

    def clear(self) -> None:
        """Forget everything (the inputs' scaling or the kernel changed)."""
        self._K = np.zeros((0, 0))
        self._row_first = 0  # buffer index of the transition in row block 0
        self._n = 0  # transitions held, from _row_first
        self._slots: dict[bytes, int] = {}

    def slot_arrays(self) -> dict[str, FloatArray | IntArray]:
        """The slot of each basis vector of the last phase (``basis`` ``[n, d]``,
        ``slots`` ``[n]``): a saved agent reloads with the same column order, hence the
        same bits of every later phase."""
        keys = list(self._slots)
        width = len(keys[0]) // 8 if keys else 0
        basis = np.frombuffer(b"".join(keys), dtype=np.float64).reshape(len(keys), width)
        return {"basis": basis.copy(), "slots": np.array(list(self._slots.values()), np.int64)}

    def restore_slots(self, basis: FloatArray, slots: IntArray) -> None:
        """Start from the slots of :meth:`slot_arrays` (the entries are computed afresh)."""
        self.clear()
        rows = np.ascontiguousarray(basis, dtype=np.float64)
        slots = np.asarray(slots)
        n = rows.shape[0] if rows.ndim == 2 else -1
        if (
            slots.shape != (n,)
            or slots.dtype.kind not in "iu"
            or len(set(slots.tolist())) < n
            or (n and not 0 <= int(slots.min()) <= int(slots.max()) < max(self.min_slots, n))
        ):
            raise ValueError(
                "covariance slots: one distinct slot in [0, budget) per basis vector expected"
            )
        self._slots = {b.tobytes(): int(j) for b, j in zip(rows, slots, strict=True)}

    def get(
        self,
        kernel: BasisCovariance,
        candidate_inputs: Callable[[FloatArray], FloatArray],
        next_states: FloatArray,
        first: int,
        basis: FloatArray,
        n_candidates: int,
        scratch_states: FloatArray | None = None,
    ) -> tuple[FloatArray, IntArray]:
        """The covariances of ``candidate_inputs(next_states)`` with ``basis``, and the slots.

        ``next_states`` ``[N, d_s]`` are the transitions ``first, ..., first + N - 1`` of
        the buffer; ``candidate_inputs`` maps ``[n, d_s]`` states to their ``[n K, d]``
        inputs (state-major). ``kernel`` must not follow its basis (``tracks_basis``).
        ``scratch_states`` ``[n, d_s]`` (e.g. imagined next states) get ``n K`` rows
        right after them, computed afresh and not kept: no copy of the kept rows.

        Returns ``K`` ``[(N + n) K, S]`` (a view, valid until the next call) and
        ``slots`` ``[m]``: ``K[:, slots[j]] = k(inputs, basis[j])``; the other ``S - m``
        columns hold finite values of no meaning.
        """
        if kernel.tracks_basis:
            raise ValueError("a kernel that follows its basis cannot reuse covariances")
        N, K = next_states.shape[0], int(n_candidates)
        if first < self._row_first or first > self._row_first + self._n:
            self._row_first, self._n = first, 0  # not a forward slide: rows afresh, same slots
        slots, new = self._assign_slots(basis)
        kept = self._row_first + self._n - first  # transitions held and still wanted
        kept = min(kept, N)
        n_scratch = 0 if scratch_states is None else scratch_states.shape[0]
        n_slots = max(self.min_slots, int(slots.max(initial=-1)) + 1)
        self._make_room(first, N + n_scratch, K, n_slots)
        r0 = (first - self._row_first) * K
        if kept and new.size:  # new basis vectors: their columns for the rows held
            block = kernel.to_basis(candidate_inputs(next_states[:kept]), basis[new])
            _scatter_columns(block, self._K, r0, slots[new])
        if kept < N:  # new transitions: every column
            block = kernel.to_basis(candidate_inputs(next_states[kept:]), basis)
            _scatter_columns(block, self._K, r0 + kept * K, slots)
        self._n = first + N - self._row_first
        if scratch_states is not None and n_scratch:
            block = kernel.to_basis(candidate_inputs(scratch_states), basis)
            _scatter_columns(block, self._K, r0 + N * K, slots)
        return self._K[r0 : r0 + (N + n_scratch) * K], slots

    def _assign_slots(self, basis: FloatArray) -> tuple[IntArray, IntArray]:
        """Slots of ``basis`` ``[m]`` (kept ones unchanged, freed ones reused lowest first)
        and the indices of the basis vectors that are new."""
        keys = [b.tobytes() for b in basis]
        old = self._slots
        slots = np.array([old.get(k, -1) for k in keys], dtype=np.intp)
        new = np.flatnonzero(slots < 0)
        used = set(slots[slots >= 0].tolist())
        free = (s for s in range(basis.shape[0] + len(old)) if s not in used)
        for j in new:
            slots[j] = next(free)
        self._slots = dict(zip(keys, slots.tolist(), strict=True))
        return slots, new

    def _make_room(self, first: int, N: int, K: int, n_slots: int) -> None:
        """Make the buffer hold rows for transitions ``first .. first + N - 1`` (the
        held ones and any scratch rows after them) and ``n_slots`` columns, keeping the
        rows of the transitions still wanted."""
        rows, cols = self._K.shape
        kept = max(0, min(self._row_first + self._n, first + N) - first)
        start = (first - self._row_first) * K
        need_rows = N * K
        if cols >= n_slots and start + need_rows <= rows:
            return
        if cols >= n_slots and need_rows <= rows:  # slide: live rows to the top
            self._K[: kept * K] = self._K[start : start + kept * K]
        else:
            grown = np.zeros((max(need_rows, int(GROWTH * need_rows)), max(cols, n_slots)))
            grown[: kept * K, :cols] = self._K[start : start + kept * K]
            self._K = grown
        self._row_first, self._n = first, kept
