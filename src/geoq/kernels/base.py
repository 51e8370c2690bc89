"""The kernel interface: ``k(X, Y=None) -> [n, m]``, ``k.diag(X) -> [n]``.

Following tinygp, a stationary-style kernel is a *profile of a distance*: the
distance is a separate object, so the graph (geodesic) distance of
:mod:`geoq.kernels.graph_distance` is one more :class:`Distance` and the GP code does
not change. Kernels whose state follows the GP's basis-vector (BV) set (the
geodesic kernel's graph) receive the GP's notifications through the
``basis_*`` hooks; for every other kernel they are no-ops.

Persistence: each concrete kernel and distance registers itself by class name
and turns its configuration (and state) into plain arrays with ``to_arrays`` /
``from_arrays``, so models are saved as ``.npz`` without pickle.
"""

from __future__ import annotations

import weakref
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from geoq._typing import ArrayLike, FloatArray
from geoq._validation import MAX_MAGNITUDE, as_inputs

__all__ = [
    "Distance",
    "GaussianOfDistance",
    "Kernel",
    "kernel_from_arrays",
    "kernel_to_arrays",
]

#: ``f(x, BV, m) -> exponents [m] | None`` of a kernel's fused per-point row.
RowExponent = Callable[[FloatArray, FloatArray, int], FloatArray | None]

#: ``(lengthscale, period, variance)`` of a kernel the GP may evaluate in its compiled
#: squared-exponential loop: a scalar or ``[d]`` length-scale, ``[d]`` periods or None.
SEParameters = tuple[float | FloatArray, FloatArray | None, float]

_KERNELS: dict[str, type[Kernel]] = {}
_DISTANCES: dict[str, type[Distance]] = {}


