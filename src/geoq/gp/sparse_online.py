"""The sparse online Gaussian process of Csató & Opper (2002).

Sign convention
---------------
The posterior process is kept on a basis-vector (BV) set ``x_1 ... x_m`` as::

    mean(x) = k_x^T alpha                     # [m] . [m]
    var(x)  = k(x, x) + k_x^T C k_x           # C [m, m], negative (semi-)definite

with ``k_x = [k(x_1, x), ..., k(x_m, x)]`` and ``Q = K_BV^{-1}`` [m, m]. With every
point kept (``max_bv >= N``, ``tol = 0``) this is the exact GP:
``alpha = (K + sigma0^2 I)^{-1} y`` and ``C = -(K + sigma0^2 I)^{-1}`` (note the minus:
Csató & Opper's convention, JC12 eq. 1 writes ``- k C k`` with ``C`` positive).

The update for one observation (``q``, ``r``, ``gamma``, the projection with
``eta = 1/(1 + gamma r)``, the full update and the KL-optimal deletion with score
``alpha_i^2 / (Q_ii + C_ii)``) is listed equation by equation, with the function that
computes each, in ``docs/equations.md``; the compiled implementation, citing
Csató & Opper (2002) as ``CO02`` and the Aston report NCRG/2001/014 as ``TR``, is
:mod:`geoq.gp._step`. The projected update with ``eta`` is the exact Bayes update
for the projected likelihood ``y ~ N(e_hat^T f_BV, sigma0^2)``, so on a fixed BV set
the online pass is the projected-process (DTC) posterior; :meth:`SparseOnlineGP.refit`
computes that posterior directly.

Numerical health
----------------
* ``Q = K_BV^{-1}`` is never formed. The state keeps the upper Cholesky factor
  ``R`` of ``K_BV`` (a column appended per added BV, a rank-one Cholesky update per
  deleted BV, O(m^2)) and ``diag(Q)`` (O(m) per change, for the deletion scores).
  Novelty is the Cholesky pivot ``gamma = k(x,x) - |R^{-T} k|^2``, accurate to
  rounding (an explicit inverse updated by rank-one terms is not:
  ``docs/design-notes.md``).
* Every ``resync_every`` changes of the BV set ``diag(Q)`` is recomputed exactly
  from ``R`` (the largest relative drift found is
  :attr:`OnlineDiagnostics.max_q_drift`), and for a basis-tracking kernel (whose
  ``K_BV`` changes as its graph grows) ``R`` is re-factorised from the current
  ``K_BV`` (when it comes back unchanged, ``diag(Q)`` is recomputed every
  ``max(64, 2 max_bv)`` resyncs only). Amortised cost O(m^2) per change.
* ``C`` is symmetric bit for bit (every update adds symmetric terms).
* Indefinite kernels (the geodesic kernel): negative novelty is treated as "not
  novel" and counted; below rounding level ``v = R^{-T} k_x`` is scaled onto
  ``|v|^2 = k(x, x)`` first (``novelty_clipped``; why: ``docs/design-notes.md``).
  An indefinite ``K_BV`` at a resync or refit goes through the jitter
  policy of :mod:`geoq.gp.numerics` and, if even that fails, eigenvalue clipping;
  negative predictive variances are clipped at 0. A noise variance below
  ``CONFIG.noise_floor * k(x, x)`` is raised to it in the updates
  (``noise_floored``). Every repair is counted in
  :attr:`SparseOnlineGP.diagnostics` and the first one is announced by a single
  :class:`~geoq.gp.numerics.NumericalWarning` per GP.
* A point with ``gamma < CONFIG.novelty_floor * k(x, x)`` never becomes a BV, so
  ``tol = 0`` with duplicated inputs is safe (and still exact: a duplicate lies in
  the span of the BVs, where the projection is exact).
"""

from __future__ import annotations

from os import PathLike
from typing import Any, Literal, overload

import numpy as np

