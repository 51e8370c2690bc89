"""What a :class:`~geoq.agents.GPQAgent` has learned besides its GP and its transitions
(:class:`LearningState`), and what it recorded on the way (:class:`TrainingLog`).

Both are saved whole, as JSON, in the agent's file (:mod:`geoq.agents._persist`)
under the keys they have had since the format's first version; a key missing from
an older file takes the value that file's code behaved as.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from geoq.agents.buffer import EpisodeRecord

__all__ = ["LearningState", "TrainingLog"]

_EMPTY_RANGE = (np.inf, -np.inf)


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

    def observe_reward(self, r: float, terminated: bool) -> None:
        """Widen the reward range of terminating or of other steps by ``r``."""
        lo, hi = self.terminal_reward_range if terminated else self.reward_range
        widened = (min(lo, r), max(hi, r))
        if terminated:
            self.terminal_reward_range = widened
        else:
            self.reward_range = widened

    def value_bounds(self, gamma: float) -> tuple[float, float]:
        """``[lo, hi]`` holding every discounted return, so every target.

        ``lo = min(r_min, r_min / (1 - gamma), t_min)``, ``hi = max(r_max, r_max / (1 -
        gamma), t_max)`` with ``[r_min, r_max]`` the range of the rewards of steps that do
        not end an episode and ``[t_min, t_max]`` of those that do (declared or seen).
        A discounted return is ``sum_{t<k} gamma^t r_t + gamma^k t_k``: between
        ``r / (1 - gamma)`` and ``t`` for constant rewards, so within the bounds.
        """
        lo, hi = self.reward_range
        t_lo, t_hi = self.terminal_reward_range
        return min(lo, lo / (1.0 - gamma), t_lo), max(hi, hi / (1.0 - gamma), t_hi)

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