class Distance(ABC):
    """A (possibly data-dependent) distance between input points.

    Subclasses implement :meth:`squared`. Distances whose state follows the
    basis set (a graph over the BVs) set ``tracks_basis = True`` and override
    the ``basis_*`` hooks and :meth:`squared_to_basis`.
    """

    tracks_basis: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        _DISTANCES[cls.__name__] = cls

    input_dim: int | None = None

    @abstractmethod
    def squared(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        """Squared distances, ``[n, d] x [m, d] -> [n, m]``; inputs already validated."""

    def squared_to_basis(self, X: FloatArray, basis: FloatArray) -> FloatArray:
        """Squared distances from ``X`` [n, d] to the current basis vectors [m, d]."""
        return self.squared(X, basis)

    def basis_added(self, x: FloatArray) -> None:  # noqa: B027 - optional hook
        """The GP appended ``x`` [d] to its basis set."""

    def basis_removed(self, index: int) -> None:  # noqa: B027 - optional hook
        """The GP deleted basis vector ``index``; later indices shift down by one."""

    def basis_cleared(self) -> None:  # noqa: B027 - optional hook
        """The GP emptied its basis set."""

    def follows_basis(self, basis: FloatArray) -> bool:
        """Whether the distance's state matches the basis set ``basis`` [m, d]."""
        return True

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Configuration and state as plain arrays (for ``.npz`` persistence)."""
        return {}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> Distance:
        """Inverse of :meth:`to_arrays`."""
        return cls()


class Kernel(ABC):
    """A covariance function ``k(x, x')`` on ``d``-dimensional inputs.

    What a GP may call (the protocol of :class:`~geoq.gp.SparseOnlineGP`):
    :meth:`diag` (prior variances), :meth:`to_basis` and :meth:`basis_gram`
    (covariances with its basis set), the hooks :meth:`basis_added`,
    :meth:`basis_removed`, :meth:`basis_cleared` and :meth:`follows_basis`
    (kernels with ``tracks_basis``), and two optional fast paths, each None
    unless the kernel offers it: :meth:`fused_row` (a compiled per-point row) and
    :meth:`se_parameters` (the kernel is a squared exponential the GP may
    evaluate itself). A subclass implements :meth:`_matrix` (and ``_diag`` if
    it has a cheaper diagonal).
    """

    tracks_basis: ClassVar[bool] = False
    #: False for kernels whose Gram matrices can be indefinite (a Gaussian of a graph
    #: distance); the GP's numerics policy treats them differently where it matters.
    positive_definite: ClassVar[bool] = True
    #: The model whose basis hooks drive this kernel's state (weak), see :meth:`bind`.
    _owner: weakref.ref[Any] | None = None

    def __getstate__(self) -> dict[str, Any]:
        """Copies (``copy.deepcopy``, pickling) start unbound: a copy is a new kernel."""
        state = dict(self.__dict__)
        state.pop("_owner", None)
        return state

    def bind(self, owner: object) -> None:
        """Attach the kernel to the model that will drive its basis hooks.

        A kernel that follows a basis set (``tracks_basis``: it owns a graph over
        the model's basis vectors) holds that model's state, so two models
        sharing it would silently change each other's predictions: binding it
        to a second live model raises ``ValueError``. Stateless kernels can be
        shared freely.
        """
        if not self.tracks_basis:
            return
        current = self._owner() if self._owner is not None else None
        taken = current is not None and current is not owner
        del current  # no strong reference to the other model in a traceback's frame
        if taken:
            raise ValueError(
                f"this {type(self).__name__} already belongs to another model (it keeps that "
                "model's graph); give each model its own kernel, e.g. copy.deepcopy(kernel) "
                "before fitting, or a new kernel with the same arguments"
            )
        self._owner = weakref.ref(owner)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        _KERNELS[cls.__name__] = cls

    #: Input dimension if the kernel fixes it (e.g. per-dimension length-scales), else None.
    input_dim: int | None = None

    def __call__(self, X: ArrayLike, Y: ArrayLike | None = None) -> FloatArray:
        """Kernel matrix ``[n, m]`` between the rows of ``X`` [n, d] and ``Y`` [m, d].

        ``k(X)`` is ``k(X, X)``.
        """
        Xa = as_inputs(X, "X", self.input_dim)
        Ya = Xa if Y is None else as_inputs(Y, "Y", Xa.shape[1])
        return self._matrix(Xa, Ya)

    def diag(self, X: ArrayLike) -> FloatArray:
        """``k(x_i, x_i)`` for every row of ``X`` [n, d] -> [n]."""
        return self._diag(as_inputs(X, "X", self.input_dim))

    @abstractmethod
    def _matrix(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        """``[n, d] x [m, d] -> [n, m]`` on validated inputs."""

    def _diag(self, X: FloatArray) -> FloatArray:
        return np.array([self._matrix(x[None, :], x[None, :])[0, 0] for x in X])

    # -- the GP's view: covariances with its basis set --------------------------------
    def to_basis(self, X: FloatArray, basis: FloatArray) -> FloatArray:
        """``k(X, BV)`` [n, m] where ``basis`` [m, d] is the GP's current BV set.

        Kernels that track the basis may use node identity (a BV *is* graph
        node ``j``) instead of comparing coordinates.
        """
        return self._matrix(X, basis)

    def basis_gram(self, basis: FloatArray) -> FloatArray:
        """``K_BV = k(BV, BV)`` [m, m]."""
        return self._matrix(basis, basis)

    def basis_added(self, x: FloatArray) -> None:  # noqa: B027 - optional hook
        """The GP appended ``x`` [d] to its basis set (called after the GP's update)."""

    def basis_removed(self, index: int) -> None:  # noqa: B027 - optional hook
        """The GP deleted basis vector ``index``; later indices shift down by one."""

    def basis_cleared(self) -> None:  # noqa: B027 - optional hook
        """The GP emptied its basis set."""

    def follows_basis(self, basis: FloatArray) -> bool:
        """Whether the kernel's basis-following state matches ``basis`` [m, d]."""
        return True

    def fused_row(self) -> tuple[RowExponent, float] | None:
        """A compiled per-point path for the GP, or None (the GP then uses :meth:`to_basis`).

        ``(f, c)``: whenever ``f(x [d], BV [cap, d], m)`` returns an array ``e`` [m]
        (None means "not here, use to_basis"), ``k(x, BV[:m]) = c * exp(e)`` and
        ``k(x, x) = c``, bit for bit.
        """
        return None

    def se_parameters(self) -> SEParameters | None:
        """The squared-exponential parameters if this kernel is exactly
        ``variance * exp(-0.5 sum_k (wrap(x_k - x'_k) / lengthscale_k)^2)`` (so the GP
        may evaluate it in its compiled loop), else None."""
        return None

    # -- persistence ------------------------------------------------------------------
    @abstractmethod
    def to_arrays(self) -> dict[str, np.ndarray]:
        """Hyper-parameters (and any basis-following state) as plain arrays."""

    @classmethod
    @abstractmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> Kernel:
        """Inverse of :meth:`to_arrays`."""


class GaussianOfDistance(Kernel):
    """``k(x, x') = variance * exp(-r^2 / 2)`` with ``r^2 = distance.squared(x, x')``.

    The squared-exponential kernel is this with a scaled Euclidean distance;
    the geodesic kernel (JC12 eq. 3) is this with the shortest-path distance.
    """

    def __init__(self, distance: Distance, variance: float = 1.0) -> None:
        v = float(variance)
        if not np.isfinite(v) or v <= 0.0:
            raise ValueError(f"variance must be a finite number > 0, got {variance!r}")
        if not 1.0 / MAX_MAGNITUDE <= v <= MAX_MAGNITUDE:
            # products of covariances (k^T C k, the noise floor) must stay normal floats
            raise ValueError(
                f"variance (amplitude) must be in [{1.0 / MAX_MAGNITUDE:g}, {MAX_MAGNITUDE:g}] "
                f"(products of covariances overflow or underflow beyond), got {variance!r}: "
                "standardise the targets"
            )
        self.distance = distance
        self.variance = v
        self.input_dim = distance.input_dim

    @property
    def tracks_basis(self) -> bool:  # type: ignore[override]
        return self.distance.tracks_basis

    def _matrix(self, X: FloatArray, Y: FloatArray) -> FloatArray:
        return self.variance * np.exp(-0.5 * self.distance.squared(X, Y))

    def _diag(self, X: FloatArray) -> FloatArray:
        return np.full(X.shape[0], self.variance)

    def to_basis(self, X: FloatArray, basis: FloatArray) -> FloatArray:
        # One temporary, not three (the fitted-Q phases call this on [N K, m]); the
        # distance array may be a cache of the distance object, so it is not overwritten.
        out = -0.5 * self.distance.squared_to_basis(X, basis)
        np.exp(out, out=out)
        out *= self.variance
        return out

    def basis_gram(self, basis: FloatArray) -> FloatArray:
        return self.to_basis(basis, basis)

    def follows_basis(self, basis: FloatArray) -> bool:
        return self.distance.follows_basis(basis)

    def basis_added(self, x: FloatArray) -> None:
        self.distance.basis_added(x)

    def basis_removed(self, index: int) -> None:
        self.distance.basis_removed(index)

    def basis_cleared(self) -> None:
        self.distance.basis_cleared()

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {
            "variance": np.asarray(self.variance),
            "distance": np.asarray(type(self.distance).__name__),
        }
        out.update({f"distance.{k}": v for k, v in self.distance.to_arrays().items()})
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> Kernel:
        dist_cls = _DISTANCES[str(arrays["distance"])]
        sub = {k[len("distance.") :]: v for k, v in arrays.items() if k.startswith("distance.")}
        return GaussianOfDistance(dist_cls.from_arrays(sub), variance=float(arrays["variance"]))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(distance={self.distance!r}, variance={self.variance:g})"


def kernel_to_arrays(kernel: Kernel, prefix: str = "kernel.") -> dict[str, np.ndarray]:
    """Flatten a kernel into ``{prefix + name: array}`` including its class name."""
    out = {f"{prefix}class": np.asarray(type(kernel).__name__)}
    out.update({prefix + k: np.asarray(v) for k, v in kernel.to_arrays().items()})
    return out


def kernel_from_arrays(arrays: dict[str, np.ndarray], prefix: str = "kernel.") -> Kernel:
    """Rebuild a kernel saved by :func:`kernel_to_arrays`."""
    name = str(arrays[f"{prefix}class"])
    if name not in _KERNELS:
        raise ValueError(f"unknown kernel class {name!r} in saved model; known: {sorted(_KERNELS)}")
    sub = {
        k[len(prefix) :]: v
        for k, v in arrays.items()
        if k.startswith(prefix) and k != f"{prefix}class"
    }
    return _KERNELS[name].from_arrays(sub)
