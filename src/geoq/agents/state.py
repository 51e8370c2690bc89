"""What a :class:`~geoq.agents.GPQAgent` has learned besides its GP and its transitions
(:class:`LearningState`), and what it recorded on the way (:class:`TrainingLog`).

Both are saved whole, as JSON, in the agent's file (:mod:`geoq.agents._persist`)
under the keys they have had since the format's first version; a key missing from
an older file takes the value that file's code behaved as.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

import numpy as np

from geoq._validation import MAX_MAGNITUDE
from geoq.agents.buffer import EpisodeRecord

__all__ = [
    "MAX_VALUE",
    "LearningState",
    "PhaseSchedule",
    "TrainingLog",
    "as_range",
    "check_target",
    "check_value_bounds",
    "value_bounds",
]

_EMPTY_RANGE = (np.inf, -np.inf)

#: Largest magnitude of a value (a target, a bound of :func:`value_bounds`): the GP's
#: limit on targets (``MAX_MAGNITUDE``), so sums of squares of targets stay finite.
MAX_VALUE = MAX_MAGNITUDE


def as_range(bounds: tuple[float, float] | None) -> tuple[float, float]:
    """A declared ``(r_min, r_max)`` as floats; None: the empty range ``(inf, -inf)``."""
    return (float(bounds[0]), float(bounds[1])) if bounds else _EMPTY_RANGE


def check_target(z: float, reward: float) -> float:
    """A standardised target ``z`` the GP takes (``|z| <= MAX_MAGNITUDE``), else a
    ``ValueError`` about the env's ``reward`` that made it."""
    if not abs(z) <= MAX_MAGNITUDE:
        raise ValueError(
            f"the env's reward {reward!r} lies {abs(z):.3g} standard deviations of the values "
            f"learned so far from them (beyond {MAX_MAGNITUDE:g}, the agent's arithmetic "
            "overflows); rescale the rewards (gymnasium.wrappers.TransformReward)"
        )
    return z


def value_bounds(
    reward_range: tuple[float, float], terminal_range: tuple[float, float], gamma: float
) -> tuple[float, float]:
    """``[lo, hi]`` holding every discounted return (see :meth:`LearningState.value_bounds`)."""
    lo, hi = reward_range
    t_lo, t_hi = terminal_range
    return min(lo, lo / (1.0 - gamma), t_lo), max(hi, hi / (1.0 - gamma), t_hi)


def check_value_bounds(bounds: tuple[float, float], what: str) -> tuple[float, float]:
    """``bounds`` if both ends that are set lie within ``MAX_VALUE``; else a ``ValueError``
    saying that ``what`` (rewards) imply values too large, and what to do."""
    lo, hi = bounds
    if (lo, hi) == _EMPTY_RANGE:  # no reward declared or seen yet
        return bounds
    worst = max(abs(lo), abs(hi))  # inf (or NaN) where r / (1 - gamma) overflowed
    if not worst <= MAX_VALUE:
        raise ValueError(
            f"{what} would make the values (discounted returns, up to r / (1 - gamma)) reach "
            f"{worst:.3g}, beyond the {MAX_VALUE:g} the agent can learn; rescale the rewards "
            "(gymnasium.wrappers.TransformReward)"
        )
    return bounds


class PhaseSchedule(Protocol):
    """The settings that say when a fitted-Q phase is due (a :class:`~geoq.agents.GPQConfig`)."""

    @property
    def train_every(self) -> int: ...
    @property
    def train_fraction(self) -> float: ...
    @property
    def window(self) -> int: ...


