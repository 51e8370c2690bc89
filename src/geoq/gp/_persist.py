"""Saving and loading a :class:`~geoq.gp.SparseOnlineGP`: plain arrays, versioned, no pickle.

The public entry points are the GP's methods ``save``, ``load``, ``to_arrays`` and
``from_arrays``; this module holds the format and its migrations:

* version 1: eight step counters (no ``noise_floored``);
* version 2: counter ``noise_floored``;
* version 3: counter ``covariance_projections`` and the predict-time feature
  repair state (``predict_rescaled``, ``novelty_clipped_at_refit``). Files of
  versions 1 and 2 predicted with the raw features: they still do after loading.
"""

from __future__ import annotations

from collections.abc import Callable
from os import PathLike
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.linalg

from geoq._io import ArchiveError
from geoq.gp.diagnostics import COUNTER_NAMES, PYTHON_COUNTER_NAMES
from geoq.kernels.base import kernel_from_arrays, kernel_to_arrays

if TYPE_CHECKING:
    from geoq.gp.sparse_online import SparseOnlineGP

__all__ = ["FORMAT_KIND", "FORMAT_VERSION", "gp_from_arrays", "gp_to_arrays"]

FORMAT_KIND = "SparseOnlineGP"
#: 2: counter "noise_floored"; 3: counter "covariance_projections" and the predict-time
#: feature repair state (older files still load, with their original predictions)
FORMAT_VERSION = 3
_N_COUNTERS_V1 = 8


def gp_to_arrays(gp: SparseOnlineGP) -> dict[str, Any]:
    """The model (kernel included) as plain arrays, in the current format version."""
    m = gp._m
    counts = gp._counts
    arrays: dict[str, Any] = {
        "noise": np.float64(gp.noise),
        "max_bv": np.int64(gp.max_bv),
        "tol": np.float64(gp.tol),
        "resync_every": np.int64(gp.resync_every),
        "dim": np.int64(-1 if gp._dim is None else gp._dim),
        "basis_vectors": gp._bv[:m],
        "cholesky_factor": np.triu(gp._R[:m, :m]),
        "mu": gp._mu[:m],
        "S": gp._S[:m, :m],
        "score_alpha": gp._alpha[:m],
        "score_mdiag": gp._mdiag[:m],
        "counters": counts.step,
        "changes": np.int64(gp._changes),
        "warned": np.bool_(counts.warned),
    }
    for name in PYTHON_COUNTER_NAMES:
        arrays[f"extra.{name}"] = np.int64(counts.python[name])
    arrays["predict_clipped"] = np.int64(counts.predict_clipped)
    arrays["predict_rescaled"] = np.int64(counts.predict_rescaled)
    arrays["novelty_clipped_at_refit"] = np.int64(counts.novclip_at_refit)
    arrays["max_q_drift"] = np.float64(counts.max_q_drift)
    arrays.update(kernel_to_arrays(gp.kernel))
    return arrays


def gp_from_arrays(
    cls: type[SparseOnlineGP],
    a: dict[str, np.ndarray],
    version: int,
    source: str | PathLike[str],
) -> SparseOnlineGP:
    """Inverse of :func:`gp_to_arrays` for files of format ``version`` (1 ... current).

    Raises :class:`~geoq._io.ArchiveError` naming ``source`` on missing or
    inconsistent entries.
    """
    path = source
    get = _archive_getter(a, path)
    try:
        kernel = kernel_from_arrays(a)
    except (KeyError, ValueError, TypeError) as exc:
        raise ArchiveError(f"{path}: cannot rebuild the kernel ({exc})") from exc
    try:
        gp = cls(
            kernel,
            noise=float(get("noise", ())),
            max_bv=int(get("max_bv", ())),
            tol=float(get("tol", ())),
            resync_every=int(get("resync_every", ())),
        )
    except ValueError as exc:
        raise ArchiveError(f"{path}: invalid model parameters ({exc})") from exc
    dim = int(get("dim", ()))
    if kernel.input_dim is not None and dim != kernel.input_dim:
        raise ArchiveError(
            f"{path}: model dimension {dim} does not match the kernel's {kernel.input_dim}"
        )
    bv = get("basis_vectors", None)
    if bv.ndim != 2 or bv.shape[0] > gp.max_bv or (dim >= 0 and bv.shape[1] != dim):
        raise ArchiveError(f"{path}: basis_vectors has shape {bv.shape}; corrupt model")
    m = bv.shape[0]
    if not kernel.follows_basis(bv):
        raise ArchiveError(
            f"{path}: the kernel's graph nodes differ from basis_vectors; corrupt model"
        )
    if dim >= 0:
        gp._dim = dim
        gp._reset_state()
    gp._m = m
    gp._bv[:m] = bv
    R = get("cholesky_factor", (m, m))
    S = get("S", (m, m))
    if not (np.all(np.diag(R) > 0.0) and np.array_equal(R, np.triu(R))):
        raise ArchiveError(f"{path}: cholesky_factor is not upper triangular with a positive "
                           "diagonal; corrupt model")  # fmt: skip
    if not np.array_equal(S, S.T):
        raise ArchiveError(f"{path}: S is not symmetric; corrupt model")
    gp._R[:m, :m] = R
    gp._mu[:m] = get("mu", (m,))
    gp._S[:m, :m] = S
    gp._alpha[:m] = get("score_alpha", (m,))
    gp._mdiag[:m] = get("score_mdiag", (m,))
    _check_posterior(gp, path)
    counts = gp._counts
    counters = get("counters", None)
    n_old = _N_COUNTERS_V1 if version == 1 else len(COUNTER_NAMES)
    if counters.shape != (n_old,):
        raise ArchiveError(
            f"{path}: entry 'counters' has shape {counters.shape}, expected ({n_old},)"
        )
    counts.step[:n_old] = counters  # version 1 had no noise_floored counter
    gp._changes = int(get("changes", ()))
    counts.warned = bool(get("warned", ()))
    for name in PYTHON_COUNTER_NAMES:
        if version < 3 and name == "covariance_projections":
            continue  # not recorded before version 3
        counts.python[name] = int(get(f"extra.{name}", ()))
    counts.predict_clipped = int(get("predict_clipped", ()))
    if version >= 3:
        counts.predict_rescaled = int(get("predict_rescaled", ()))
        counts.novclip_at_refit = int(get("novelty_clipped_at_refit", ()))
    else:  # older files predicted with the raw features: keep their predictions
        counts.novclip_at_refit = counts.novelty_clipped_online
    counts.max_q_drift = float(get("max_q_drift", ()))
    return gp


