"""When the agent explores with a :class:`~geoq.agents.state_map.StateMap`, and how.

``GPQConfig.explore_map`` says whether a map drives exploration: ``"auto"`` (the
default) decides once, after ``2 K`` steps (``K`` candidate actions; 64 on
TwoRooms), by :func:`moves_follow_actions` on the stored
transitions: a task whose moves are its actions' own (a point pushed around, walls
or not) gets a map; one whose state integrates a velocity (the pendulums, the
mountain car, MuJoCo's tasks) keeps the GP's exploration, unchanged to the bit.
``"on"`` builds the map at that step whatever the test says, ``"off"`` never.

With a map, the agent's training action is the explore plan's candidate (the GP
still learns from every step, online and in its fitted-Q phases) and its greedy
action (``predict(deterministic=True)``) is the exploit plan's where the map knows
a route to a termination, the GP's elsewhere.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np

from geoq._typing import FloatArray
from geoq.agents.buffer import TransitionBuffer, Transitions
from geoq.agents.state_map import StateMap

__all__ = ["EXPLORE_MAP_MODES", "ExploreMap", "MapExplorer", "moves_follow_actions"]

ExploreMap = Literal["auto", "on", "off"]
EXPLORE_MAP_MODES: tuple[str, ...] = ("auto", "on", "off")


def moves_follow_actions(
    states: FloatArray, actions: FloatArray, next_states: FloatArray, threshold: float = 0.5
) -> bool:
    """Whether every observation dimension's move ``s' - s`` is explained by the action.

    The least-squares fit of ``s' - s`` on ``[a, 1]`` explains at least ``threshold`` of
    each dimension's variance (``R^2``; a dimension that never moved is ignored). True
    for a point moved by its action (TwoRooms and its layouts: ``R^2`` 0.85-1.00 over
    the first 64-256 steps), False where the state integrates a velocity (swing-up,
    MountainCarContinuous, Pendulum-v1: the least dimension's ``R^2`` <= 0.08).
    """
    D = np.asarray(next_states, dtype=np.float64) - np.asarray(states, dtype=np.float64)
    X = np.hstack([np.asarray(actions, dtype=np.float64), np.ones((D.shape[0], 1))])
    coef, *_ = np.linalg.lstsq(X, D, rcond=None)
    total = np.sum((D - D.mean(axis=0)) ** 2, axis=0)
    residual = np.sum((D - X @ coef) ** 2, axis=0)
    moved = total > 0
    return bool(moved.any() and np.all(residual[moved] <= (1 - threshold) * total[moved]))


class MapExplorer:
    """The agent's map, from the step it is decided on (see the module docstring).

    Parameters
    ----------
    mode : ``"auto" | "on" | "off"``.
    candidates : the agent's candidate actions ``[K, d_a]``.
    action_low, action_high : the action box ``[d_a]``.
    gamma : the discount factor.
    """

    def __init__(self, mode: ExploreMap, candidates: FloatArray, action_low: FloatArray,
                 action_high: FloatArray, gamma: float) -> None:  # fmt: skip
        self.mode, self.candidates, self.gamma = mode, candidates, gamma
        low, high = np.asarray(action_low), np.asarray(action_high)
        self.half = 0.5 * (high - low)
        #: The candidates in the action box's own centred, scaled coordinates ``[K, d_a]``
        #: (``[-1, 1]^d_a``): the map compares moves there, so that relabelling the box
        #: (``[0, 1]`` for ``[-1, 1]``) changes nothing.
        self.centred = (np.asarray(candidates) - 0.5 * (low + high)) / self.half
        self.decided = mode == "off"
        self.map: StateMap | None = None

    @property
    def decide_after(self) -> int:
        """Transitions stored when the map is decided on: ``2 K``."""
        return 2 * len(self.candidates)

    def choices(self, actions: FloatArray) -> np.ndarray:
        """The candidate ``[n]`` nearest each action ``[n, d_a]`` (in half-ranges)."""
        diff = (actions[:, None, :] - self.candidates[None, :, :]) / self.half
        return np.argmin(np.sum(diff**2, axis=2), axis=1)

    def observe(self, buffer: TransitionBuffer, low: FloatArray | None,
                high: FloatArray | None) -> None:  # fmt: skip
        """Take in the buffer's newest transition; decide on the map when it is due.

        ``low, high``: the observation box ``[d_s]`` (infinite or None bounds: the
        stored states' range at the decision)."""
        if self.map is not None:
            s, a, r, s2, term = buffer.arrays(last=1)
            self.map.observe(s[0], int(self.choices(a)[0]), float(r[0]), s2[0], bool(term[0]))
        elif not self.decided and len(buffer) >= self.decide_after:
            self.decided = True
            stored = buffer.transitions()
            if self.mode == "on" or moves_follow_actions(
                stored.states, stored.actions, stored.next_states
            ):
                self.map = self._new_map(stored, low, high)

    def _new_map(self, stored: Transitions, low: FloatArray | None,
                 high: FloatArray | None) -> StateMap:  # fmt: skip
        seen = np.vstack([stored.states, stored.next_states])
        lo = seen.min(axis=0) if low is None else np.where(np.isfinite(low), low, seen.min(0))
        hi = seen.max(axis=0) if high is None else np.where(np.isfinite(high), high, seen.max(0))
        declared = (
            low is not None
            and high is not None
            and bool(np.all(np.isfinite(low)) and np.all(np.isfinite(high)))
        )
        return StateMap(lo, np.maximum(hi, lo + 1e-12), self.centred, self.gamma,
                        stored.states, self.choices(stored.actions), stored.rewards,
                        stored.next_states, stored.terminated, declared_box=declared)  # fmt: skip

    def action(self, s: FloatArray, rng: np.random.Generator) -> FloatArray | None:
        """The training action ``[1, d_a]`` at ``s [1, d_s]``: the map's, or None (no map)."""
        if self.map is None:
            return None
        return self.candidates[self.map.explore(s[0], rng)][None, :].copy()

    def plan(self) -> None:
        """Bring the map's plans up to date (the map also does so itself before it answers
        :meth:`action` or :meth:`greedy`, and before it is saved)."""
        if self.map is not None:
            self.map.plan()

    def greedy(self, states: FloatArray, mean: FloatArray, actions: FloatArray) -> FloatArray:
        """``actions [n, d_a]``, the GP's greedy ones at ``states [n, d_s]`` (posterior mean
        ``[n, K]`` at the candidates), where the map knows no route; elsewhere the exploit
        plan's best candidate, ties broken by the GP (:meth:`StateMap.greedy`)."""
        if self.map is None:
            return actions
        route, known = self.map.greedy(states)
        k = np.argmax(np.where(route, mean, -np.inf), axis=1)
        return np.where(known[:, None], self.candidates[k], actions)

    def to_arrays(self) -> dict[str, Any]:
        """The explorer's state as named arrays (:meth:`restore` reads them back)."""
        out: dict[str, Any] = {"decided": np.bool_(self.decided)}
        if self.map is not None:
            self.map.plan()  # a file holds the plans of the map it holds
            out.update({f"map/{k}": v for k, v in self.map.to_arrays().items()})
        return out

    def restore(self, arrays: dict[str, Any]) -> None:
        """Read :meth:`to_arrays`' output; empty (a file from before the map): the agent
        keeps exploring as it did, without one. ``ValueError`` if inconsistent."""
        if not arrays:
            self.decided = True
            return
        decided = np.asarray(arrays.get("decided"))
        if decided.shape != () or decided.dtype.kind not in "bi" or int(decided) not in (0, 1):
            raise ValueError("inconsistent exploration map: decided is not a flag")
        self.decided = bool(decided)
        maps = {k[4:]: v for k, v in arrays.items() if k.startswith("map/")}
        if not maps:
            self.map = None
            return
        if self.mode == "off":
            raise ValueError("inconsistent exploration map: explore_map is 'off' but a map is "
                             "stored")  # fmt: skip
        if not self.decided:
            raise ValueError("inconsistent exploration map: a map stored before it was decided on")
        m = StateMap.from_arrays(maps)
        # a file from before the centred coordinates holds the raw candidates
        if m.candidates.shape != self.centred.shape or not (
            np.array_equal(m.candidates, self.centred)
            or np.array_equal(m.candidates, self.candidates)
        ):
            raise ValueError("inconsistent exploration map: its candidates are not the agent's")
        m.candidates = self.centred.copy()
        if m.gamma != self.gamma:
            raise ValueError(f"inconsistent exploration map: gamma {m.gamma} is not the "
                             f"agent's {self.gamma}")  # fmt: skip
        self.map = m
