"""Compiled (numba) posterior means of every output of a :class:`~geoq.models.GPDynamicsModel`.

``mean[p, j] = variance_j sum_i alpha_ji exp(-|x_p / l_j - b_ji|^2 / 2)`` over output
``j``'s own basis vectors ``b_ji`` (already divided by its length-scales ``l_j``),
stored one output after another (``offsets``): no padding, and no ``[J, P, m]`` arrays.
Terms past ``_FAR`` are dropped.
A planner's roll-outs ask only for means (their halts come from the data's support,
not from the GPs' variances), so this is its inner loop.
"""

from __future__ import annotations

import math

from numba import njit

from geoq._typing import FloatArray, IntArray

__all__ = ["posterior_means", "posterior_means_and_gradients"]

#: A basis vector this far (squared, in length-scales) adds less than ``e^-30 = 1e-13``
#: of its weight: skipped, which spares most of the exponentials where length-scales
#: are short.
_FAR = 60.0


@njit(cache=True, fastmath=True)
def posterior_means(
    X: FloatArray, inv_ls: FloatArray, basis: FloatArray, offsets: IntArray,
    alpha: FloatArray, variance: FloatArray, out: FloatArray,
) -> None:  # pragma: no cover - compiled  # fmt: skip
    """``out`` [P, J] = the means of standardised inputs ``X`` [P, D] (module docstring);
    ``inv_ls`` [J, D], ``basis`` [M, D], ``offsets`` [J + 1], ``alpha`` [M], ``variance`` [J]."""
    P, D = X.shape
    J = inv_ls.shape[0]
    z = X[0].copy()
    for p in range(P):
        x = X[p]
        for j in range(J):
            ls = inv_ls[j]
            for k in range(D):
                z[k] = x[k] * ls[k]
            acc = 0.0
            for i in range(offsets[j], offsets[j + 1]):
                b = basis[i]
                d2 = 0.0
                for k in range(D):
                    diff = z[k] - b[k]
                    d2 += diff * diff
                if d2 < _FAR:
                    acc += alpha[i] * math.exp(-0.5 * d2)
            out[p, j] = variance[j] * acc


@njit(cache=True, fastmath=True)
def posterior_means_and_gradients(
    X: FloatArray, inv_ls: FloatArray, basis: FloatArray, offsets: IntArray,
    alpha: FloatArray, variance: FloatArray, out: FloatArray, grad: FloatArray,
) -> None:  # pragma: no cover - compiled  # fmt: skip
    """:func:`posterior_means` into ``out`` [P, J] and their gradients ``grad`` [P, J, D]
    with respect to ``X``: ``d mean[p, j] / d X[p, k] = -variance_j inv_ls[j, k] sum_i
    alpha_ji e_ji (z_k - b_jik)`` with ``z = X[p] inv_ls[j]`` and ``e_ji`` the term's
    exponential (the same terms dropped)."""
    P, D = X.shape
    J = inv_ls.shape[0]
    z = X[0].copy()
    g = X[0].copy()
    for p in range(P):
        x = X[p]
        for j in range(J):
            ls = inv_ls[j]
            for k in range(D):
                z[k] = x[k] * ls[k]
                g[k] = 0.0
            acc = 0.0
            for i in range(offsets[j], offsets[j + 1]):
                b = basis[i]
                d2 = 0.0
                for k in range(D):
                    diff = z[k] - b[k]
                    d2 += diff * diff
                if d2 < _FAR:
                    w = alpha[i] * math.exp(-0.5 * d2)
                    acc += w
                    for k in range(D):
                        g[k] -= w * (z[k] - b[k])
            out[p, j] = variance[j] * acc
            for k in range(D):
                grad[p, j, k] = variance[j] * g[k] * ls[k]