#: Tolerances of the load-time invariants: far above rounding and the jitter policy's
#: largest jitter (1e-4 of the mean diagonal), far below any deliberate scaling.
_GRAM_RTOL = 1e-3
_WHITENED_TOL = 1e-4
_ALPHA_RTOL = 1e-4


def _check_posterior(gp: SparseOnlineGP, path: str | PathLike[str]) -> None:
    """Cheap invariants of a loaded posterior (O(m^3), m = number of BVs); ArchiveError if not.

    * a positive-definite kernel: ``R^T R`` reproduces ``K_BV`` of the stored basis
      vectors (a graph kernel that is indefinite keeps a factor of a repaired or
      earlier ``K_BV``: not checked);
    * the whitened posterior covariance satisfies ``0 <= S <= I`` (any posterior does);
    * the deletion scores' ``alpha`` satisfies ``R alpha = mu``.
    """
    m = gp._m
    if m == 0:
        return
    with np.errstate(over="ignore", invalid="ignore"):  # a tampered file: inf compares False
        _check_posterior_arrays(gp, m, path)


def _check_posterior_arrays(gp: SparseOnlineGP, m: int, path: str | PathLike[str]) -> None:
    R, S, mu = gp._R[:m, :m], gp._S[:m, :m], gp._mu[:m]
    if gp.kernel.positive_definite:
        K = np.asarray(gp.kernel.basis_gram(gp._bv[:m]), dtype=np.float64)
        scale = float(np.max(np.abs(np.diag(K)))) if np.all(np.isfinite(K)) else np.nan
        err = float(np.max(np.abs(R.T @ R - K))) if np.isfinite(scale) else np.inf
        if not err <= _GRAM_RTOL * scale:
            raise ArchiveError(
                f"{path}: cholesky_factor does not reproduce the kernel's K_BV of the stored "
                f"basis vectors (max error {err:.3g}, diagonal {scale:.3g}); tampered or "
                "corrupt model"
            )
    w = scipy.linalg.eigvalsh(S, check_finite=False)
    if not (w[0] >= -_WHITENED_TOL and w[-1] <= 1.0 + _WHITENED_TOL):
        raise ArchiveError(
            f"{path}: the whitened posterior covariance S has eigenvalues in "
            f"[{w[0]:.3g}, {w[-1]:.3g}], outside [0, 1] (no posterior has them); tampered or "
            "corrupt model"
        )
    residual = float(np.linalg.norm(R @ gp._alpha[:m] - mu))
    if not residual <= _ALPHA_RTOL * max(float(np.linalg.norm(mu)), 1e-300):
        raise ArchiveError(
            f"{path}: the posterior mean mu and the deletion scores' alpha disagree "
            f"(|R alpha - mu| = {residual:.3g}, |mu| = {float(np.linalg.norm(mu)):.3g}); "
            "tampered or corrupt model"
        )


def _archive_getter(
    arrays: dict[str, np.ndarray], path: str | PathLike[str]
) -> Callable[[str, tuple[int, ...] | None], np.ndarray]:
    """A reader of archive entries that raises :class:`ArchiveError` on anything odd."""

    def get(name: str, shape: tuple[int, ...] | None) -> np.ndarray:
        if name not in arrays:
            raise ArchiveError(f"{path}: entry {name!r} is missing; the file is corrupt")
        arr = arrays[name]
        if shape is not None and arr.shape != shape:
            raise ArchiveError(f"{path}: entry {name!r} has shape {arr.shape}, expected {shape}")
        if arr.dtype.kind in "fc" and not np.all(np.isfinite(arr)):
            raise ArchiveError(f"{path}: entry {name!r} contains NaN or inf; corrupt model")
        if arr.dtype.kind not in "fiub":
            raise ArchiveError(f"{path}: entry {name!r} has dtype {arr.dtype}; corrupt model")
        return arr

    return get
