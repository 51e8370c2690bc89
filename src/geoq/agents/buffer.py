"""The agent's memory: transitions ``(s, a, r, s', terminated)`` with their current
targets, and the record of finished episodes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoq._typing import FloatArray

__all__ = ["EpisodeRecord", "TransitionBuffer", "Transitions"]


@dataclass(frozen=True)
class Transitions:
    """Transitions ``(s, a, r, s', terminated)`` as arrays ``[N, d_s]``, ``[N, d_a]``,
    ``[N]``, ``[N, d_s]``, ``[N]`` (bool)."""

    states: FloatArray
    actions: FloatArray
    rewards: FloatArray
    next_states: FloatArray
    terminated: np.ndarray

    def __len__(self) -> int:
        return int(self.rewards.shape[0])

    def then(self, other: Transitions) -> Transitions:
        """These transitions followed by ``other``'s."""
        return Transitions(
            np.vstack([self.states, other.states]),
            np.vstack([self.actions, other.actions]),
            np.concatenate([self.rewards, other.rewards]),
            np.vstack([self.next_states, other.next_states]),
            np.concatenate([self.terminated, other.terminated]),
        )


class TransitionBuffer:
    """Every transition seen, in order, in growable float64 arrays, with its latest target.

    The target of a transition is its bootstrapped value estimate
    ``r + gamma (1 - terminated) max_a' Q(s', a')`` as last computed (online when
    it was seen, then by every fitted-Q phase); it warm-starts the next phase.

    Parameters
    ----------
    obs_dim, action_dim : sizes of one observation and one action.
    capacity : initial size (doubles when full; nothing is ever dropped).
    """

    def __init__(self, obs_dim: int, action_dim: int, capacity: int = 1024) -> None:
        self.obs_dim, self.action_dim = int(obs_dim), int(action_dim)
        cap = max(int(capacity), 1)
        self._s = np.empty((cap, self.obs_dim))
        self._a = np.empty((cap, self.action_dim))
        self._r = np.empty(cap)
        self._s2 = np.empty((cap, self.obs_dim))
        self._term = np.empty(cap, dtype=bool)
        self._target = np.empty(cap)
        self._n = 0

    def __len__(self) -> int:
        return self._n

    def add(
        self,
        s: FloatArray,
        a: FloatArray,
        r: float,
        s2: FloatArray,
        terminated: bool,
        target: float = 0.0,
    ) -> None:
        """Append one transition (``s`` [d_s], ``a`` [d_a], ``s2`` [d_s]) and its target."""
        if self._n == self._r.shape[0]:
            self._grow()
        i = self._n
        self._s[i], self._a[i], self._r[i] = s, a, r
        self._s2[i], self._term[i], self._target[i] = s2, terminated, target
        self._n += 1

    def _grow(self) -> None:
        cap = 2 * self._r.shape[0]
        for name in ("_s", "_a", "_r", "_s2", "_term", "_target"):
            old = getattr(self, name)
            new = np.empty((cap, *old.shape[1:]), dtype=old.dtype)
            new[: self._n] = old[: self._n]
            setattr(self, name, new)

    def arrays(
        self, last: int | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray]:
        """Views ``(S [N, d_s], A [N, d_a], R [N], S2 [N, d_s], terminated [N])``.

        ``last``: only the most recent ``last`` transitions.
        """
        lo = 0 if last is None else max(self._n - int(last), 0)
        sl = slice(lo, self._n)
        return self._s[sl], self._a[sl], self._r[sl], self._s2[sl], self._term[sl]

    def transitions(self, last: int | None = None) -> Transitions:
        """The (most recent ``last``) transitions as a :class:`Transitions` of views."""
        return Transitions(*self.arrays(last))

    def targets(self, last: int | None = None) -> FloatArray:
        """Copy of the current targets ``[N]`` (of the ``last`` most recent transitions)."""
        lo = 0 if last is None else max(self._n - int(last), 0)
        return self._target[lo : self._n].copy()

    def set_targets(self, values: FloatArray) -> None:
        """Overwrite the targets of the ``len(values)`` most recent transitions."""
        k = len(values)
        if k > self._n:
            raise ValueError(f"{k} targets for {self._n} transitions")
        self._target[self._n - k : self._n] = values

    def to_arrays(self) -> dict[str, np.ndarray]:
        s, a, r, s2, term = self.arrays()
        return {"s": s, "a": a, "r": r, "s2": s2, "terminated": term, "target": self.targets()}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> TransitionBuffer:
        """Inverse of :meth:`to_arrays`; raises ``ValueError`` on inconsistent arrays."""
        s, a, r = arrays["s"], arrays["a"], arrays["r"]
        s2, term, target = arrays["s2"], arrays["terminated"], arrays["target"]
        n = r.shape[0]
        if not (
            s.ndim == 2 and a.ndim == 2 and r.ndim == 1 and s2.shape == s.shape
            and s.shape[0] == n and a.shape[0] == n and term.shape == (n,)
            and target.shape == (n,)
        ):  # fmt: skip
            raise ValueError("transition arrays have inconsistent shapes")
        if not all(np.all(np.isfinite(x)) for x in (s, a, r, s2, target)):
            raise ValueError("transition arrays hold non-finite values")
        buf = cls(s.shape[1], a.shape[1], capacity=max(n, 1))
        buf._s[:n], buf._a[:n], buf._r[:n], buf._s2[:n] = s, a, r, s2
        buf._term[:n] = term.astype(bool)
        buf._target[:n] = target
        buf._n = n
        return buf


@dataclass(frozen=True)
class EpisodeRecord:
    """One finished training episode (a row of ``learning_curve.csv``)."""

    timesteps: int
    """Environment steps taken by the agent when the episode ended."""
    episode: int
    """1-based episode index."""
    ret: float
    """Undiscounted return of the episode."""
    success: float
    """``info["is_success"]`` at the episode's end (1/0), NaN if the env reports none."""