@dataclass
class LearningState:
    """The agent's learning state: everything but the GP, the transitions and the log."""

    y_mean: float
    """The GP sees ``z = (y - y_mean) / y_scale`` (set after every fitted-Q phase)."""
    y_scale: float
    reward_range: tuple[float, float] = _EMPTY_RANGE
    """Extreme rewards of the steps that did not end an episode (declared, then widened by
    those seen); see :meth:`value_bounds`."""
    terminal_reward_range: tuple[float, float] = _EMPTY_RANGE
    """Extreme rewards of the steps that ended an episode (``terminated``), likewise."""
    num_timesteps: int = 0
    """Environment steps taken."""
    last_train_timestep: int = 0
    """``num_timesteps`` at the last fitted-Q phase (``train_fraction``)."""
    scaling_pending: bool = False
    """True until ``warmup_steps`` steps have fixed a data-driven input scaling (an
    observation space with infinite bounds and no ``scaling=``)."""
    data_scaled: bool = False
    """Whether the input scaling comes from data (it then follows the states seen)."""
    fitted_lengthscale: tuple[float, ...] | None = None
    """Length-scales fitted by evidence (``hyperparameters="evidence"``), else None."""
    evidence_due: int = 0
    """The next evidence fit runs once this many transitions are stored."""

    def phase_due(self, config: PhaseSchedule, n_stored: int) -> bool:
        """Whether a fitted-Q phase is due mid-episode with ``n_stored`` transitions stored
        (``config.train_every``, ``config.train_fraction``, ``config.window``)."""
        if self.num_timesteps % config.train_every:
            return False
        new = self.num_timesteps - self.last_train_timestep
        return new >= config.train_fraction * min(n_stored, config.window)

    def _widened(self, r: float, terminated: bool) -> tuple[float, float]:
        lo, hi = self.terminal_reward_range if terminated else self.reward_range
        return (min(lo, r), max(hi, r))

    def observe_reward(self, r: float, terminated: bool) -> None:
        """Widen the reward range of terminating or of other steps by ``r``."""
        if terminated:
            self.terminal_reward_range = self._widened(r, terminated)
        else:
            self.reward_range = self._widened(r, terminated)

    def value_bounds_with(self, r: float, terminated: bool, gamma: float) -> tuple[float, float]:
        """:meth:`value_bounds` once ``r`` is observed (nothing changes), checked: a
        ``ValueError`` naming the env's reward if they pass ``MAX_VALUE``."""
        rewards = self.reward_range if terminated else self._widened(r, False)
        terminal = self._widened(r, True) if terminated else self.terminal_reward_range
        kind = "reward of a terminating step" if terminated else "reward"
        return check_value_bounds(value_bounds(rewards, terminal, gamma), f"the env's {kind} {r!r}")

    def check(self, gamma: float) -> LearningState:
        """``self`` if its fields are consistent (a loaded file's), else a ``ValueError``."""
        for name in ("reward_range", "terminal_reward_range"):
            lo, hi = getattr(self, name)
            if not ((lo, hi) == _EMPTY_RANGE or (np.isfinite(lo) and np.isfinite(hi) and lo <= hi)):
                raise ValueError(f"{name} {[lo, hi]} is neither empty nor a finite range")
        check_value_bounds(self.value_bounds(gamma), "the rewards recorded")
        if not (np.isfinite(self.y_mean) and np.isfinite(self.y_scale) and self.y_scale > 0):
            raise ValueError(f"y_mean {self.y_mean} / y_scale {self.y_scale} are not valid")
        if not 0 <= self.last_train_timestep <= self.num_timesteps or self.evidence_due < 0:
            raise ValueError("the step counters are inconsistent")
        ls = self.fitted_lengthscale
        if ls is not None and not (len(ls) and all(np.isfinite(v) and v > 0 for v in ls)):
            raise ValueError(f"fitted_lengthscale {ls} holds no finite length-scales > 0")
        return self

    def value_bounds(self, gamma: float) -> tuple[float, float]:
        """``[lo, hi]`` holding every discounted return, so every target.

        ``lo = min(r_min, r_min / (1 - gamma), t_min)``, ``hi = max(r_max, r_max / (1 -
        gamma), t_max)`` with ``[r_min, r_max]`` the range of the rewards of steps that do
        not end an episode and ``[t_min, t_max]`` of those that do (declared or seen).
        A discounted return is ``sum_{t<k} gamma^t r_t + gamma^k t_k``: between
        ``r / (1 - gamma)`` and ``t`` for constant rewards, so within the bounds.
        """
        return value_bounds(self.reward_range, self.terminal_reward_range, gamma)

    def as_dict(self) -> dict[str, Any]:
        """JSON-able form (ranges as lists)."""
        out = asdict(self)
        out["reward_range"] = list(self.reward_range)
        out["terminal_reward_range"] = list(self.terminal_reward_range)
        return out

    @classmethod
    def from_dict(cls, meta: dict[str, Any]) -> LearningState:
        """Inverse of :meth:`as_dict`; keys of later versions default as older files behaved."""
        num_timesteps = int(meta["num_timesteps"])
        fitted = meta.get("fitted_lengthscale")
        lo, hi = meta["reward_range"]
        # Files before the split counted terminal rewards in reward_range: still valid bounds.
        t_lo, t_hi = meta.get("terminal_reward_range", _EMPTY_RANGE)
        return cls(
            y_mean=float(meta["y_mean"]),
            y_scale=float(meta["y_scale"]),
            reward_range=(float(lo), float(hi)),
            terminal_reward_range=(float(t_lo), float(t_hi)),
            num_timesteps=num_timesteps,
            last_train_timestep=int(meta.get("last_train_timestep", num_timesteps)),
            scaling_pending=bool(meta.get("scaling_pending", False)),
            data_scaled=bool(meta.get("data_scaled", False)),
            fitted_lengthscale=None if fitted is None else tuple(float(v) for v in fitted),
            evidence_due=int(meta.get("evidence_due", 0)),
        )


