"""The sparse online GP's state: its buffers, the views of them, snapshots and copies.

:class:`OnlineGPState` is the base of :class:`~geoq.gp.SparseOnlineGP`, which adds
the updates, the refits, prediction and persistence. The buffers have ``cap =
max_bv + 1`` rows (a new basis vector is appended before one is deleted); their
leading ``m`` block is the state (:func:`geoq.gp._step._step` documents each):
``BV`` [cap, d], ``R`` [cap, cap] upper with ``K_BV = R^T R``, the whitened
posterior ``u ~ N(mu, S)`` with ``f_BV = R^T u``, and the deletion scores' ``alpha``
and ``diag(Q + C)``. The compiled steps receive them as one tuple
(:meth:`OnlineGPState._buffers`), with the step's settings and scratch likewise.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Self

import numpy as np
import scipy.linalg

from geoq._typing import FloatArray
from geoq.gp._resync import FactorMemo
from geoq.gp._step import N_WORK, GPBuffers, Scratch, StepSettings
from geoq.gp.diagnostics import Counters, OnlineDiagnostics, repair_warning
from geoq.gp.numerics import NumericalWarning, NumericsConfig
from geoq.kernels.base import Kernel

__all__ = ["OnlineGPState"]


class OnlineGPState:
    """Buffers and views of a sparse online GP (see the module docstring)."""

    kernel: Kernel
    noise: float
    max_bv: int
    tol: float
    resync_every: int
    config: NumericsConfig
    _dim: int | None

    def _reset_state(self) -> None:
        cap = self.max_bv + 1
        d = 0 if self._dim is None else self._dim
        self._m = 0
        self._bv = np.zeros((cap, d))  # [cap, d]
        self._R = np.zeros((cap, cap))  # [cap, cap] upper, K_BV = R^T R
        self._mu = np.zeros(cap)  # [cap] whitened posterior mean, f_BV = R^T u
        self._S = np.zeros((cap, cap))  # [cap, cap] whitened posterior covariance
        self._alpha = np.zeros(cap)  # [cap] R^{-1} mu, for the deletion scores
        self._mdiag = np.zeros(cap)  # [cap] diag(Q + C), for the deletion scores
        self._T = np.zeros((cap, cap))  # [cap, cap] scratch
        self._kbuf = np.zeros(cap)
        self._work = np.zeros((N_WORK, cap))
        self._counts = Counters()  # every counter, and whether the warning was shown
        self._changes = 0
        self._factor_memo: FactorMemo | None = None  # the last K_BV factorised
        self._batch = 0  # odd inside a batch of updates (geoq.gp._stream.stream)
        self._last_projected = (-1, 0)  # (batch, eigenvalues) of the last projection

    def _set_dim(self, d: int) -> None:
        if self._dim is None:
            self._dim = d
            self._bv = np.zeros((self.max_bv + 1, d))

    @property
    def n_bv(self) -> int:
        """Current number of basis vectors."""
        return self._m

    @property
    def basis_vectors(self) -> FloatArray:
        """The BV set, ``[n_bv, d]`` (a copy), in the order the kernel hooks saw."""
        return self._bv[: self._m].copy()

    def _rinv(self) -> FloatArray:
        m = self._m
        R = np.ascontiguousarray(self._R[:m, :m])
        return scipy.linalg.solve_triangular(R, np.eye(m), check_finite=False)

    @property
    def alpha(self) -> FloatArray:
        """Posterior mean weights ``alpha = R^{-1} mu`` ``[n_bv]``: ``mean(x) = k_x^T alpha``."""
        return self._rinv() @ self._mu[: self._m]

    @property
    def C(self) -> FloatArray:
        """``C = R^{-1} (S - I) R^{-T}`` ``[n_bv, n_bv]``: ``var(x) = k(x,x) + k_x^T C k_x``."""
        m = self._m
        Rinv = self._rinv()
        C = Rinv @ (self._S[:m, :m] - np.eye(m)) @ Rinv.T
        return 0.5 * (C + C.T)

    @property
    def Q(self) -> FloatArray:
        """``Q = K_BV^{-1} = R^{-1} R^{-T}`` ``[n_bv, n_bv]`` from the maintained factor."""
        Rinv = self._rinv()
        Q = Rinv @ Rinv.T
        return 0.5 * (Q + Q.T)

    @property
    def cholesky_factor(self) -> FloatArray:
        """Upper Cholesky factor ``R`` [n_bv, n_bv] with ``K_BV = R^T R`` (a copy)."""
        return np.triu(self._R[: self._m, : self._m])

    @property
    def whitened_posterior(self) -> tuple[FloatArray, FloatArray]:
        """``(mu [n_bv], S [n_bv, n_bv])``: ``u ~ N(mu, S)`` with ``f_BV = R^T u`` (copies)."""
        m = self._m
        return self._mu[:m].copy(), self._S[:m, :m].copy()

    @property
    def features_repaired(self) -> bool:
        """Whether online updates since the last refit rescaled features (negative novelty):
        predictions then use the repaired feature map, and the mean is not ``k_x^T alpha``."""
        return self._counts.features_repaired

    @property
    def diagnostics(self) -> OnlineDiagnostics:
        """A snapshot of the counters (see :class:`OnlineDiagnostics`)."""
        return self._counts.snapshot()

    def _warn_once(self) -> None:
        if self._counts.warned or not self._counts.any_repair():
            return
        repairs = self._counts.repairs()
        if not repairs:
            return
        self._counts.warned = True
        warnings.warn(repair_warning(repairs), NumericalWarning, stacklevel=3)

    def _buffers(self) -> GPBuffers:
        """The state buffers ``(BV, mu, S, R, alpha, mdiag)`` for the compiled steps."""
        return self._bv, self._mu, self._S, self._R, self._alpha, self._mdiag

    def _step_settings(self) -> StepSettings:
        """``(noise, tol, novelty floor, noise floor, max_bv)`` for the compiled steps."""
        c = self.config
        return (
            float(self.noise),
            float(self.tol),
            float(c.novelty_floor),
            float(c.noise_floor),
            int(self.max_bv),
        )

    def _scratch(self) -> Scratch:
        """``(work, T, counters)`` for the compiled steps."""
        return self._work, self._T, self._counts.step

    #: Scratch buffers: not part of the model's state.
    _SCRATCH = frozenset(
        {"_T", "_kbuf", "_work", "kernel", "config", "_factor_memo", "_batch", "_last_projected"}
    )

    @contextmanager
    def _all_or_nothing(self) -> Iterator[None]:
        """Restore the model (and a basis-tracking kernel's graph) if the body raises.

        The snapshot copies the state buffers (O(max_bv^2)) and, for a kernel that
        follows the basis set, the kernel's state (its graph): cheap next to a batch
        of updates; :meth:`update` (one row, the agents' per-step call) takes none.
        """
        state = {k: copy.deepcopy(v) for k, v in vars(self).items() if k not in self._SCRATCH}
        kernel = self.kernel
        kernel_state = None
        if kernel.tracks_basis:  # a copy starts unbound (Kernel.__getstate__)
            kernel_state = vars(copy.deepcopy(kernel))
        try:
            yield
        except BaseException:
            vars(self).update(state)
            if kernel_state is not None:
                vars(kernel).clear()
                vars(kernel).update(kernel_state)
                kernel.bind(self)  # the restored state is unbound; this GP owns the kernel
            raise

    def copy(self) -> Self:
        """An independent model in the same state, kernel (and its graph) included.

        Updates of the copy and of the original give the same numbers as they would
        on either alone (``copy.deepcopy``: every buffer copied bit for bit); the
        copied kernel is bound to the copy.
        """
        new = copy.deepcopy(self)  # the kernel's copy starts unbound (Kernel.__getstate__)
        new.kernel.bind(new)
        return new
