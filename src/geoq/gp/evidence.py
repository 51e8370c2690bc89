"""Type-II maximum likelihood (evidence maximisation) of squared-exponential hyper-parameters.

The paper (JC12 §3) sets the kernel's hyper-parameters by maximising the evidence
of the exact GP; we do the same on a random subsample of at most ``max_points``
points. With ``K_y = variance * K_l + noise * I`` and ``alpha = K_y^{-1} y``
(Rasmussen & Williams 2006 -- ``RW06`` -- eqs. 5.8 and 5.9)::

    log p(y | X, theta) = -y^T alpha / 2 - log|K_y| / 2 - N log(2 pi) / 2
    d log p / d theta_j = tr((alpha alpha^T - K_y^{-1}) dK_y/dtheta_j) / 2

The parameters are optimised in log space, ``theta = log(lengthscale_1..d,
variance, noise)``, by L-BFGS-B with the analytic gradient above, within the
box :data:`LOG_BOUNDS`.

How the fit avoids stalling (issue 14)
--------------------------------------
* The objective is finite everywhere in the box. It used to return ``(inf, 0)``
  where ``K_y`` failed a Cholesky (at 7 of the 64 corners of the box on the data
  of issue 14), which made L-BFGS-B's line search fall back to the start and
  report convergence. The squared distances are now summed from exact
  per-dimension differences (``|a|^2 + |b|^2 - 2 a.b`` cancelled badly when short
  length-scales blew the inputs up, and made ``K_l`` indefinite), and a ``K_y``
  that is still numerically indefinite is factorised with the jitter policy of
  :func:`geoq.gp.numerics.safe_cholesky`: the evidence and gradient are then those
  of the jittered matrix.
* The default start is data-driven: per input dimension, the median of the
  pairwise distances between the points (the "median heuristic"); the prior
  variance ``var(y)``; the noise ``var(y) / 10``.
* ``n_restarts`` further starts are drawn with the caller's ``rng``: each
  log-parameter log-uniformly within a factor :data:`RESTART_FACTOR` of the
  data-driven start. The best end point wins; a given seed gives the same fit.
* ``converged`` is true only when the winning run's optimiser reported success,
  the evidence rose above its start and the projected gradient is small (a
  local optimum of the box-constrained problem).
* A :class:`~geoq.gp.numerics.NumericalWarning` is emitted when the fit ends at
  a bound of the box or at its starting point, or did not converge.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize
from threadpoolctl import threadpool_limits

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import as_float_matrix, as_float_vector, check_positive
from geoq.gp.numerics import CONFIG, NumericalWarning, NumericsConfig, safe_cholesky
from geoq.kernels.base import Kernel
from geoq.kernels.stationary import SquaredExponential

__all__ = [
    "LOG_BOUNDS",
    "RESTART_FACTOR",
    "EvidenceFit",
    "fit_squared_exponential",
    "log_marginal_likelihood",
    "median_lengthscales",
]

#: Bounds of the log-parameters: one length-scale (per dimension), variance, noise.
LOG_BOUNDS: dict[str, tuple[float, float]] = {
    "lengthscale": (float(np.log(1e-3)), float(np.log(1e3))),
    "variance": (float(np.log(1e-4)), float(np.log(1e4))),
    "noise": (float(np.log(1e-6)), float(np.log(1e2))),
}
#: Restarts draw every parameter log-uniformly within this factor of the data-driven start.
RESTART_FACTOR = 10.0
#: A log-parameter this close to a bound is "at the bound"; a fit whose winning run moved
#: every log-parameter less than this "ended at its start".
_AT_TOL = 1e-4
#: Largest projected gradient (per point of the data) of a local optimum.
_PGTOL_PER_POINT = 1e-4


@dataclass(frozen=True)
class EvidenceFit:
    """Result of :func:`fit_squared_exponential`.

    Attributes
    ----------
    kernel : the fitted :class:`SquaredExponential` (``.lengthscale``, ``.variance``).
    noise : fitted observation-noise variance ``sigma0^2``.
    log_evidence : ``log p(y | X)`` at the optimum, on the ``n_used`` points.
    n_used : number of points the evidence was computed on.
    converged : the winning run's optimiser reported success, the evidence rose
        above that run's start, and the projected gradient is small (a local optimum).
        A fit started exactly at an optimum has made no progress and reports False.
    message : the winning run's optimiser message.
    log_evidence_start : ``log p(y | X)`` at the first start (data-driven, or the caller's).
    n_restarts : number of starts beyond the first.
    log_evidence_runs : [n_restarts + 1] log evidence each run ended at (the first
        start first); a wide spread means several local optima.
    best_run : index into ``log_evidence_runs`` of the winning run.
    at_bound : names of the parameters that ended at a bound of :data:`LOG_BOUNDS`,
        e.g. ``("lengthscale[2] upper",)``; an input whose length-scale ends at the
        upper bound barely matters to the evidence.
    """

    kernel: SquaredExponential
    noise: float
    log_evidence: float
    n_used: int
    converged: bool
    message: str
    log_evidence_start: float
    n_restarts: int
    log_evidence_runs: tuple[float, ...]
    best_run: int
    at_bound: tuple[str, ...]


def log_marginal_likelihood(
    kernel: Kernel, noise: float, X: ArrayLike, y: ArrayLike, *, config: NumericsConfig = CONFIG
) -> float:
    """``log p(y | X)`` of the exact GP with ``kernel`` and noise variance ``noise`` (RW06 eq. 5.8).

    ``X`` is [N, d], ``y`` is [N].
    """
    noise = check_positive(noise, "noise")
    Xa = as_float_matrix(X, "X", kernel.input_dim)
    ya = as_float_vector(y, "y", Xa.shape[0])
    K = kernel(Xa)  # [N, N]
    K[np.diag_indices_from(K)] += noise
    with threadpool_limits(limits=1, user_api="blas"):
        L, _ = safe_cholesky(K, config=config, what="K + noise I")
        alpha = scipy.linalg.cho_solve((L, True), ya, check_finite=False)
    n = ya.shape[0]
    return float(-0.5 * ya @ alpha - np.sum(np.log(np.diag(L))) - 0.5 * n * np.log(2.0 * np.pi))


def median_lengthscales(X: ArrayLike, ard: bool = True) -> FloatArray:
    """Median pairwise distance between the rows of ``X``: the data-driven length-scale.

    ``X`` is [N, d]. Returns [d] (per dimension, ``ard=True``) or [1] (Euclidean).
    Pairs at distance zero (repeated values, e.g. clipped actions) are left out; a
    dimension with a single value gets 1.0.
    """
    Xa = as_float_matrix(X, "X")
    iu = np.triu_indices(Xa.shape[0], 1)
    if ard:
        dist = np.abs(Xa[iu[0]] - Xa[iu[1]])  # [P, d]
    else:
        dist = np.linalg.norm(Xa[iu[0]] - Xa[iu[1]], axis=1)[:, None]  # [P, 1]
    out = np.ones(dist.shape[1])
    for k in range(dist.shape[1]):
        nonzero = dist[:, k][dist[:, k] > 0]
        if nonzero.size:
            out[k] = float(np.median(nonzero))
    return out


class _Objective:
    """``-log p(y | X, theta)`` and its gradient, with the pairwise squared
    differences of ``X`` computed once.

    ``theta = log(lengthscale_1..n_ls, variance, noise)`` with ``n_ls = d`` (ARD)
    or 1; the cache holds ``n_ls N^2`` floats. Never returns ``inf``: a ``K_y``
    that is numerically indefinite is factorised with the jitter policy, and the
    value and gradient are those of the jittered matrix.
    """

    def __init__(
        self, X: FloatArray, y: FloatArray, ard: bool, config: NumericsConfig = CONFIG
    ) -> None:
        self.X = X  # [N, d]
        self.y = y  # [N]
        self.config = config
        if ard:  # one dimension at a time: no [N, N, d] intermediate beside the cache
            self.D2 = np.empty((X.shape[1], X.shape[0], X.shape[0]))  # [d, N, N]
            for k in range(X.shape[1]):
                self.D2[k] = (X[:, None, k] - X[None, :, k]) ** 2
        else:
            self.D2 = ((X[:, None, :] - X[None, :, :]) ** 2).sum(axis=2)[None]  # [1, N, N]

    def __call__(self, theta: FloatArray) -> tuple[float, FloatArray]:
        n_ls = self.D2.shape[0]
        inv_l2 = np.exp(-2.0 * theta[:n_ls])  # [n_ls]
        variance, noise = np.exp(theta[n_ls]), np.exp(theta[n_ls + 1])
        r2 = np.tensordot(inv_l2, self.D2, axes=1)  # [N, N]
        VK = variance * np.exp(-0.5 * r2)  # [N, N]
        K_y = VK.copy()
        K_y[np.diag_indices_from(K_y)] += noise
        with warnings.catch_warnings():
            # Jitter inside the optimiser is routine; the final fit is checked once.
            warnings.simplefilter("ignore", NumericalWarning)
            L, _ = safe_cholesky(K_y, config=self.config, what="K_y")
        alpha = scipy.linalg.cho_solve((L, True), self.y, check_finite=False)  # [N]
        n = self.y.shape[0]
        log_ev = -0.5 * self.y @ alpha - np.sum(np.log(np.diag(L))) - 0.5 * n * np.log(2.0 * np.pi)
        Linv, info = scipy.linalg.lapack.dtrtri(L, lower=1)
        if info != 0:  # pragma: no cover - L has a positive diagonal
            raise np.linalg.LinAlgError(f"dtrtri failed with info={info}")
        K_inv = Linv.T @ Linv  # [N, N]
        M = (np.outer(alpha, alpha) - K_inv) * VK  # W * dK/dlog(variance); d log p = tr(W dK) / 2
        grad = np.empty_like(theta)
        grad[:n_ls] = 0.5 * np.tensordot(self.D2, M, axes=2) * inv_l2  # RW06 eq. 5.9
        grad[n_ls] = 0.5 * np.sum(M)
        grad[n_ls + 1] = 0.5 * noise * (alpha @ alpha - np.trace(K_inv))
        return float(-log_ev), -grad


def _negative_evidence_and_gradient(
    theta: FloatArray, X: FloatArray, y: FloatArray, ard: bool
) -> tuple[float, FloatArray]:
    """``-log p(y | X, theta)`` and its gradient with respect to ``theta`` (log space)."""
    with threadpool_limits(limits=1, user_api="blas"):
        return _Objective(X, y, ard)(theta)


def _projected_gradient(theta: FloatArray, grad: FloatArray, bounds: FloatArray) -> float:
    """Largest violation of the first-order (KKT) conditions of ``min f`` in the box
    ``bounds`` ([p, 2]): ``|grad|`` inside; at a bound, only a descent direction
    that points into the box counts."""
    at_lo = theta <= bounds[:, 0] + _AT_TOL
    at_hi = theta >= bounds[:, 1] - _AT_TOL
    g = np.where(at_lo, np.minimum(grad, 0.0), grad)
    g = np.where(at_hi, np.maximum(g, 0.0), g)
    return float(np.max(np.abs(g)))


def fit_squared_exponential(
    X: ArrayLike,
    y: ArrayLike,
    *,
    lengthscale0: float | ArrayLike | None = None,
    variance0: float | None = None,
    noise0: float | None = None,
    ard: bool = True,
    max_points: int = 500,
    n_restarts: int = 3,
    rng: np.random.Generator | None = None,
    config: NumericsConfig = CONFIG,
) -> EvidenceFit:
    """Maximise the exact-GP evidence over SE length-scale(s), variance and noise.

    Parameters
    ----------
    X : [N, d] inputs; y : [N] targets.
    lengthscale0, variance0, noise0 : the first starting point; each defaults to its
        data-driven value (:func:`median_lengthscales` of the points used, ``var(y)``,
        ``var(y) / 10``).
    ard : one length-scale per input dimension (True) or a shared one.
    max_points : the evidence is computed on a random subsample of this many points
        (drawn with ``rng``) when ``N`` is larger; the cost is ``O(max_points^3)`` per
        evaluation.
    n_restarts : further starts, each log-parameter drawn log-uniformly within a
        factor :data:`RESTART_FACTOR` of the data-driven start with ``rng``; the best
        end point wins. ``0`` runs the first start only.
    rng : generator for the subsample and the restarts; required when ``N > max_points``
        or ``n_restarts > 0``. The same seed gives the same fit.
    config : the jitter policy used where ``K_y`` is numerically indefinite.

    Warns
    -----
    NumericalWarning : the fit ended at a bound of :data:`LOG_BOUNDS`, at its start,
        or not at a local optimum (then ``converged`` is False).
    """
    Xa = as_float_matrix(X, "X")
    ya = as_float_vector(y, "y", Xa.shape[0])
    if Xa.shape[0] < 2:
        raise ValueError(f"evidence maximisation needs at least 2 points, got {Xa.shape[0]}")
    if int(max_points) < 2:
        raise ValueError(f"max_points must be >= 2, got {max_points!r}")
    if isinstance(n_restarts, bool) or int(n_restarts) != n_restarts or n_restarts < 0:
        raise ValueError(f"n_restarts must be an integer >= 0, got {n_restarts!r}")
    if Xa.shape[0] > max_points:
        if rng is None:
            raise ValueError(
                f"{Xa.shape[0]} points exceed max_points={max_points}: pass rng= to subsample"
            )
        idx = np.sort(rng.choice(Xa.shape[0], size=int(max_points), replace=False))
        Xa, ya = Xa[idx], ya[idx]
    n_ls = Xa.shape[1] if ard else 1
    bounds = np.array(
        [LOG_BOUNDS["lengthscale"]] * n_ls + [LOG_BOUNDS["variance"], LOG_BOUNDS["noise"]]
    )  # [p, 2]
    # The data-driven start, then the caller's overrides of it.
    var_y = max(float(np.var(ya)), float(np.exp(LOG_BOUNDS["variance"][0])))
    theta_dd = np.log(np.concatenate([median_lengthscales(Xa, ard), [var_y, var_y / 10.0]]))
    theta0 = theta_dd.copy()
    if lengthscale0 is not None:
        ls0 = np.broadcast_to(np.asarray(lengthscale0, dtype=np.float64), (n_ls,))
        if not np.all(np.isfinite(ls0)) or np.any(ls0 <= 0):
            raise ValueError(f"lengthscale0 must be finite and > 0, got {lengthscale0!r}")
        theta0[:n_ls] = np.log(ls0)
    if variance0 is not None:
        theta0[n_ls] = np.log(check_positive(variance0, "variance0"))
    if noise0 is not None:
        theta0[n_ls + 1] = np.log(check_positive(noise0, "noise0"))
    starts = [theta0]
    if n_restarts > 0:
        if rng is None:
            raise ValueError(
                f"n_restarts={n_restarts} needs random starts: pass "
                "rng=np.random.default_rng(seed), or n_restarts=0 for the first start only"
            )
        spread = np.log(RESTART_FACTOR)
        starts += list(theta_dd + rng.uniform(-spread, spread, size=(int(n_restarts), n_ls + 2)))
    starts = [np.clip(s, bounds[:, 0], bounds[:, 1]) for s in starts]
    # Small dense algebra runs with one BLAS thread (STYLE; docs/design-notes.md).
    with threadpool_limits(limits=1, user_api="blas"):
        fit, problems = _maximise(_Objective(Xa, ya, ard, config), starts, bounds, ard)
    if problems:
        hint = (
            " A length-scale at its upper bound means that input barely matters to the evidence."
            if any(b.startswith("lengthscale") and b.endswith("upper") for b in fit.at_bound)
            else ""
        )
        warnings.warn(
            f"evidence maximisation {'; '.join(problems)}: log evidence {fit.log_evidence:.6g}, "
            f"{fit.log_evidence_start:.6g} at the first start.{hint} Check the scaling "
            "of the inputs against the bounds (LOG_BOUNDS), or add restarts "
            f"(n_restarts={n_restarts}).",
            NumericalWarning,
            stacklevel=2,
        )
    return fit


def _maximise(
    objective: _Objective, starts: list[FloatArray], bounds: FloatArray, ard: bool
) -> tuple[EvidenceFit, list[str]]:
    """Run L-BFGS-B from every start; the best end point, and what is wrong with it."""
    runs = []
    for start in starts:
        f_start = objective(start)[0]
        res = scipy.optimize.minimize(
            objective,
            start,
            jac=True,
            method="L-BFGS-B",
            bounds=bounds,
            options={"maxiter": 1000, "ftol": 1e-10},
        )
        runs.append((float(res.fun), f_start, start, res))
    best_run = int(np.argmin([r[0] for r in runs]))
    _, f_start, start, res = runs[best_run]
    theta = np.clip(res.x, bounds[:, 0], bounds[:, 1])
    f_end, grad = objective(theta)
    n_ls = theta.size - 2
    n = objective.y.shape[0]
    names = [f"lengthscale[{k}]" for k in range(n_ls)] if ard else ["lengthscale"]
    names += ["variance", "noise"]
    at_lo = theta <= bounds[:, 0] + _AT_TOL
    at_hi = theta >= bounds[:, 1] - _AT_TOL
    at_bound = tuple(
        f"{name} {'lower' if lo else 'upper'}"
        for name, lo, hi in zip(names, at_lo, at_hi, strict=True)
        if lo or hi
    )
    progressed = bool(np.max(np.abs(theta - start)) >= _AT_TOL) and f_end < f_start
    local_optimum = _projected_gradient(theta, grad, bounds) <= _PGTOL_PER_POINT * n
    problems = []
    if at_bound:
        problems.append(f"ended at a bound ({', '.join(at_bound)})")
    if not progressed:
        problems.append("ended at its starting point")
    if not local_optimum:
        problems.append(f"did not reach a local optimum (optimiser: {res.message})")
    lengthscale = np.exp(theta[:n_ls])
    kernel = SquaredExponential(
        lengthscale=lengthscale if ard else float(lengthscale[0]),
        variance=float(np.exp(theta[n_ls])),
    )
    noise = float(np.exp(theta[n_ls + 1]))
    fit = EvidenceFit(
        kernel=kernel,
        noise=noise,
        log_evidence=log_marginal_likelihood(
            kernel, noise, objective.X, objective.y, config=objective.config
        ),
        n_used=int(n),
        converged=bool(res.success) and progressed and local_optimum,
        message=str(res.message),
        log_evidence_start=-runs[0][1],
        n_restarts=len(runs) - 1,
        log_evidence_runs=tuple(-r[0] for r in runs),
        best_run=best_run,
        at_bound=at_bound,
    )
    return fit, problems
