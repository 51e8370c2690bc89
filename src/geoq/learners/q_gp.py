"""GP action-value function learner: roll-outs -> Monte-Carlo targets -> sparse online GP.

Data flow (JC12 §3): every step ``t`` of a roll-out gives an input
``x_t = [s_t, a_t]`` (mapped through :class:`~geoq.learners.scaling.InputScaling`)
and a target ``y_t = sum_{i=0}^{H-t} gamma^i r_{t+i}`` (the discounted return
to the end of the episode, as in the paper). The pairs are streamed, in order,
into a :class:`~geoq.gp.SparseOnlineGP` whose kernel is one of

* ``"euclidean"``: squared exponential (the paper's "standard GP"),
* ``"nearest"``: geodesic kernel, JC12 eq. 3 with JC12 eq. 4,
* ``"interpolated"``: geodesic kernel, JC12 eq. 3 with JC12 eq. 5,
* ``"resistance"`` (beyond the paper): ``A exp(-R / l)`` of the effective
  resistance ``R`` on the same graph, positive definite
  (:class:`~geoq.kernels.ResistanceKernel`).

Choices the paper leaves open, made here and recorded in :class:`QGPConfig`:

* targets are standardised (training mean and standard deviation) before the
  zero-mean GP sees them, so ``amplitude = 1`` (the paper's value) is the prior
  variance of the *standardised* Q; predictions are mapped back. Set
  ``standardize=False`` for raw targets.
* ``refit``: ``"none"`` (paper), ``"episode"`` (DTC refit on the current BV set
  and kernel after every roll-out) or ``"end"`` (once, after the last roll-out).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Literal

import numpy as np

from geoq import kernels
from geoq._typing import ArrayLike, FloatArray
from geoq._validation import (
    MAX_BUDGET,
    as_float_matrix,
    as_float_vector,
    check_budget,
    check_real,
)
from geoq.gp import SparseOnlineGP
from geoq.gp.pd_novelty import PDNoveltyOnlineGP
from geoq.kernels import KERNEL_NAMES, PAPER_KERNELS, Kernel, KernelName
from geoq.kernels.geodesic import GraphKernel
from geoq.kernels.stationary import as_scale_vector
from geoq.learners.scaling import PENDULUM_SCALING, InputScaling
from geoq.rollouts import Rollout

__all__ = [
    "KERNEL_NAMES",
    "MAX_BUDGET",
    "PAPER_KERNELS",
    "GPQFunction",
    "QGPConfig",
    "make_kernel",
]

RefitMode = Literal["none", "episode", "end"]


@dataclass(frozen=True)
class QGPConfig:
    """Everything that defines a GP Q-function learner (recorded with every result)."""

    kernel: KernelName = "nearest"
    """``euclidean`` (squared exponential), ``nearest`` (JC12 eq. 4), ``interpolated``
    (JC12 eq. 5) or ``resistance`` (positive-definite kernel on the same graph)."""
    max_bv: int = 100
    """Basis-vector budget of the sparse online GP."""
    tol: float = 1e-6
    """Relative novelty threshold: a point is added when ``gamma >= tol * k(x, x)``."""
    noise: float = 0.01
    """Observation-noise variance (of the standardised targets when ``standardize``)."""
    lengthscale: float | tuple[float, ...] = 1.0
    """Squared-exponential length-scale(s), in scaled input units (``euclidean`` only)."""
    amplitude: float = 1.0
    """Prior variance ``A`` of every kernel (JC12 eq. 3; the paper sets 1)."""
    eps: float = 0.3
    """Graph threshold of JC12 eq. 2: edge iff ``exp(-||x_i - x_j||^2) > eps``."""
    sigma_sp: float = 1.0
    """Width of JC12 eq. 3: ``k = A exp(-SP^2 / (2 sigma_sp))`` (paper: 1)."""
    sigma_se: float = 0.01
    """Width of the interpolation weights of JC12 eq. 5."""
    normalize_weights: bool = False
    """Normalise the JC12 eq. 5 weights to sum to one (the paper's sum is unnormalised)."""
    attach_weights: bool = False
    """JC12 eq. 5 averages ``||x* - x_i||^2 + P_ij`` instead of ``P_ij`` (beyond the paper: the
    literal JC12 eq. 5 gives every point zero novelty against a one-node graph, so its BV set
    never grows past one point; see :mod:`geoq.kernels.graph_distance`)."""
    resistance_lengthscale: float = 1.0
    """``l`` of the ``resistance`` kernel ``A exp(-R / l)``."""
    wrap_angle: bool = False
    """Wrap-aware distance on periodic inputs (theta); the paper uses raw angles."""
    temporal_edges: bool = False
    """Also link successive basis vectors of a roll-out in the graph (beyond JC12 eq. 2)."""
    pd_novelty: bool = False
    """Measure the novelty of a new point under the positive-definite (eigenvalue-flip)
    repair of the augmented Gram (:class:`~geoq.gp.pd_novelty.PDNoveltyOnlineGP`), so an
    indefinite graph kernel's BV set can grow to the budget; the default treats negative
    novelty as "not novel" (beyond the paper, which is silent)."""
    standardize: bool = True
    """Centre and scale the targets before the zero-mean GP sees them."""
    refit: RefitMode = "none"
    """When to refit the posterior on the current BV set and kernel."""
    scaling: InputScaling = field(default_factory=lambda: PENDULUM_SCALING)
    """Per-dimension input scaling ``x = [s, a] / scale``."""

    def __post_init__(self) -> None:
        """Every field is checked here, at construction (not when the learner first fits)."""
        if self.kernel not in KERNEL_NAMES:
            raise ValueError(f"kernel must be one of {KERNEL_NAMES}, got {self.kernel!r}")
        if self.refit not in ("none", "episode", "end"):
            raise ValueError(f"refit must be 'none', 'episode' or 'end', got {self.refit!r}")
        check_budget(self.max_bv)
        check_real(self.tol, "tol", low=0.0, high=1.0)
        for name in ("noise", "amplitude", "sigma_sp", "sigma_se", "resistance_lengthscale"):
            check_real(getattr(self, name), name, low=0.0, low_open=True)
        check_real(self.eps, "eps", low=0.0, high=1.0, low_open=True, high_open=True)
        for name in (
            "normalize_weights", "attach_weights", "wrap_angle", "temporal_edges",
            "pd_novelty", "standardize",
        ):  # fmt: skip
            if not isinstance(getattr(self, name), bool | np.bool_):
                raise ValueError(f"{name} must be true or false, got {getattr(self, name)!r}")
        if not isinstance(self.scaling, InputScaling):
            raise ValueError(f"scaling must be an InputScaling, got {type(self.scaling).__name__}")
        ls = self.lengthscale
        values = ls if isinstance(ls, tuple | list) else (ls,)
        if isinstance(ls, tuple | list) and len(ls) != self.scaling.dim:
            raise ValueError(
                f"lengthscale has {len(ls)} entries; expected one number or "
                f"{self.scaling.dim} (one per input dimension)"
            )
        for v in values:
            check_real(v, "lengthscale", low=0.0, low_open=True)
        try:
            as_scale_vector(np.asarray(values, dtype=np.float64), "lengthscale")
        except ValueError as exc:
            raise ValueError(str(exc)) from None

    def replace(self, **changes: Any) -> QGPConfig:
        """A copy with some fields changed."""
        return replace(self, **changes)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> QGPConfig:
        """Inverse of :meth:`as_dict`; a ``ValueError`` naming the field for anything else."""
        if not isinstance(data, dict):
            raise ValueError(f"a learner configuration must be an object, got {data!r}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown learner field(s) {unknown}; known: {sorted(known)}")
        d = dict(data)
        if "scaling" in d:
            d["scaling"] = _scaling_from_dict(d["scaling"])
        if isinstance(d.get("lengthscale"), list):
            d["lengthscale"] = tuple(d["lengthscale"])
        return cls(**d)

    def as_dict(self) -> dict[str, Any]:
        """JSON-able representation."""
        out = asdict(self)
        out["scaling"] = self.scaling.as_dict()
        out["lengthscale"] = (
            list(self.lengthscale) if isinstance(self.lengthscale, tuple) else self.lengthscale
        )
        return out


def _scaling_from_dict(sc: Any) -> InputScaling:
    keys = {"scale", "periods", "names"}
    if not isinstance(sc, dict) or set(sc) != keys:
        raise ValueError(
            f"scaling must be an object with exactly the keys {sorted(keys)}, got {sc!r}"
        )
    for key in ("scale", "periods"):
        if not isinstance(sc[key], list | tuple):
            raise ValueError(f"scaling.{key} must be a list of numbers, got {sc[key]!r}")
        for v in sc[key]:
            check_real(v, f"scaling.{key}")
    if not isinstance(sc["names"], list | tuple) or not all(
        isinstance(n, str) for n in sc["names"]
    ):
        raise ValueError(f"scaling.names must be a list of strings, got {sc['names']!r}")
    try:
        return InputScaling(tuple(sc["scale"]), tuple(sc["periods"]), tuple(sc["names"]))
    except ValueError as exc:
        raise ValueError(f"scaling: {exc}") from None


def make_kernel(config: QGPConfig) -> Kernel:
    """A fresh kernel for ``config`` (:func:`geoq.kernels.make_kernel` of its fields)."""
    return kernels.make_kernel(
        config.kernel,
        lengthscale=config.lengthscale,
        amplitude=config.amplitude,
        eps=config.eps,
        sigma_sp=config.sigma_sp,
        sigma_se=config.sigma_se,
        resistance_lengthscale=config.resistance_lengthscale,
        period=config.scaling.scaled_periods() if config.wrap_angle else None,
        normalize_weights=config.normalize_weights,
        attach_weights=config.attach_weights,
        temporal_edges=config.temporal_edges,
    )


class GPQFunction:
    """A Q-function ``Q(s, a)`` learned from roll-outs by a sparse online GP.

    Parameters
    ----------
    config : the learner's settings.

    Attributes (after :meth:`fit`)
    ------------------------------
    gp_ : the underlying :class:`~geoq.gp.SparseOnlineGP` (on scaled inputs).
    y_mean_, y_scale_ : target standardisation (0 and 1 when disabled).
    """

    def __init__(self, config: QGPConfig | None = None) -> None:
        self.config = config or QGPConfig()
        self.gp_: SparseOnlineGP | None = None
        self.y_mean_ = 0.0
        self.y_scale_ = 1.0

    # -- inputs -----------------------------------------------------------------------
    def inputs(self, states: ArrayLike, actions: ArrayLike) -> FloatArray:
        """Scaled GP inputs ``[N, d]`` from states ``[N, d_s]``, actions ``[N]`` or ``[N, d_a]``."""
        S = as_float_matrix(states, "states")
        A = np.asarray(actions, dtype=np.float64)
        if A.ndim == 1:
            A = A[:, None]
        A = as_float_matrix(A, "actions")
        if A.shape[0] != S.shape[0]:
            raise ValueError(f"states has {S.shape[0]} rows but actions has {A.shape[0]}")
        return self.config.scaling.transform(np.hstack([S, A]))

    # -- learning ---------------------------------------------------------------------
    def fit(self, rollouts: Sequence[Rollout]) -> GPQFunction:
        """Learn from roll-outs, streamed in order (roll-out by roll-out, step by step).

        Parameters
        ----------
        rollouts : records with ``states [H, d_s]``, ``actions [H]`` and
            Monte-Carlo targets ``returns [H]`` (:class:`geoq.rollouts.Rollout`).
        """
        Xs, zs = self._targets(rollouts)
        gp = self._new_gp()
        self._stream(gp, Xs[0], zs[0])
        self._finish(gp, Xs, zs)
        return self

    def fit_twin(self, rollouts: Sequence[Rollout], refit: RefitMode) -> GPQFunction:
        """:meth:`fit` this learner, and return a second one fitted to the same roll-outs
        with ``config.refit = refit``: the same numbers as ``GPQFunction(
        config.replace(refit=refit)).fit(rollouts)``, bit for bit.

        The two learners stream the first roll-out identically (no refit happens before
        it ends), so that part runs once and the GP is copied
        (:meth:`~geoq.gp.SparseOnlineGP.copy`).
        """
        twin = GPQFunction(self.config.replace(refit=refit))
        Xs, zs = self._targets(rollouts)
        twin.y_mean_, twin.y_scale_ = self.y_mean_, self.y_scale_
        gp = self._new_gp()
        self._stream(gp, Xs[0], zs[0])
        twin_gp = gp.copy()
        self._finish(gp, Xs, zs)
        twin._finish(twin_gp, Xs, zs)
        return twin

    def _targets(self, rollouts: Sequence[Rollout]) -> tuple[list[FloatArray], list[FloatArray]]:
        """Scaled inputs and standardised targets per roll-out; sets ``y_mean_``, ``y_scale_``."""
        if len(rollouts) == 0:
            raise ValueError("no roll-outs given; fit needs at least one")
        Xs = [self.inputs(ro.states, ro.actions) for ro in rollouts]
        ys = [
            as_float_vector(ro.returns, "returns", X.shape[0])
            for X, ro in zip(Xs, rollouts, strict=True)
        ]
        y_all = np.concatenate(ys)
        if self.config.standardize:
            self.y_mean_ = float(np.mean(y_all))
            self.y_scale_ = float(np.std(y_all)) or 1.0
        else:
            self.y_mean_, self.y_scale_ = 0.0, 1.0
        return Xs, [(y - self.y_mean_) / self.y_scale_ for y in ys]

    def _new_gp(self) -> SparseOnlineGP:
        cfg = self.config
        gp_class = PDNoveltyOnlineGP if cfg.pd_novelty else SparseOnlineGP
        return gp_class(make_kernel(cfg), noise=cfg.noise, max_bv=cfg.max_bv, tol=cfg.tol)

    @staticmethod
    def _stream(gp: SparseOnlineGP, X: FloatArray, z: FloatArray) -> None:
        """One roll-out into ``gp``, step by step (a graph kernel starts a new roll-out)."""
        if isinstance(gp.kernel, GraphKernel):
            gp.kernel.start_rollout()
        gp.partial_fit(X, z)

    def _finish(self, gp: SparseOnlineGP, Xs: list[FloatArray], zs: list[FloatArray]) -> None:
        """The refits and roll-outs after the first roll-out has been streamed into ``gp``."""
        cfg = self.config
        for i in range(len(Xs)):
            if i > 0:
                self._stream(gp, Xs[i], zs[i])
            if cfg.refit == "episode":
                gp.refit(np.vstack(Xs[: i + 1]), np.concatenate(zs[: i + 1]))
        if cfg.refit == "end":
            gp.refit(np.vstack(Xs), np.concatenate(zs))
        self.gp_ = gp
        self._train = (np.vstack(Xs), np.concatenate(zs))

    def refit(self) -> GPQFunction:
        """Refit the posterior on the current BV set and kernel, using all training data."""
        gp = self._fitted()
        gp.refit(*self._train)
        return self

    def _fitted(self) -> SparseOnlineGP:
        if self.gp_ is None:
            raise RuntimeError("this GPQFunction is not fitted yet; call fit(...) first")
        return self.gp_

    # -- prediction -------------------------------------------------------------------
    def predict(
        self, states: ArrayLike, actions: ArrayLike, return_std: bool = False
    ) -> FloatArray | tuple[FloatArray, FloatArray]:
        """``Q(s, a)`` ``[N]`` (and its posterior std ``[N]``, in return units)."""
        gp = self._fitted()
        X = self.inputs(states, actions)
        if not return_std:
            mean = gp.predict(X)
            return self.y_mean_ + self.y_scale_ * mean
        mean, std = gp.predict(X, return_std=True)
        return self.y_mean_ + self.y_scale_ * mean, self.y_scale_ * std

    def prior_variance(self, states: ArrayLike, actions: ArrayLike) -> FloatArray:
        """Prior variance of ``Q(s, a)`` ``[N]``, in return units (``k(x, x) * y_scale^2``)."""
        gp = self._fitted()
        return self.y_scale_**2 * gp.kernel.diag(self.inputs(states, actions))