from geoq._io import load_archive, save_archive
from geoq._threads import single_blas_thread, single_blas_thread_for_small_batches
from geoq._typing import ArrayLike, FloatArray
from geoq._validation import (
    as_input_point,
    as_inputs,
    as_target,
    as_targets,
    check_budget,
    check_count,
    check_novelty_tol,
    check_positive,
)
from geoq.gp._nb_delete import refresh_scores
from geoq.gp._persist import FORMAT_KIND, FORMAT_VERSION, gp_from_arrays, gp_to_arrays
from geoq.gp._predict import FACTOR_ROUTE_MIN, predict_chunked, predict_factored
from geoq.gp._resync import (
    ProjectedSystem,
    factor_gram,
    projected_system,
    reanchor,
)
from geoq.gp._state import OnlineGPState
from geoq.gp._stream import NoveltyRepair, stream
from geoq.gp.diagnostics import OnlineDiagnostics
from geoq.gp.numerics import (
    CONFIG,
    NumericsConfig,
    robust_cholesky,
)
from geoq.kernels.base import Kernel

# OnlineDiagnostics and robust_cholesky live in geoq.gp.diagnostics and geoq.gp.numerics;
# they stay importable from here.
__all__ = ["OnlineDiagnostics", "SparseOnlineGP", "robust_cholesky"]


