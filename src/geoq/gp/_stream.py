"""How a batch reaches the compiled step of :class:`~geoq.gp.SparseOnlineGP`.

Two drivers over the GP's state buffers, both ending in the same compiled step
(:mod:`geoq.gp._step`):

* a kernel that offers :meth:`~geoq.kernels.base.Kernel.se_parameters` streams
  through one compiled loop that also evaluates ``k_x`` (:func:`~geoq.gp._step.se_stream`);
* every other kernel (in particular basis-tracking ones, whose hooks Python must
  call between points) goes point by point: the covariance row from the kernel's
  fused compiled row (:meth:`~geoq.kernels.base.Kernel.fused_row`) or from
  ``to_basis``, then the step, then the kernel's ``basis_*`` hooks.

Both resync the GP every ``resync_every`` changes of its basis set.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from geoq._typing import FloatArray
from geoq.gp._nb_linalg import mirror_lower
from geoq.gp._state import OnlineGPState
from geoq.gp._step import online_step_lower, se_stream
from geoq.kernels.base import Kernel

__all__ = ["NoveltyRepair", "kernel_row", "se_loop_parameters", "stream"]

#: The per-point step's ``(k, scale, k(x, x), m) -> k(x, x)`` hook (``None``: the kernel's).
NoveltyRepair = Callable[[FloatArray, float, float, int], float]


def se_loop_parameters(
    kernel: Kernel, dim: int | None
) -> tuple[FloatArray, FloatArray, float] | None:
    """``(inv_ls [d], period [d], variance)`` if the compiled SE loop applies
    (the kernel offers :meth:`~geoq.kernels.base.Kernel.se_parameters`)."""
    params = kernel.se_parameters()
    if params is None or dim is None:
        return None
    lengthscale, period_or_none, variance = params
    inv_ls = np.broadcast_to(1.0 / np.asarray(lengthscale, dtype=np.float64), (dim,))
    period = np.zeros(dim) if period_or_none is None else np.asarray(period_or_none)
    return np.ascontiguousarray(inv_ls), np.ascontiguousarray(period), float(variance)


def stream(
    gp: OnlineGPState, X: FloatArray, y: FloatArray, *, resync: Callable[[], None],
    novelty_repair: Callable[[], NoveltyRepair | None],
) -> None:  # fmt: skip
    """Apply the rows of ``X`` [N, d], ``y`` [N] to ``gp``'s state in order (inputs
    validated). ``resync`` is the GP's resync of its whitened posterior (due every
    ``gp.resync_every`` changes of the basis set); ``novelty_repair`` gives the per-point
    step's hook (:meth:`geoq.gp.SparseOnlineGP._novelty_repair`)."""
    if X.shape[0] == 0:
        return
    gp._batch += 1  # a new batch: the factor memo's rounding tolerance holds inside it
    try:
        _stream_batch(gp, X, y, resync, novelty_repair)
    finally:
        gp._batch += 1


def _stream_batch(
    gp: OnlineGPState, X: FloatArray, y: FloatArray, resync: Callable[[], None],
    novelty_repair: Callable[[], NoveltyRepair | None],
) -> None:  # fmt: skip
    gp._set_dim(X.shape[1])
    fast = se_loop_parameters(gp.kernel, gp._dim)
    if fast is None:
        _stream_points(gp, X, y, resync, novelty_repair)
        return
    settings, state, scratch = gp._step_settings(), gp._buffers(), gp._scratch()
    t = 0
    while t < X.shape[0]:
        stop = gp.resync_every - gp._changes
        t, gp._m, changes = se_stream(
            X, y, t, fast, settings, state, gp._m, gp._kbuf, scratch, stop
        )
        gp._changes += changes
        if gp._changes >= gp.resync_every:
            resync()


def _stream_points(
    gp: OnlineGPState, X: FloatArray, y: FloatArray, resync: Callable[[], None],
    novelty_repair: Callable[[], NoveltyRepair | None],
) -> None:  # fmt: skip
    """Per-point path: kernel in Python, step compiled, hooks in between points.

    The steps keep ``S`` as its lower triangle (:func:`online_step_lower`); it is
    mirrored before a resync and when the batch ends (also on an error). A graph
    kernel's covariance row comes from its fused compiled path
    (``Kernel.fused_row``), else from ``to_basis``.
    """
    kernel = gp.kernel
    fused = kernel.fused_row()
    row_exponent, variance = (None, 1.0) if fused is None else fused
    S, kbuf, bv = gp._S, gp._kbuf, gp._bv
    settings, state, scratch = gp._step_settings(), gp._buffers(), gp._scratch()
    repair = novelty_repair()
    try:
        for x, yt in zip(X, y.tolist(), strict=True):
            m = gp._m
            expo = None if row_exponent is None else row_exponent(x, bv, m)
            if expo is not None:
                np.exp(expo, out=kbuf[:m])
                kxx = scale = variance
            else:
                kxx, scale = kernel_row(kernel, x, bv, m, kbuf), 1.0
            if repair is not None:
                kxx = repair(kbuf, scale, kxx, m)
            gp._m, added, deleted = online_step_lower(
                kbuf, scale, kxx, yt, x, settings, state, m, scratch
            )
            if added < 0:
                raise ValueError(f"kernel returned non-finite covariances at x={x}; check it")
            if added:
                kernel.basis_added(x.copy())
                if deleted >= 0:
                    kernel.basis_removed(int(deleted))
                    gp._changes += 2
                else:
                    gp._changes += 1
            if gp._changes >= gp.resync_every:
                mirror_lower(S, gp._m)
                resync()
    finally:
        mirror_lower(S, gp._m)


def kernel_row(kernel: Kernel, x: FloatArray, bv: FloatArray, m: int, out: FloatArray) -> float:
    """``k(x, BV[:m])`` into ``out[:m]`` by ``to_basis``; returns ``k(x, x)``."""
    kx = np.asarray(kernel.to_basis(x[None, :], bv[:m]), dtype=np.float64)
    kxx = np.asarray(kernel.diag(x[None, :]), dtype=np.float64)
    if kx.shape != (1, m) or kxx.shape != (1,):
        raise ValueError(
            f"kernel returned shapes {kx.shape} and {kxx.shape}; expected (1, {m}) and (1,)"
        )
    out[:m] = kx[0]
    return float(kxx[0])
