"""Novelty measured under a positive-definite repair of the augmented Gram (beyond the paper).

With an indefinite kernel (the geodesic kernel of JC12 eq. 3) the novelty of a new
point, ``gamma = k(x, x) - k_x^T K_BV^{-1} k_x`` (TR eq. 3.16), can be negative:
the Gram of the BV set *with* ``x`` is indefinite. :class:`SparseOnlineGP` treats
such a point as "not novel" and projects it; on the pendulum this stops the
geodesic BV set at a few dozen points whatever the budget.

:class:`PDNoveltyOnlineGP` measures the novelty of ``x`` under a positive-definite
repair of that augmented Gram instead. In the coordinates whitened by the current
factor ``K_BV = R^T R`` (a congruence, so definiteness is unchanged) the augmented
Gram is ``[[I, v], [v^T, c]]`` with ``v = R^{-T} k_x`` and ``c = k(x, x)``; it differs
from the identity only on ``span(v, e_new)``, where it is the 2 x 2 block
``B = [[1, nu], [nu, c]]``, ``nu = |v|``, indefinite iff ``nu^2 > c``. Two repairs
of ``B``'s negative eigenvalue ``lambda_-``:

* *clipping* it to a floor ``f >= 0`` leaves a Schur complement (the novelty) of
  order ``f``: with the numerics floor (1e-10) the point is still below any useful
  ``tol`` and the BV set still does not grow (checked in the tests);
* *flipping* it to ``|lambda_-|`` (the "flip" repair of indefinite similarity
  matrices) gives the novelty :func:`flipped_novelty`
  ``(nu^2 - c) / (1 - 2 lambda_- u_1^2)``, of the order of ``|gamma|``.

This class uses the flip, against the positive-definite repair of the *current*
``K_BV``: the factor ``R`` is re-anchored on the kernel's own ``K_BV`` after every
change of the BV set (``resync_every = 1``: jitter, then eigenvalue clipping,
:func:`geoq.gp.numerics.clip_eigenvalues`; the posterior of ``f_BV`` is kept). The
step then runs with the prior variance ``|v|^2 + gamma_flip`` in place of
``k(x, x)`` (so its Cholesky pivot is ``gamma_flip``): ``K_BV`` and ``k_x`` are kept,
only the new diagonal entry is raised until the next re-anchoring, and the point
becomes a BV when ``gamma_flip >= tol * (|v|^2 + gamma_flip)``. Both parts are needed
(measured on the pendulum, 3 x 250 steps, budget 200): re-anchoring alone leaves the
``nearest`` BV set at 26 points, the flip against the incrementally updated factor
stops at 39 (the raised diagonals make the factor ill-conditioned, ``|v|^2`` reaches
1e19 and no relative novelty passes ``tol``), both together fill the budget. The
cost is an eigendecomposition of ``K_BV`` per BV change (about 19 s for a fit at
budget 200 on a busy 2-core machine, against 0.01 s for the default).

Points with ``gamma >= 0`` are untouched, so with a positive-definite kernel and the
same ``resync_every`` the result is that of :class:`SparseOnlineGP` bit for bit.

Only the per-point path has the hook; the compiled squared-exponential stream
(positive definite) is unchanged. :meth:`SparseOnlineGP.save` stores the state, not
the class: a reloaded GP predicts the same but updates with the default novelty.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import scipy.linalg

from geoq._typing import FloatArray
from geoq.gp.numerics import CONFIG, NumericsConfig
from geoq.gp.sparse_online import OnlineDiagnostics, SparseOnlineGP
from geoq.kernels.base import Kernel

__all__ = ["PDNoveltyOnlineGP", "flipped_novelty"]


def flipped_novelty(vv: float, c: float) -> float:
    """Novelty of the new point under the eigenvalue flip of ``B = [[1, nu], [nu, c]]``.

    ``vv = nu^2 = |R^{-T} k_x|^2``, ``c = k(x, x)``; for ``vv <= c`` (``B`` positive
    semi-definite) the plain novelty ``c - vv``. Otherwise, with ``lambda_- < 0`` and its
    unit eigenvector ``u``, ``|B| = B - 2 lambda_- u u^T`` and the novelty is its Schur
    complement ``det|B| / |B|_11 = (vv - c) / (1 - 2 lambda_- u_1^2)``.
    """
    if vv <= c:
        return c - vv
    disc = np.sqrt((1.0 - c) ** 2 + 4.0 * vv)
    lam = 0.5 * ((1.0 + c) - disc)  # < 0
    u1 = vv / (vv + (lam - 1.0) ** 2)  # u_1^2 of u ~ (nu, lambda_- - 1)
    return float((vv - c) / (1.0 - 2.0 * lam * u1))


class PDNoveltyOnlineGP(SparseOnlineGP):
    """:class:`SparseOnlineGP` whose novelty is measured under the flip repair (see module).

    Parameters as :class:`SparseOnlineGP`; ``resync_every`` defaults to 1 (re-anchor the
    factor of ``K_BV`` at every change of the BV set). ``diagnostics.negative_novelty``
    counts the repaired points (their novelty under the kernel was negative) on top of
    the step's own count; :attr:`novelty_flips` is the number repaired.
    """

    def __init__(
        self,
        kernel: Kernel,
        noise: float,
        max_bv: int,
        tol: float = 1e-6,
        *,
        resync_every: int | None = 1,
        config: NumericsConfig = CONFIG,
    ) -> None:
        super().__init__(kernel, noise, max_bv, tol, resync_every=resync_every, config=config)

    def _reset_state(self) -> None:
        super()._reset_state()
        self.novelty_flips = 0

    def _novelty_repair(self) -> Callable[[FloatArray, float, float, int], float] | None:
        def repair(k: FloatArray, scale: float, kxx: float, m: int) -> float:
            if m == 0 or not np.isfinite(kxx):
                return kxx
            kx = k[:m] * scale
            if not np.all(np.isfinite(kx)):
                return kxx  # the step reports it
            v = scipy.linalg.solve_triangular(self._R[:m, :m], kx, trans="T", check_finite=False)
            vv = float(v @ v)
            if vv <= kxx:
                return kxx
            self.novelty_flips += 1
            return vv + flipped_novelty(vv, kxx)

        return repair

    @property
    def diagnostics(self) -> OnlineDiagnostics:
        d = super().diagnostics
        return replace(d, negative_novelty=d.negative_novelty + self.novelty_flips)