class SparseOnlineGP(OnlineGPState):
    """Sparse online GP regression (Csató & Opper 2002) with a basis-vector budget.

    Parameters
    ----------
    kernel : covariance function; the GP talks to it only through the protocol of
        :class:`~geoq.kernels.base.Kernel` (``diag``, ``to_basis``, ``basis_gram``,
        the ``basis_*`` hooks and the optional ``fused_row`` / ``se_parameters``).
    noise : observation-noise *variance* ``sigma0^2`` (> 0).
    max_bv : basis-vector budget (integer in ``[1, MAX_BUDGET]``, 5000).
    tol : relative novelty threshold: ``x`` becomes a BV iff ``gamma >= tol * k(x, x)``.
    resync_every : BV-set changes between exact refreshes of the deletion scores
        (and re-factorisations of ``K_BV`` for basis-tracking kernels); default
        ``max(64, 2 * max_bv)`` (amortised O(max_bv^2) per change), and 1 for a
        positive-definite basis-tracking kernel (O(m^3) per change), whose ``K_BV``
        changes with its graph (a stale factor made its novelty and online MSE
        useless); for an indefinite graph kernel (geodesic) keeping the factor
        current did not help, so it gets the interval of ordinary kernels. The
        measurements behind both choices: ``docs/design-notes.md``.
    config : numerics constants (jitter policy, novelty floor).

    Notes
    -----
    A kernel that offers ``se_parameters`` streams through one compiled loop that
    evaluates ``k_x`` in numba; every other kernel (in particular basis-tracking
    ones, whose hooks Python must call between points) goes through the per-point
    path (:mod:`geoq.gp._stream`). Both use the same compiled step.
    """

    def __init__(
        self,
        kernel: Kernel,
        noise: float,
        max_bv: int,
        tol: float = 1e-6,
        *,
        resync_every: int | None = None,
        config: NumericsConfig = CONFIG,
    ) -> None:
        if not isinstance(kernel, Kernel):
            raise ValueError(f"kernel must be a geoq Kernel, got {type(kernel).__name__}")
        kernel.bind(self)  # a graph kernel serves one GP only
        self.kernel = kernel
        self.noise = check_positive(noise, "noise")
        self.max_bv = check_budget(max_bv)
        self.tol = check_novelty_tol(tol)
        if resync_every is None:
            resync_every = (
                1 if kernel.tracks_basis and kernel.positive_definite else max(64, 2 * self.max_bv)
            )
        self.resync_every = check_count(resync_every, "resync_every")
        self.config = config
        self._dim: int | None = kernel.input_dim
        self._reset_state()

    # ------------------------------------------------------------ validation
    # update, fit, partial_fit, refit and predict accept what geoq._validation's
    # as_inputs / as_targets accept, checked for the whole batch before anything changes.
    def _check_X(self, X: ArrayLike, name: str = "X", dim: int | None = -1) -> FloatArray:
        return as_inputs(X, name, self._dim if dim == -1 else dim)

    def _check_Xy(
        self, X: ArrayLike, y: ArrayLike, dim: int | None = -1
    ) -> tuple[FloatArray, FloatArray]:
        Xa = self._check_X(X, "X", dim)
        return Xa, as_targets(y, Xa.shape[0])

    # --------------------------------------------------------------- updates
    def update(self, x: ArrayLike, y: float) -> SparseOnlineGP:
        """Process one observation ``(x [d], y)``; returns ``self``.

        A rejected input (wrong shape, NaN/inf) raises ``ValueError`` and leaves
        the model unchanged.
        """
        xa, ya = as_input_point(x, self._dim), as_target(y)
        self._stream(xa[None, :], ya.reshape(1))
        self._warn_once()
        return self

    @single_blas_thread  # small matrices: one BLAS thread (geoq._threads)
    def fit(self, X: ArrayLike, y: ArrayLike) -> SparseOnlineGP:
        """Reset to the prior (empty BV set), then stream the rows of ``X`` [N, d], ``y`` [N].

        All or nothing: the whole batch is validated first, and a failure part-way
        through (e.g. the kernel returns NaN for some row, or Ctrl-C) restores the
        model and its kernel to what they were before the call.
        """
        if self.kernel.input_dim is None:
            Xa, ya = self._check_Xy(X, y, dim=None)  # a new fit may change the dimension
        else:
            Xa, ya = self._check_Xy(X, y)
        with self._all_or_nothing():
            if self.kernel.input_dim is None:
                self._dim = None
            self._reset_state()
            self.kernel.basis_cleared()
            self._stream(Xa, ya)
        self._warn_once()  # after the batch: a warning turned into an error undoes nothing
        return self

    @single_blas_thread  # small matrices: one BLAS thread (geoq._threads)
    def partial_fit(self, X: ArrayLike, y: ArrayLike) -> SparseOnlineGP:
        """Stream the rows of ``X`` [N, d], ``y`` [N] in order, without resetting.

        All or nothing, as :meth:`fit`: either every row is applied or none is.
        """
        Xa, ya = self._check_Xy(X, y)
        if Xa.shape[0] == 0:
            return self
        with self._all_or_nothing():
            self._stream(Xa, ya)
        self._warn_once()
        return self

    def _stream(self, X: FloatArray, y: FloatArray) -> None:
        """Apply ``X`` [N, d], ``y`` [N] in order (:func:`geoq.gp._stream.stream`)."""
        stream(self, X, y, resync=self._resync_q, novelty_repair=self._novelty_repair)

    def _novelty_repair(self) -> NoveltyRepair | None:
        """Hook of the per-point path: ``(k, scale, k(x, x), m) -> k(x, x)`` used by the step.

        ``None`` here (the step sees the kernel's ``k(x, x)``); a subclass may return the
        prior variance under which the novelty of ``x`` is measured
        (:class:`geoq.gp.pd_novelty.PDNoveltyOnlineGP`).
        """
        return None

    # ------------------------------------------------------- resync / refit
    def _factor_gram(self, batch: int | None = None) -> FloatArray:
        """Upper factor ``R`` [m, m] of the current ``K_BV`` (read-only; the memo of
        :func:`~geoq.gp._resync.factor_gram` is this GP's), repairs counted; ``batch``:
        the batch of updates of a resync."""
        R, jit, clips, self._factor_memo = factor_gram(
            self.kernel, self._bv[: self._m], self.config, self._factor_memo, batch
        )
        self._counts.python["jitter_events"] += jit
        self._counts.python["eig_clips"] += clips
        return R

    def _current_factor(self) -> FloatArray:
        """:meth:`_factor_gram` without counting its repairs (they were counted once)."""
        R, _, _, self._factor_memo = factor_gram(
            self.kernel, self._bv[: self._m], self.config, self._factor_memo
        )
        return R

    def _refresh_scores(self, record_drift: bool = True) -> None:
        """Recompute ``alpha = R^{-1} mu`` and ``diag(Q + C) = diag(R^{-1} S R^{-T})`` exactly.

        Compiled and single-threaded (:func:`~geoq.gp._nb_delete.refresh_scores`; why:
        ``docs/design-notes.md``).
        """
        Z = np.empty_like(self._T)
        drift = refresh_scores(
            self._R, self._mu, self._S, self._m, self._alpha, self._mdiag, Z, self._T
        )
        if record_drift:
            self._counts.max_q_drift = max(self._counts.max_q_drift, drift)

    @property
    def score_refresh_every(self) -> int:
        """Resyncs between exact refreshes of the deletion scores when a basis-tracking
        kernel's factor did not change (``max(64, 2 max_bv)``, the interval of other
        kernels' refreshes)."""
        return max(64, 2 * self.max_bv)

    def _factor_unchanged(self, R_new: FloatArray) -> bool:
        """Whether ``R_new`` is the factor in the state bit for bit (finite state): the
        GP added a point and deleted it again, and the kernel's ``K_BV`` came back with
        its graph (about half of a ``resistance`` fit's resyncs at its budget)."""
        m = self._m
        return (
            np.array_equal(self._R[:m, :m], R_new)
            and bool(np.isfinite(self._mu[:m]).all())
            and bool(np.isfinite(self._S[:m, :m]).all())
        )

    @single_blas_thread  # per change with a resistance kernel: limit here, not per update
    def _resync_q(self) -> None:
        """Refresh the deletion scores exactly; re-anchor ``R`` for basis-tracking kernels.

        A basis-tracking kernel changes ``K_BV`` between BVs as it learns (the graph
        grows): ``R`` is re-factorised from the current ``K_BV`` and the whitened
        posterior is transformed so that the posterior of ``f_BV`` (mean ``R^T mu``,
        covariance ``R^T S R``) is unchanged. For other kernels the factor updates
        are backward stable and only the O(m)-updated scores accumulate rounding.
        A factor that came back unchanged bit for bit (a point added and deleted again)
        leaves the posterior as the updates left it (Bayes updates on that prior: no
        re-anchoring, nothing to project) and the scores refreshed every
        :attr:`score_refresh_every` resyncs (``docs/design-notes.md``).
        The projection that follows starts with the full eigendecomposition when the
        last one of the same batch projected more than an eighth of the spectrum
        (:func:`~geoq.gp.numerics.project_whitened_covariance`; consecutive counts
        are alike: ``docs/design-notes.md``).
        """
        self._changes = 0
        m = self._m
        if m == 0:
            return
        if self.kernel.tracks_basis:
            R_new = self._factor_gram(self._batch)
            if self._factor_unchanged(R_new):
                # The steps since the last re-anchoring were Bayes updates on this prior:
                # 0 <= S <= I holds to rounding, and the scores' O(m) updates drift as
                # those of any kernel, refreshed every ``score_refresh_every`` resyncs.
                self._counts.python["q_resyncs"] += 1
                self._last_projected = (self._batch, 0)  # as a projection that found none
                if self._counts.python["q_resyncs"] % self.score_refresh_every == 0:
                    self._refresh_scores()
                return
            batch, last = self._last_projected
            self._mu[:m], self._S[:m, :m], projected = reanchor(
                self._R[:m, :m],
                R_new,
                self._mu[:m],
                self._S[:m, :m],
                many_above_one=batch == self._batch and 8 * last > m,
            )
            self._last_projected = (self._batch, projected)
            self._counts.python["covariance_projections"] += projected
            self._R[:m, :m] = R_new
        self._refresh_scores()
        self._counts.python["q_resyncs"] += 1

    @single_blas_thread  # small matrices: one BLAS thread (geoq._threads)
    def refit(self, X: ArrayLike, y: ArrayLike) -> SparseOnlineGP:
        """Projected-process (DTC) posterior on the current BV set with the current kernel.

        With ``K_BV = L L^T`` (``L = R^T``), ``V = L^{-1} K_BX`` [m, N] and
        ``B = sigma0^2 I + V V^T`` the whitened posterior is::

            mu = B^{-1} V y,    S = sigma0^2 B^{-1}

        i.e. ``alpha = (sigma0^2 K_BV + K_BX K_XB)^{-1} K_BX y`` and
        ``C = -K_BV^{-1} + (K_BV + K_BX K_XB / sigma0^2)^{-1}``: exactly the result of
        the online pass had this BV set and kernel been fixed from the start (every
        point projected, TR eq. 3.17-3.19). ``R`` is re-factorised from the current
        ``K_BV`` (``Q = K_BV^{-1}``). Returns ``self``.
        """
        Xa, ya = self._check_Xy(X, y)
        with self._all_or_nothing():  # a failed refit changes nothing, counters included
            self._refit(Xa, ya)
        self._warn_once()
        return self

    def _refit(self, Xa: FloatArray, ya: FloatArray) -> None:
        if self._m == 0:
            self._counts.python["refits"] += 1
            return
        self._install(self._projected_system(Xa), ya)

    @single_blas_thread  # small matrices: one BLAS thread (geoq._threads)
    def projected_system(self, X: ArrayLike) -> ProjectedSystem:
        """The projected-process system of inputs ``X`` [N, d] on the current BV set and
        kernel: :meth:`refit` without its targets (:class:`~geoq.gp.ProjectedSystem`:
        ``V = R^{-T} K_BX``, ``B^{-1}``, the posterior and mean weights of any targets).

        For many targets on the same inputs (fitted Q-iteration): form it once, then
        :meth:`refit_projected` installs the posterior of the chosen targets, the same
        bits as ``refit(X, y)``. Raises ``ValueError`` on an empty BV set.
        """
        Xa = self._check_X(X)
        if self._m == 0:
            raise ValueError("projected_system needs at least one basis vector; update first")
        return self._projected_system(Xa)

    def _projected_system(self, Xa: FloatArray) -> ProjectedSystem:
        R = self._factor_gram()  # [m, m] upper
        return projected_system(self.kernel, Xa, self._bv[: self._m], R, self.noise, self.config)

    @single_blas_thread  # small matrices: one BLAS thread (geoq._threads)
    def refit_projected(self, system: ProjectedSystem, y: ArrayLike) -> SparseOnlineGP:
        """:meth:`refit` to targets ``y`` [N] of a system from :meth:`projected_system`.

        The system must have been formed on this GP's current BV set and ``K_BV`` (no
        update in between): otherwise ``ValueError``. Returns ``self``.
        """
        m = self._m
        ya = as_targets(y, system.n_inputs)
        if (
            system.basis.shape != (m, self._bv.shape[1])
            or not np.array_equal(system.basis, self._bv[:m])
            or system.noise != self.noise
            or system.config != self.config
            or not np.array_equal(system.R, self._current_factor())
        ):
            raise ValueError(
                "this projected system was formed on another basis set, K_BV or noise: "
                "call projected_system again after the last update"
            )
        with self._all_or_nothing():
            self._install(system, ya)
        self._warn_once()
        return self

    def _install(self, system: ProjectedSystem, ya: FloatArray) -> None:
        """The DTC posterior of ``ya`` on ``system`` becomes the GP's state."""
        m = self._m
        mu, S = system.posterior(ya)
        self._counts.python["jitter_events"] += system.jitter_events
        self._counts.python["eig_clips"] += system.eig_clips
        self._R[:m, :m] = system.R
        self._mu[:m] = mu
        self._S[:m, :m] = S
        self._changes = 0
        self._counts.novclip_at_refit = self._counts.novelty_clipped_online  # raw features now
        self._refresh_scores(record_drift=False)  # a new posterior: nothing to compare with
        self._counts.python["refits"] += 1  # counted once it has happened

    # ------------------------------------------------------------ prediction
    @overload
    def predict(self, X: ArrayLike, return_std: Literal[False] = ...) -> FloatArray: ...
    @overload
    def predict(self, X: ArrayLike, return_std: Literal[True]) -> tuple[FloatArray, FloatArray]: ...
    @single_blas_thread_for_small_batches  # geoq._threads
    def predict(
        self, X: ArrayLike, return_std: bool = False
    ) -> FloatArray | tuple[FloatArray, FloatArray]:
        """Posterior mean ``[N]`` (and std ``[N]`` of the latent f, noise excluded).

        With ``V = R^{-T} K_BX`` [m, N]: ``mean = V^T mu`` and
        ``var = (diag K_XX - |V|^2) + diag(V^T S V)`` (prior residual + whitened
        posterior term, both non-negative for a PD kernel), clipped at 0. If the
        online updates since the last :meth:`refit` had to repair negative novelty
        (an indefinite kernel), test points get the same repair: a column of ``V``
        with ``|v|^2 > k(x, x)`` is scaled onto ``|v|^2 = k(x, x)`` (counted in
        ``diagnostics.novelty_clipped``).
        """
        Xa = self._check_X(X)
        n, m = Xa.shape[0], self._m
        if m == 0:  # the prior (the input dimension may not be known yet)
            prior = np.asarray(self.kernel.diag(Xa), dtype=np.float64)
            return (np.zeros(n), np.sqrt(np.maximum(prior, 0.0))) if return_std else np.zeros(n)
        mean = np.empty(n)
        std = np.empty(n) if return_std else None
        R, S = self._R[:m, :m], self._S[:m, :m]  # strided views of the [cap, cap] buffers
        mu, bv = self._mu[:m], self._bv[:m]
        repaired = self._counts.features_repaired
        if n >= FACTOR_ROUTE_MIN * m and not repaired:
            # Contiguous copies: LAPACK's O(m^3) set-up on strided views is slow.
            R, S = np.ascontiguousarray(R), np.ascontiguousarray(S)
            predict_factored(self.kernel, Xa, R, S, mu, bv, mean, std, self._counts)
        else:  # a solve per chunk: copying the buffers would cost more than it saves
            predict_chunked(self.kernel, Xa, R, S, mu, bv, mean, std, repaired, self._counts)
        if std is None:
            return mean
        self._warn_once()
        return mean, std

    # ----------------------------------------------------------- persistence
    def save(self, path: str | PathLike[str]) -> None:
        """Save the model (kernel included) as a versioned ``.npz`` without pickle."""
        save_archive(path, FORMAT_KIND, FORMAT_VERSION, self.to_arrays())

    def to_arrays(self) -> dict[str, Any]:
        """The model (kernel included) as plain arrays: what :meth:`save` writes.

        For embedding a GP in a larger archive (e.g. an agent's), in the current
        format version; :meth:`from_arrays` reads it back. The format and its
        migrations live in :mod:`geoq.gp._persist`.
        """
        return gp_to_arrays(self)

    @classmethod
    def load(cls, path: str | PathLike[str]) -> SparseOnlineGP:
        """Load a model written by :meth:`save` (basis hooks are *not* replayed)."""
        version, a = load_archive(path, FORMAT_KIND, FORMAT_VERSION)
        return cls.from_arrays(a, version=version, source=path)

    @classmethod
    def from_arrays(
        cls,
        a: dict[str, np.ndarray],
        *,
        version: int = 0,
        source: str | PathLike[str] = "<arrays>",
    ) -> SparseOnlineGP:
        """Inverse of :meth:`to_arrays`; ``version`` of the format (default: the current one).

        Raises :class:`~geoq._io.ArchiveError` naming ``source`` on missing or
        inconsistent entries.
        """
        return gp_from_arrays(cls, a, version or FORMAT_VERSION, source)

    def get_params(self) -> dict[str, Any]:
        """Constructor parameters (kernel, noise, max_bv, tol, resync_every)."""
        return {
            "kernel": self.kernel,
            "noise": self.noise,
            "max_bv": self.max_bv,
            "tol": self.tol,
            "resync_every": self.resync_every,
        }

    def __repr__(self) -> str:
        return (
            f"SparseOnlineGP(kernel={self.kernel!r}, noise={self.noise:g}, "
            f"max_bv={self.max_bv}, tol={self.tol:g}, n_bv={self._m})"
        )
