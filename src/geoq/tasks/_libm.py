"""Squares as the C library's ``pow`` computes them, elementwise: what scalar code gets.

Gymnasium's classic-control envs square *scalars*: ``thdot**2`` on a NumPy float64,
``u**2`` on a NumPy float32, ``math.pow(action[0], 2)`` on a Python float. NumPy's
scalar power and ``math.pow`` call the C library's ``pow`` / ``powf``. NumPy's
*array* power does not: ``x ** 2`` becomes ``x * x``, and ``np.power`` with an array
exponent runs SIMD kernels chosen by the CPU (measured with NumPy 2.4 on an AVX-512
machine: ``np.power`` differs from the scalar result in 2.7% of float64 and 11% of
float32 inputs, ``x * x`` in 0.08%: ``pow`` is accurate to about half a unit in the
last place, not correctly rounded). So a vectorised twin that must equal ``env.step``
bit for bit squares through ``pow`` itself.

:func:`libm_square` calls the C library's ``pow`` / ``powf`` from a compiled loop
(numba calling the function pointer that :mod:`ctypes` finds: the same function the
interpreter's scalars call). Where no C maths library can be found, it loops over
NumPy scalars, which is the scalar arithmetic itself, only slower.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from collections.abc import Callable
from typing import Any

import numba
import numpy as np

__all__ = ["libm_square", "scalar_square"]

_Loop = Callable[[np.ndarray, np.ndarray], None]


def scalar_square(x: np.ndarray) -> np.ndarray:
    """``v ** 2`` of every element ``v`` as a NumPy scalar, in ``x``'s dtype (the reference)."""
    x = np.asarray(x)
    flat = np.fromiter((v**2 for v in x.reshape(-1)), dtype=x.dtype, count=x.size)
    return flat.reshape(x.shape)


@functools.cache
def _c_pow() -> tuple[Any, Any] | None:
    """The C library's ``pow`` and ``powf`` as ctypes functions, or None if not found."""
    for name in ("m", "c", "ucrtbase", "msvcrt"):
        path = ctypes.util.find_library(name)
        if path is None:
            continue
        try:
            lib = ctypes.CDLL(path)
            c_pow, c_powf = lib.pow, lib.powf
        except (OSError, AttributeError):
            continue
        c_pow.argtypes, c_pow.restype = [ctypes.c_double, ctypes.c_double], ctypes.c_double
        c_powf.argtypes, c_powf.restype = [ctypes.c_float, ctypes.c_float], ctypes.c_float
        return c_pow, c_powf
    return None


@functools.cache
def _compiled_loops() -> dict[np.dtype, _Loop] | None:
    """``out[i] = pow(x[i], 2)`` loops for float64 and float32, compiled on first use
    (not cached on disk: the function pointers are the process's own)."""
    found = _c_pow()
    if found is None:
        return None
    c_pow, c_powf = found

    @numba.njit(nogil=True)
    def square64(x: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
        for i in range(x.size):
            out[i] = c_pow(x[i], 2.0)

    @numba.njit(nogil=True)
    def square32(x: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
        two = np.float32(2.0)
        for i in range(x.size):
            out[i] = c_powf(x[i], two)

    return {np.dtype(np.float64): square64, np.dtype(np.float32): square32}


def libm_square(x: np.ndarray) -> np.ndarray:
    """``pow(x, 2)`` elementwise in ``x``'s dtype (float64 or float32), shape of ``x``.

    Equal, bit for bit, to :func:`scalar_square` (NumPy's scalar ``v ** 2``) and, for
    float64, to ``math.pow(v, 2)``.
    """
    x = np.asarray(x)
    if x.dtype not in (np.float64, np.float32):
        raise TypeError(f"libm_square takes float64 or float32 arrays, not {x.dtype}")
    loops = _compiled_loops()
    if loops is None:
        return scalar_square(x)
    flat = np.ascontiguousarray(x).reshape(-1)
    out = np.empty_like(flat)
    loops[x.dtype](flat, out)
    return out.reshape(x.shape)
