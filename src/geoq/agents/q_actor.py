"""``actor``: a deterministic policy trained on ``Q``'s posterior mean (DDPG's actor).

The value-based agent acts by the best of a finite set of actions (candidates, or the
actions stored near the state); past a few action dimensions that set is sparse, and its
best is far from ``Q``'s. The actor ``a = pi(s)`` (a :class:`~geoq.models.MLPFeedback`, a
``tanh``-bounded network on the states standardised by the stored ones) climbs ``Q``
instead: after every fitted-Q phase, :data:`STEPS` Adam steps (Kingma & Ba 2015) up the mean
of ``Q(s, pi(s))`` over batches of :data:`BATCH` of the window's stored states (the
deterministic policy gradient, Silver et al. 2014; DDPG's actor update, Lillicrap et al.
2016). ``Q``'s action gradient is the squared exponential's closed form
(:func:`mean_action_gradient`, one kernel evaluation per step), else central differences.

``on``: the actor acts where ``Q`` would (a map's or a planner's policy comes first): training
actions are its own plus Gaussian noise of ``config.action_noise`` half-ranges (TD3's
exploration, Fujimoto et al. 2018), clipped to the box, and greedy actions its own. It then
takes actions ``Q`` has not seen; where ``Q`` rises along a direction its data do not pin
down (nearly linear along the actions, as on ``HalfCheetah-v5``), the actor follows it to
the box's corners (docs/design-notes.md, part twenty-five).

``curved``: as ``on``, in the phases where ``Q`` can turn inside the action box: where every
action length-scale of its squared exponential is at most the box's side along that action
(:func:`curves_inside`), the length-scales measured (fitted by evidence, or chosen; not the
rule's starting values before the first fit). A ``Q`` whose length-scales pass the box is close
to linear across it, its maximum a corner whatever the data say; there the actor is idle (no
training, no draws) and ``Q`` acts as with ``off``. ``auto`` resolves (``GPQConfig.for_dims``)
to ``off`` on the tasks ``Q`` alone learns, ``curved`` elsewhere.

Draws (initial weights, batches, noise) come from the agent's generator.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import numpy as np

from geoq._typing import FloatArray
from geoq.gp import SparseOnlineGP
from geoq.kernels.stationary import SquaredExponential
from geoq.learners.scaling import InputScaling
from geoq.models import MLPFeedback

__all__ = [
    "ACTORS", "BATCH", "STEPS", "QActor", "central_gradient", "closed_form_gradient",
    "curves_inside", "mean_action_gradient",
]  # fmt: skip

Actor = Literal["off", "on", "curved", "auto"]
ACTORS: tuple[str, ...] = ("off", "on", "curved", "auto")

#: ``Q``'s action gradient ``[n, d_a]`` at raw states ``[n, d_s]`` and actions ``[n, d_a]``.
ActionGradient = Callable[[FloatArray, FloatArray], FloatArray]

#: Adam steps after each fitted-Q phase, stored states per step, step size, hidden units.
STEPS, BATCH, LEARNING_RATE, HIDDEN = 50, 256, 3e-3, 32


def mean_action_gradient(
    gp: SparseOnlineGP, alpha: FloatArray, X: FloatArray, first: int, scale: FloatArray
) -> FloatArray:
    """``d mean / d a`` ``[n, d_a]`` of a GP with a :class:`SquaredExponential` kernel at scaled
    inputs ``X`` [n, d], for the raw actions ``a = X[:, first:] * scale`` (``scale`` [d_a]).

    With ``mean(x) = sum_b alpha_b k(x, b)`` (``alpha`` [m], :attr:`SparseOnlineGP.alpha`) and
    ``k(x, b) = v exp(-sum_j (x_j - b_j)^2 / (2 l_j^2))``:
    ``d mean / d x_j = -sum_b alpha_b k(x, b) (x_j - b_j) / l_j^2``. The action inputs must
    not wrap (the kernel's period on them 0 or none)."""
    kernel = gp.kernel
    assert isinstance(kernel, SquaredExponential)
    bv = gp.basis_vectors
    W = np.asarray(kernel.to_basis(X, bv), dtype=np.float64) * alpha  # [n, m]
    lengthscale = np.broadcast_to(np.asarray(kernel.lengthscale), (X.shape[1],))[first:]
    moved = X[:, first:] * W.sum(axis=1)[:, None] - W @ bv[:, first:]  # [n, d_a]
    return -moved / lengthscale**2 / scale


def closed_form_gradient(gp: SparseOnlineGP, scaling: InputScaling, d_s: int) -> ActionGradient:
    """:func:`mean_action_gradient` of ``gp`` (a squared exponential's) at raw states and
    actions, ``alpha`` computed once."""
    alpha, scale = gp.alpha, np.asarray(scaling.scale)[d_s:]

    def gradient(S: FloatArray, A: FloatArray) -> FloatArray:
        return mean_action_gradient(gp, alpha, scaling.transform(np.hstack([S, A])), d_s, scale)

    return gradient


def central_gradient(gp: SparseOnlineGP, scaling: InputScaling, h: float) -> ActionGradient:
    """``d mean / d a`` by central differences of step ``h`` (raw action units): ``2 d_a``
    predictions per state, for any kernel."""

    def gradient(S: FloatArray, A: FloatArray) -> FloatArray:
        n, d_a = A.shape
        shifted = np.repeat(A[None], 2 * d_a, axis=0)  # [2 d_a, n, d_a]
        for j in range(d_a):
            shifted[2 * j, :, j] += h
            shifted[2 * j + 1, :, j] -= h
        X = scaling.transform(np.hstack([np.tile(S, (2 * d_a, 1)), shifted.reshape(-1, d_a)]))
        q = gp.predict(X).reshape(2 * d_a, n)
        return ((q[0::2] - q[1::2]) / (2 * h)).T

    return gradient


def curves_inside(gp: SparseOnlineGP, scaling: InputScaling, width: FloatArray) -> bool:
    """Whether ``gp``'s kernel is a squared exponential whose every action length-scale (the
    inputs after the states, scaled) is at most the action box's side ``width`` [d_a] (raw
    units) along it: ``Q``'s mean can then have a maximum inside the box."""
    kernel = gp.kernel
    if not isinstance(kernel, SquaredExponential):
        return False
    d_a = width.shape[0]
    lengthscale = np.broadcast_to(np.asarray(kernel.lengthscale), (scaling.dim,))[-d_a:]
    return bool(np.all(lengthscale <= width / np.asarray(scaling.scale)[-d_a:]))


class QActor:
    """The actor of ``mode`` (module docstring) for actions in ``[low, high]`` ``[d_a]``."""

    def __init__(self, mode: Actor, low: FloatArray, high: FloatArray) -> None:
        self.mode, self.low, self.high = mode, low, high
        self.policy: MLPFeedback | None = None
        self.params = self.m = self.v = np.zeros(0)
        self.t = 0  # Adam steps taken
        self.active = mode == "on"  # curved: whether the last phase's Q curves inside the box

    @property
    def ready(self) -> bool:
        """Whether the actor acts: it has weights (after the first phase with data) and, in
        ``curved`` mode, the last phase's ``Q`` curves inside the box."""
        return self.policy is not None and self.active

    def act(self, S: FloatArray) -> FloatArray:
        """The actor's actions ``[n, d_a]`` at states ``[n, d_s]``."""
        assert self.policy is not None
        return self.policy.act(self.params, S)

    def explore(self, s: FloatArray, noise: float, rng: np.random.Generator) -> FloatArray:
        """Training actions ``[n, d_a]`` at ``s`` [n, d_s]: the actor's plus Gaussian noise of
        ``noise`` half-ranges, clipped to the box."""
        half = 0.5 * (self.high - self.low)
        a = self.act(s) + noise * half * rng.standard_normal((s.shape[0], self.low.shape[0]))
        return np.clip(a, self.low, self.high)

    # ------------------------------------------------------------------ training
    def train(self, states: FloatArray, gp: SparseOnlineGP, scaling: InputScaling,
              rng: np.random.Generator, measured: bool = True) -> None:  # fmt: skip
        """:data:`STEPS` Adam steps up the mean of ``Q(s, pi(s))`` over batches of ``states``
        ``[n, d_s]`` (the window's), ``Q`` the posterior mean of ``gp`` (scaled inputs); in
        ``curved`` mode only where ``gp``'s length-scales are ``measured`` and
        :func:`curves_inside` (else the actor is idle)."""
        if self.mode == "off" or len(states) == 0 or gp.n_bv == 0:
            return
        if self.mode == "curved":
            self.active = measured and curves_inside(gp, scaling, self.high - self.low)
            if not self.active:
                return
        if self.policy is None:
            center, spread = states.mean(axis=0), np.maximum(states.std(axis=0), 1e-6)
            self.policy = MLPFeedback(self.low, self.high, center, spread, hidden=HIDDEN)
            self.params = self.policy.initial(rng)
            self.m, self.v = np.zeros_like(self.params), np.zeros_like(self.params)
        gradient = self._gradient(gp, scaling, states.shape[1])
        for _ in range(STEPS):
            batch = states[rng.integers(0, len(states), BATCH)]
            A, cache = self.policy.forward(self.params, batch)
            grad, _ = self.policy.backward(self.params, cache, gradient(batch, A))
            self._adam(-grad / BATCH)

    def _adam(self, grad: FloatArray) -> None:
        self.t += 1
        self.m = 0.9 * self.m + 0.1 * grad
        self.v = 0.999 * self.v + 0.001 * grad**2
        m_hat, v_hat = self.m / (1 - 0.9**self.t), self.v / (1 - 0.999**self.t)
        self.params = self.params - LEARNING_RATE * m_hat / (np.sqrt(v_hat) + 1e-8)

    def _gradient(self, gp: SparseOnlineGP, scaling: InputScaling, d_s: int) -> ActionGradient:
        """``Q``'s action gradient for this phase's GP: the closed form where the kernel is a
        squared exponential whose action inputs do not wrap and no feature was repaired,
        else central differences of steps 1e-3 of the box's widest side."""
        periods = getattr(gp.kernel, "period", None)
        if (isinstance(gp.kernel, SquaredExponential) and not gp.features_repaired
                and (periods is None or not np.any(periods[d_s:]))):  # fmt: skip
            return closed_form_gradient(gp, scaling, d_s)
        return central_gradient(gp, scaling, 1e-3 * float(np.max(self.high - self.low)))

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> dict[str, Any]:
        """The actor as arrays (an agent's archive, prefix ``actor/``); none without weights."""
        if self.policy is None:
            return {}
        return {"center": self.policy.center, "scale": self.policy.scale, "params": self.params,
                "adam_m": self.m, "adam_v": self.v, "adam_t": np.int64(self.t),
                "active": np.bool_(self.active)}  # fmt: skip

    def restore(self, a: dict[str, Any], obs_dim: int) -> None:
        """Inverse of :meth:`to_arrays`; ``ValueError`` where it does not fit this actor."""
        if self.mode == "off":
            if a:
                raise ValueError("the file holds an actor, but its config's actor is off")
            return
        if not a:  # no weights yet
            return
        center, spread = np.asarray(a["center"], np.float64), np.asarray(a["scale"], np.float64)
        if center.shape != (obs_dim,) or spread.shape != (obs_dim,):
            raise ValueError(f"the actor's center and scale must have shape ({obs_dim},)")
        policy = MLPFeedback(self.low, self.high, center, spread, hidden=HIDDEN)
        arrays = [np.asarray(a[k], dtype=np.float64) for k in ("params", "adam_m", "adam_v")]
        if any(x.shape != (policy.n_params,) or not np.all(np.isfinite(x)) for x in arrays):
            raise ValueError(f"the actor's weights must be {policy.n_params} finite numbers")
        t = int(a["adam_t"])
        if t < 0 or np.any(arrays[2] < 0.0):  # Adam's step divides by sqrt(v / (1 - 0.999^t))
            raise ValueError(f"the actor's Adam state must have t >= 0 and v >= 0, got t = {t}")
        self.policy, (self.params, self.m, self.v), self.t = policy, arrays, t
        active = np.asarray(a.get("active", True))  # files before curved: on's, always active
        if active.shape != () or active.dtype != np.bool_:
            raise ValueError(f"the actor's active flag must be one boolean, got {active!r}")
        self.active = self.mode == "on" or bool(active)