@dataclass
class TrainingLog:
    """What the agent recorded while learning (read by reports; never read back to act)."""

    episodes: list[EpisodeRecord] = field(default_factory=list)
    """One record per finished training episode."""
    fitted_q_sweeps: list[int] = field(default_factory=list)
    """Sweeps of each fitted-Q phase."""
    fitted_q_residuals: list[float] = field(default_factory=list)
    """Per fitted-Q phase, the largest change of a target in its last sweep (return
    units; 0 without sweeps). Above ``sweep_tol`` x the phase's ``y_scale``: it
    stopped at ``max_sweeps`` without converging (docs/design-notes.md)."""
    imagined_counts: list[int] = field(default_factory=list)
    """Imagined transitions of each fitted-Q phase (``replay="graph"``)."""
    train_seconds: float = 0.0
    """Wall time of the fitted-Q phases (the compute cost of replay)."""
    rescales: int = 0
    """Times a data-driven input scaling was refreshed."""
    evidence_fits: list[dict[str, Any]] = field(default_factory=list)
    """One record per evidence fit: transitions, length-scales, log evidence, ..."""

    def as_dict(self) -> dict[str, Any]:
        """JSON-able form of everything but the episodes (an array of their own)."""
        out = asdict(self)
        del out["episodes"]
        return out

    def episodes_array(self) -> np.ndarray:
        """The episodes as ``[n, 4]`` rows ``(timesteps, episode, return, success)``."""
        rows = [[e.timesteps, e.episode, e.ret, e.success] for e in self.episodes]
        return np.array(rows, dtype=np.float64).reshape(-1, 4)

    @classmethod
    def from_dict(cls, meta: dict[str, Any], episodes: np.ndarray) -> TrainingLog:
        """Inverse of :meth:`as_dict` and :meth:`episodes_array`."""
        sweeps = [int(v) for v in meta["fitted_q_sweeps"]]
        # Files before the field did not record the residuals: NaN, one per phase.
        residuals = meta.get("fitted_q_residuals", [np.nan] * len(sweeps))
        return cls(
            episodes=[EpisodeRecord(int(t), int(e), float(r), float(s)) for t, e, r, s in episodes],
            fitted_q_sweeps=sweeps,
            fitted_q_residuals=[float(v) for v in residuals],
            imagined_counts=[int(v) for v in meta.get("imagined_counts", [])],
            train_seconds=float(meta.get("train_seconds", 0.0)),
            rescales=int(meta.get("rescales", 0)),
            evidence_fits=list(meta.get("evidence_fits", [])),
        )
