"""A GP model of one step of a task: next-state change, reward and termination.

As in PILCO (Deisenroth & Rasmussen 2011), each output of a step is its own GP on
the input ``x = [s, a]`` [D = d_s + d_a]: the ``d_s`` state changes ``s' - s``, the
reward ``r`` and the termination flag (0 or 1, read as a probability). Inputs are
standardised by the data's mean and standard deviation, each output by its own.

Each output's squared-exponential kernel (ARD: one length-scale per input) takes its
length-scales, amplitude and noise from the exact GP's evidence
(:func:`geoq.gp.evidence.fit_squared_exponential`) on at most ``fit_points`` of the
transitions; its posterior is a :class:`~geoq.gp.SparseOnlineGP` of at most
``max_bv`` basis vectors into which every transition is streamed (a refit at
:meth:`GPDynamicsModel.fit`, one step at a time by :meth:`GPDynamicsModel.observe`).
An output that has been constant in the data (a task that never terminated) is that
constant, with no uncertainty, until the next fit.

Two settings change what the GPs learn (both off by default). ``linear_mean``: each
output's prior mean is the least-squares linear function of the standardised inputs,
the GP learns what it leaves (Rasmussen & Williams 2006, section 2.7, with the weights
fixed at their least-squares values). ``outlier_mads``: a transition whose state change
lies more than that many median absolute deviations (normal-consistent) from the state
changes' least-squares line is left out of the state changes' GPs, in the fit and
when streamed after it; the reward's and the termination's GPs take every transition.
A stationary kernel must otherwise shorten an input's length-scale everywhere to fit
a rare jump somewhere: ``InvertedPendulum-v5``'s cart hitting its stop made the state
changes depend on the cart's position, which they do not elsewhere
(docs/design-notes.md).

The evidence sees at most ``fit_points`` transitions, each of which its exact GP can
interpolate: a simulator's outputs then get a noise near zero. A posterior of far fewer
basis vectors than transitions cannot interpolate them all, and streamed with that
noise its mean can miss its own transitions by more than the outputs' spread
(``Walker2d-v5`` at 2,500 transitions: a mean squared residual of 12 on a standardised
state change, held-out errors above predicting no change at all). Under the GP's own
assumptions the mean squared residual at the transitions is below the noise variance;
where it is above (``residual_noise``, on by default), every transition is streamed
again with that residual as the noise: what the budget cannot represent is treated as
noise (docs/design-notes.md, part thirty-three).

Where the model has data is measured on the states seen
(:class:`~geoq.models.support.StateSupport`), in the metric the outputs learned: each
state input in units of the shortest length-scale any output gave it, so that an input
no output depends on counts for nothing; or (``standardised_support``) in the states
standardised by the data, so that leaving the data along an input that nothing seen
depends on counts too (a cart's position before it ever met its stop). The predicted
reward is clipped to the range of the rewards seen: a planner otherwise seeks out the
GP's overshoot next to a jump (``InvertedPendulum-v5``'s reward, 1 per step alive and
0 at the step that ends the episode, was predicted at up to 1.02 beside the terminal
states, and the greedy plans went there: docs/design-notes.md).

Prediction: the means of ``P`` particles are one compiled loop over every output's own
basis vectors (:mod:`geoq.models._nb_mean`), what a planner's roll-outs ask for. The
std, where asked, is ``var = k(x, x) - |W^T k_x|^2`` per output, with ``W W^T = -C``
(the GP's ``C``; ``W = R^{-1} F`` with ``F F^T`` the whitened ``I - S``: a sum of
squares, which keeps the variance's rounding at the prior's).
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import scipy.linalg
from scipy.spatial.distance import cdist
from scipy.stats import median_abs_deviation

from geoq._io import ArchiveError
from geoq._threads import single_blas_thread, single_blas_thread_for_small_batches
from geoq._typing import FloatArray
from geoq._validation import as_float_matrix, as_float_vector, check_int
from geoq.gp import NumericalWarning, SparseOnlineGP
from geoq.gp.evidence import fit_squared_exponential
from geoq.gp.numerics import robust_cholesky
from geoq.kernels.stationary import SquaredExponential
from geoq.models._nb_mean import posterior_means, posterior_means_and_gradients
from geoq.models.model_settings import ModelSettings, settings_from
from geoq.models.support import StateSupport

__all__ = ["GPDynamicsModel", "ModelSettings"]

#: A standard deviation below this times ``1 + |mean|`` makes an input or output constant.
_CONSTANT = 1e-12
#: Least noise variance of a standardised output (a deterministic simulator's outputs
#: would otherwise ask the Cholesky factors for an exactly interpolating GP).
_NOISE_FLOOR = 1e-6


@dataclass(frozen=True)
class _Means:
    """Every non-constant output's mean weights, one output after another: ``inv_ls``
    [J, D], ``basis`` [M, D] (divided by the output's length-scales), ``offsets`` [J + 1],
    ``alpha`` [M], ``variance`` [J]; ``live`` [J] the outputs' columns."""

    inv_ls: FloatArray
    basis: FloatArray
    offsets: np.ndarray
    alpha: FloatArray
    variance: FloatArray
    live: np.ndarray


def _kernel(gp: SparseOnlineGP) -> SquaredExponential:
    assert isinstance(gp.kernel, SquaredExponential)  # every output's GP is made so
    return gp.kernel


def _variance_factor(gp: SparseOnlineGP) -> FloatArray:
    """``W`` [m, m] with ``W W^T = -C = R^{-1} (I - S) R^{-T}`` (module docstring): ``R^{-1}``
    times a Cholesky factor of the whitened ``I - S`` (PSD: the posterior shrinks every
    direction; where rounding says otherwise, the library's one jitter policy,
    :func:`~geoq.gp.numerics.robust_cholesky`)."""
    _, S = gp.whitened_posterior
    F, _, _ = robust_cholesky(np.eye(gp.n_bv) - 0.5 * (S + S.T), "a model output's I - S")
    return scipy.linalg.solve_triangular(gp.cholesky_factor, F, lower=False, check_finite=False)


class GPDynamicsModel:
    """One GP per output of a step (module docstring).

    Attributes (after :meth:`fit`): ``x_mean``, ``x_scale`` [D]; ``y_mean``, ``y_scale``
    [J] with ``J = d_s + 2`` (state changes, reward, termination); ``gps`` [J] (None for
    a constant output); ``prior_std`` [J] (an output's std far from every transition, 0
    for a constant); ``n_seen`` (transitions taken in); ``reward_range`` [2] (the least
    and largest reward taken in); ``linear`` [D, J] (the prior means' weights on the
    standardised inputs, zero without ``linear_mean``); ``n_outliers`` (transitions the
    state changes' GPs left out).
    """

    def __init__(self, obs_dim: int, action_dim: int, settings: ModelSettings | None = None):
        self.obs_dim = check_int(obs_dim, "obs_dim", minimum=1)
        self.action_dim = check_int(action_dim, "action_dim", minimum=1)
        self.settings = settings or ModelSettings()
        self.n_outputs = self.obs_dim + 2
        self.gps: list[SparseOnlineGP | None] = []
        self.n_seen = 0
        self._means: _Means | None = None
        self._factors: dict[int, FloatArray] = {}  # an output's W, once asked for its std

    @property
    def fitted(self) -> bool:
        """Whether :meth:`fit` has run (before it, :meth:`predict` raises)."""
        return bool(self.gps)

    # ------------------------------------------------------------------ data
    def _inputs(self, S: FloatArray, A: FloatArray) -> FloatArray:
        return (np.hstack([S, A]) - self.x_mean) / self.x_scale

    def _outputs(self, S: Any, A: Any, R: Any, S2: Any, T: Any) -> tuple[FloatArray, FloatArray]:
        """Checked inputs ``[N, D]`` (raw) and outputs ``[N, J]`` of ``N`` transitions."""
        S = as_float_matrix(S, "states", self.obs_dim)
        n = S.shape[0]
        A = as_float_matrix(A, "actions", self.action_dim)
        S2 = as_float_matrix(S2, "next_states", self.obs_dim)
        R = as_float_vector(R, "rewards", n)
        T = as_float_vector(np.asarray(T, dtype=np.float64), "terminated", n)
        if A.shape[0] != n or S2.shape[0] != n:
            raise ValueError(f"states, actions and next_states must have {n} rows each")
        return np.hstack([S, A]), np.column_stack([S2 - S, R, T])

    @single_blas_thread  # small dense algebra: geoq._threads
    def fit(
        self, states: Any, actions: Any, rewards: Any, next_states: Any, terminated: Any,
        rng: np.random.Generator,
    ) -> GPDynamicsModel:  # fmt: skip
        """Fit every output to ``N`` transitions (``[N, d_s]``, ``[N, d_a]``, ``[N]``, ``[N, d_s]``,
        ``[N]``): standardisation, evidence, then a sparse GP streamed every transition."""
        before = self.support.spacing if self.fitted and self.settings.support_holdout else 0.0
        X, Y = self._outputs(states, actions, rewards, next_states, terminated)
        if X.shape[0] < 2:
            raise ValueError(f"a model needs at least 2 transitions, got {X.shape[0]}")
        self.x_mean = X.mean(axis=0)
        spread = X.std(axis=0)
        self.x_scale = np.where(spread > _CONSTANT * (1 + np.abs(self.x_mean)), spread, 1.0)
        Xs = (X - self.x_mean) / self.x_scale
        self.y_mean = Y.mean(axis=0)
        self.linear = self._linear_part(Xs, Y)
        R = Y - self.y_mean - Xs @ self.linear  # what the prior means leave [N, J]
        self.y_scale = (R if self.settings.linear_mean else Y).std(axis=0)
        self._set_detector(Xs, Y)
        smooth = ~self._outliers(Xs, Y)  # the state changes' GPs learn these only
        self.n_outliers = int(np.sum(~smooth))
        d = self.obs_dim
        self.gps = [
            self._fit_output(Xs[smooth], R[smooth, j], j, rng) if j < d and not smooth.all()
            else self._fit_output(Xs, R[:, j], j, rng)
            for j in range(self.n_outputs)
        ]  # fmt: skip
        self.prior_std = np.array([
            0.0 if gp is None else self.y_scale[j] * np.sqrt(_kernel(gp).variance)
            for j, gp in enumerate(self.gps)
        ])  # fmt: skip
        self.reward_range = np.array([Y[:, self.obs_dim].min(), Y[:, self.obs_dim].max()])
        d, D = self.obs_dim, X.shape[1]
        relevance = [np.broadcast_to(_kernel(gp).lengthscale, (D,))[:d] for gp in self.gps if gp]
        shortest = np.min(relevance, axis=0) if relevance else np.ones(d)
        if self.settings.standardised_support:
            shortest = np.ones(d)
        S, S2 = X[:, :d], X[:, :d] + Y[:, :d]
        cut = X.shape[0] - int(self.settings.support_holdout * X.shape[0])
        newest = np.vstack([S[cut:], S2[cut:]]) if cut < X.shape[0] else None
        older, scale = np.vstack([S[:cut], S2[:cut]]), self.x_scale[:d] * shortest
        self.support: StateSupport = StateSupport(older, scale, rng, newest)
        self.support.spacing = max(self.support.spacing, before)
        self.n_seen, self._means, self._factors = X.shape[0], None, {}
        return self

    def _set_detector(self, Xs: FloatArray, Y: FloatArray) -> None:
        """The outlier test of the state changes (``settings.outlier_mads``): their least-
        squares line ``[D, d_s]`` on the standardised inputs, and the median and the normal-
        consistent median absolute deviation ``[d_s]`` of the residuals."""
        d = self.obs_dim
        self.outlier_line = np.zeros((Xs.shape[1], d))
        self.outlier_center, self.outlier_mad = np.zeros(d), np.full(d, np.inf)
        if self.settings.outlier_mads <= 0:
            return
        line, *_ = scipy.linalg.lstsq(Xs, Y[:, :d] - self.y_mean[:d], check_finite=False)
        self.outlier_line = np.ascontiguousarray(line)
        residual = Y[:, :d] - self.y_mean[:d] - Xs @ self.outlier_line
        self.outlier_center = np.median(residual, axis=0)
        mad = median_abs_deviation(residual, axis=0, scale="normal")
        self.outlier_mad = np.maximum(mad, _CONSTANT * (1 + np.abs(self.outlier_center)))

    def _outliers(self, Xs: FloatArray, Y: FloatArray) -> np.ndarray:
        """Which transitions ``[N]`` (standardised inputs, outputs) the state changes'
        GPs leave out: a residual beyond ``outlier_mads`` MADs in any state change."""
        d = self.obs_dim
        if self.settings.outlier_mads <= 0:
            return np.zeros(Xs.shape[0], dtype=bool)
        residual = Y[:, :d] - self.y_mean[:d] - Xs @ self.outlier_line - self.outlier_center
        return np.any(np.abs(residual) > self.settings.outlier_mads * self.outlier_mad, axis=1)

    def _linear_part(self, Xs: FloatArray, Y: FloatArray) -> FloatArray:
        """The prior means' weights ``[D, J]`` on the standardised inputs: least squares
        (``settings.linear_mean``), else zero."""
        if not self.settings.linear_mean:
            return np.zeros((Xs.shape[1], Y.shape[1]))
        weights, *_ = scipy.linalg.lstsq(Xs, Y - self.y_mean, check_finite=False)
        return np.ascontiguousarray(weights)  # the layout a loaded copy has: the same bits

    def _fit_output(
        self, Xs: FloatArray, y: FloatArray, j: int, rng: np.random.Generator
    ) -> SparseOnlineGP | None:
        """The GP of output ``j``'s deviations ``y`` [N] from its prior mean (None: none
        left, the output is its prior mean)."""
        if self.y_scale[j] <= _CONSTANT * (
            1 + abs(self.y_mean[j]) + np.abs(self.linear[:, j]).sum()
        ):
            self.y_scale[j] = 1.0
            return None
        z = y / self.y_scale[j]
        s = self.settings
        with warnings.catch_warnings():  # a length-scale at its bound: an input it ignores
            warnings.simplefilter("ignore", NumericalWarning)
            fit = fit_squared_exponential(
                Xs, z, max_points=s.fit_points, n_restarts=s.restarts, rng=rng
            )
        variance = float(fit.kernel.variance)
        kernel = SquaredExponential(fit.kernel.lengthscale, variance=variance)
        noise = max(float(fit.noise), _NOISE_FLOOR * variance)
        gp = SparseOnlineGP(kernel, noise=noise, max_bv=s.max_bv, tol=s.tol).fit(Xs, z)
        if not s.residual_noise:
            return gp
        residual = float(np.mean((gp.predict(Xs) - z) ** 2))
        if residual <= noise:
            return gp
        return SparseOnlineGP(kernel, noise=residual, max_bv=s.max_bv, tol=s.tol).fit(Xs, z)

    def observe(
        self, state: Any, action: Any, reward: float, next_state: Any, terminated: bool
    ) -> None:
        """Stream one transition into every non-constant output's GP (the standardisation
        and kernels stay those of the last :meth:`fit`)."""
        if not self.fitted:
            raise RuntimeError("observe needs a fitted model: call fit first")
        X, Y = self._outputs([state], [action], [reward], [next_state], [terminated])
        x = (X[0] - self.x_mean) / self.x_scale
        deviation = Y[0] - self.y_mean - x @ self.linear
        outlier = bool(self._outliers(x[None, :], Y)[0])
        self.n_outliers += outlier
        for j, gp in enumerate(self.gps):
            if gp is not None and not (outlier and j < self.obs_dim):
                gp.update(x, deviation[j] / self.y_scale[j])
        r = Y[0, self.obs_dim]
        self.reward_range = np.array([min(self.reward_range[0], r), max(self.reward_range[1], r)])
        self.support.add(X[0, : self.obs_dim] + Y[0, : self.obs_dim])
        self.n_seen += 1
        self._means, self._factors = None, {}

    # ------------------------------------------------------------------ prediction
    def _mean_weights(self) -> _Means:
        if self._means is None:
            live = [j for j, gp in enumerate(self.gps) if gp is not None]
            D = self.obs_dim + self.action_dim
            inv_ls = np.ones((len(live), D))
            basis, alpha, offsets = [np.zeros((0, D))], [np.zeros(0)], [0]
            variance = np.ones(len(live))
            for i, j in enumerate(live):
                gp = self.gps[j]
                assert gp is not None
                inv_ls[i] = 1.0 / np.broadcast_to(_kernel(gp).lengthscale, (D,))
                variance[i] = _kernel(gp).variance
                basis.append(gp.basis_vectors * inv_ls[i])
                mu, _ = gp.whitened_posterior  # alpha = R^{-1} mu by one triangular solve
                alpha.append(scipy.linalg.solve_triangular(gp.cholesky_factor, mu, lower=False,
                                                           check_finite=False))  # fmt: skip
                offsets.append(offsets[-1] + gp.n_bv)
            cols = np.array(live, dtype=np.int64)
            self._means = _Means(inv_ls, np.vstack(basis), np.array(offsets, dtype=np.int64),
                                 np.concatenate(alpha), variance, cols)  # fmt: skip
        return self._means

    @property
    def step_cost(self) -> int:
        """Kernel terms one particle's model step computes, times the inputs: ``M`` basis
        vectors over every output times ``D`` (the compiled means' inner loop; a policy
        search's unit of cost)."""
        basis = self._mean_weights().basis
        return int(basis.shape[0] * basis.shape[1])

    def predict_mean(self, states: FloatArray, actions: FloatArray) -> FloatArray:
        """Predictive means ``[P, J]`` of ``P`` particles ``states`` [P, d_s], ``actions``
        [P, d_a], in the data's units: columns ``0..d_s-1`` the state change, ``d_s`` the
        reward (within ``reward_range``), ``d_s + 1`` the termination. Compiled
        (:mod:`geoq.models._nb_mean`); inputs are not validated (a planner's inner loop)."""
        return self._mean(states, actions, None)

    def mean_gradients(
        self, states: FloatArray, actions: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """:meth:`predict_mean` ``[P, J]`` and its gradients ``[P, J, D]`` with respect to
        the inputs ``[s, a]`` in the data's units (the reward's are 0 where it is clipped;
        a policy search's pathwise gradients, :mod:`geoq.models.policy_gradient`)."""
        jac = np.zeros((states.shape[0], self.n_outputs, self.obs_dim + self.action_dim))
        return self._mean(states, actions, jac), jac

    def _mean(self, states: FloatArray, actions: FloatArray, jac: FloatArray | None) -> FloatArray:
        if not self.fitted:
            raise RuntimeError("predict needs a fitted model: call fit first")
        w, P = self._mean_weights(), states.shape[0]
        z = np.empty((P, len(w.live)))
        X = np.ascontiguousarray(self._inputs(states, actions))
        if jac is None:
            posterior_means(X, w.inv_ls, w.basis, w.offsets, w.alpha, w.variance, z)
        else:
            g = np.empty((P, len(w.live), X.shape[1]))
            posterior_means_and_gradients(
                X, w.inv_ls, w.basis, w.offsets, w.alpha, w.variance, z, g
            )
            jac[:] = self.linear.T
            jac[:, w.live] += g * self.y_scale[w.live, None]
            jac /= self.x_scale
        mean = self.y_mean + X @ self.linear
        mean[:, w.live] += z * self.y_scale[w.live]
        d = self.obs_dim
        if jac is not None:
            jac[(mean[:, d] < self.reward_range[0]) | (mean[:, d] > self.reward_range[1]), d] = 0.0
        np.clip(mean[:, d], *self.reward_range, out=mean[:, d])
        return mean

    @single_blas_thread_for_small_batches  # a planner's particles: geoq._threads
    def predict(self, states: FloatArray, actions: FloatArray) -> tuple[FloatArray, FloatArray]:
        """:meth:`predict_mean` and the predictive std ``[P, J]`` (of the latent outputs,
        noise excluded; 0 for a constant output)."""
        mean = self.predict_mean(states, actions)
        std = self._stds(self._inputs(states, actions), range(self.n_outputs))
        return mean, std

    @single_blas_thread_for_small_batches  # a planner's particles: geoq._threads
    def draw(
        self, states: FloatArray, actions: FloatArray, noise: np.random.Generator | FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """:meth:`predict_mean` ``[P, J]`` and next states ``[P, d_s]`` drawn from each state
        change's predictive distribution, ``s + mean + std * N(0, 1)``: a sampled roll-out's
        step, which asks for no other output's std. ``noise``: a generator to draw the
        standard normals ``[P, d_s]`` from, or the normals themselves (common random numbers
        across the candidates a search compares)."""
        d = self.obs_dim
        mean = self.predict_mean(states, actions)
        std = self._stds(self._inputs(states, actions), range(d))
        if isinstance(noise, np.random.Generator):
            noise = noise.standard_normal((states.shape[0], d))
        return mean, states + mean[:, :d] + std * noise

    def _stds(self, X: FloatArray, outputs: range) -> FloatArray:
        """The predictive std ``[P, len(outputs)]`` of ``outputs`` at standardised inputs
        ``X`` [P, D] (module docstring; each output's ``W`` made once per model change)."""
        w = self._mean_weights()
        place = {j: i for i, j in enumerate(w.live)}
        std = np.zeros((X.shape[0], len(outputs)))
        for c, j in enumerate(outputs):
            if j not in place:
                continue  # a constant output
            gp = self.gps[j]
            if j not in self._factors and gp is not None:
                self._factors[j] = _variance_factor(gp)
            i = place[j]
            basis = w.basis[w.offsets[i] : w.offsets[i + 1]]
            K = w.variance[i] * np.exp(-0.5 * cdist(X * w.inv_ls[i], basis, "sqeuclidean"))
            KW = K @ self._factors[j]
            var = w.variance[i] - np.einsum("pm,pm->p", KW, KW)
            std[:, c] = np.sqrt(np.maximum(var, 0.0)) * self.y_scale[j]
        return std

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> dict[str, Any]:
        """The model as plain arrays (for an agent's archive); :meth:`from_arrays` reads it."""
        s = self.settings
        numbers = [s.max_bv, s.fit_points, s.restarts, s.tol, s.linear_mean, s.outlier_mads,
                   s.standardised_support, s.support_holdout, s.residual_noise]  # fmt: skip
        out: dict[str, Any] = {
            "dims": np.array([self.obs_dim, self.action_dim, self.n_seen]),
            "settings": np.array(numbers),
        }
        if not self.fitted:
            return out
        out |= {"x_mean": self.x_mean, "x_scale": self.x_scale, "y_mean": self.y_mean,
                "linear": self.linear, "outlier_line": self.outlier_line,
                "outlier_center": self.outlier_center, "outlier_mad": self.outlier_mad,
                "n_outliers": np.array(self.n_outliers),
                "y_scale": self.y_scale, "prior_std": self.prior_std,
                "reward_range": self.reward_range,
                "live": np.array([gp is not None for gp in self.gps])}  # fmt: skip
        for j, gp in enumerate(self.gps):
            if gp is not None:
                out |= {f"gp{j}/{k}": v for k, v in gp.to_arrays().items()}
        out |= {f"support/{k}": v for k, v in self.support.to_arrays().items()}
        return out

    @classmethod
    def from_arrays(cls, a: dict[str, Any], source: str = "<arrays>") -> GPDynamicsModel:
        """Inverse of :meth:`to_arrays`; an :class:`~geoq._io.ArchiveError` names what is wrong."""
        try:
            obs_dim, action_dim, n_seen = (int(v) for v in a["dims"])
            settings = settings_from([float(v) for v in a["settings"]])
            model = cls(obs_dim, action_dim, settings)
            model.n_seen = n_seen
            if "live" not in a:
                return model
            J, D = model.n_outputs, obs_dim + action_dim
            for name, n in (("x_mean", D), ("x_scale", D), ("y_mean", J), ("y_scale", J),
                            ("prior_std", J), ("live", J), ("reward_range", 2)):  # fmt: skip
                model.__dict__[name] = as_float_vector(a[name], name, n)
            if np.any(model.x_scale <= 0):
                raise ValueError("x_scale must be positive")
            model._restore_prior_means(a)
            if model.reward_range[0] > model.reward_range[1]:
                raise ValueError("reward_range must be (least, largest)")
            model.gps = [
                SparseOnlineGP.from_arrays(
                    {k.split("/", 1)[1]: v for k, v in a.items() if k.startswith(f"gp{j}/")},
                    source=source,
                ) if live else None
                for j, live in enumerate(model.__dict__.pop("live") > 0)
            ]  # fmt: skip
            model.support = StateSupport.from_arrays(
                {k[8:]: v for k, v in a.items() if k.startswith("support/")}
            )
            if model.support.scale.shape != (obs_dim,):
                raise ValueError("the support's scale does not match the states")
        except (KeyError, TypeError, ValueError) as exc:
            raise ArchiveError(f"{source}: the dynamics model is damaged: {exc}") from exc
        return model

    def _restore_prior_means(self, a: dict[str, Any]) -> None:
        """The linear prior means and the outlier test of :meth:`to_arrays` (a model saved
        before them: none, as it was fitted)."""
        D, d, J = self.obs_dim + self.action_dim, self.obs_dim, self.n_outputs
        self.linear = as_float_matrix(a.get("linear", np.zeros((D, J))), "linear", J)
        if self.linear.shape != (D, J) or (not self.settings.linear_mean and self.linear.any()):
            raise ValueError(f"linear must be [{D}, {J}] (zero without linear_mean)")
        line = as_float_matrix(a.get("outlier_line", np.zeros((D, d))), "outlier_line", d)
        if line.shape != (D, d):
            raise ValueError(f"outlier_line must be [{D}, {d}]")
        self.outlier_line = line
        self.outlier_center = as_float_vector(
            a.get("outlier_center", np.zeros(d)), "outlier_center", d
        )
        mad = np.asarray(a.get("outlier_mad", np.full(d, np.inf)), dtype=np.float64)
        if mad.shape != (d,) or np.any(np.isnan(mad)) or np.any(mad <= 0):
            raise ValueError(f"outlier_mad must be [{d}] positive")
        self.outlier_mad = mad
        self.n_outliers = check_int(int(a.get("n_outliers", 0)), "n_outliers", minimum=0)

    def __repr__(self) -> str:
        return (f"GPDynamicsModel(obs_dim={self.obs_dim}, action_dim={self.action_dim}, "
                f"{asdict(self.settings)}, n_seen={self.n_seen})")  # fmt: skip
