"""``keep_q``: greedy actions from the ``Q`` that did best on the task while it learned.

Past four inputs ``Q``'s greedy policy swings between checkpoints: on ``Walker2d-v5``
(ten seeds) the best checkpoint of each seed where ``Q`` acts is 314-789, and a later one
falls below 150 on most of them (docs/design-notes.md, part twenty-nine). The training
episodes see it happen. So at the start of each training episode ``Q`` acts in (no map's
plan, no planner's policy, the warm-up over), the agent copies ``Q`` as it is: its GP,
the actor trained on it, the input scaling and length-scales, and how many transitions
were stored (the data its greedy action is sought among,
:mod:`~geoq.agents.greedy_data`). Where the episode finishes (one cut short by
``learn``'s budget does not count), the copy is kept if the episode's return is at least
the return of the episode that kept the copy before (the ``record``): the ``Q`` whose
episode returned the most so far, the newer of equals (the mean of two episodes in a
row, measured beside it, did no better: design notes, part thirty).

Greedy actions where ``Q``'s would be taken (no policy's weights are the greedy ones)
are the kept copy's, by ``Q``'s own greedy rule (the actor's where it was ready, else
``greedy_actions``'s, among the transitions stored at the copy). Nothing learned reads
the copy: training actions, targets, phases and searches are the agent's own, so a run's
training is the same with or without it, and only its greedy checkpoints differ.
Off by default: it lifted ``Hopper-v5`` and ``Walker2d-v5`` and lowered
``InvertedDoublePendulum-v5``, where ``Q`` climbs and the best episode so far is an old
``Q``'s (docs/results.md, part thirty).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np

from geoq._typing import FloatArray
from geoq.agents.acquisition import choose_actions
from geoq.agents.buffer import TransitionBuffer, Transitions
from geoq.agents.greedy_data import act_in_data
from geoq.agents.q_actor import QActor
from geoq.gp import SparseOnlineGP
from geoq.learners.scaling import InputScaling

__all__ = ["KEEP_Q", "KeepQ", "KeptQ", "QCopy"]

#: ``GPQConfig.keep_q``.
KeepQ = Literal["on", "off"]
KEEP_Q: tuple[str, ...] = ("on", "off")


class _Agent(Protocol):
    """What :class:`KeptQ` reads of a :class:`~geoq.agents.GPQAgent`."""

    config: Any
    obs_dim: int
    action_low: FloatArray
    action_high: FloatArray
    candidates: FloatArray
    buffer: TransitionBuffer
    scaling: InputScaling
    gp: SparseOnlineGP
    actor: QActor
    state: Any
    explorer: Any
    planning: Any
    rng: np.random.Generator

    def _lengthscale(self) -> float | tuple[float, ...]: ...


@dataclass
class QCopy:
    """``Q`` as an episode started: the GP, the actor, the input scaling, the length-scales
    in use, the transitions stored (``stored``) and the standardisation ``y_mean, y_scale``."""

    gp: SparseOnlineGP
    actor: QActor
    scaling: InputScaling
    lengthscale: float | tuple[float, ...]
    stored: int
    y_mean: float
    y_scale: float


class _Stored:
    """The first ``n`` transitions of a buffer, as ``greedy_in_data`` reads them."""

    def __init__(self, buffer: TransitionBuffer, n: int):
        self.buffer, self.n = buffer, n

    def transitions(self, last: int | None = None) -> Transitions:
        lo = 0 if last is None else max(self.n - int(last), 0)
        return Transitions(*(column[lo : self.n] for column in self.buffer.arrays()))


class _Copied:
    """An agent whose ``Q`` is a :class:`QCopy` (what ``act_in_data`` reads)."""

    def __init__(self, agent: _Agent, q: QCopy):
        self.config, self.obs_dim, self.candidates = agent.config, agent.obs_dim, agent.candidates
        self.action_low, self.action_high = agent.action_low, agent.action_high
        self.buffer, self.scaling, self.gp = _Stored(agent.buffer, q.stored), q.scaling, q.gp
        self._ls = q.lengthscale

    def inputs(self, states: FloatArray, actions: FloatArray) -> FloatArray:
        return self.scaling.transform(np.hstack([states, actions]))

    def _lengthscale(self) -> float | tuple[float, ...]:
        return self._ls


class KeptQ:
    """The kept copy ``kept`` (None: none yet), the return that kept it ``record``, and the
    copy running the current episode ``running`` (None: another actor's, or none started);
    ``on``: whether the agent keeps one at all (module docstring)."""

    def __init__(self, on: bool):
        self.on = on
        self.kept: QCopy | None = None
        self.record = -np.inf
        self.running: QCopy | None = None

    def start_episode(self, agent: _Agent) -> None:
        """An episode starts: ``Q`` copied if it acts in it."""
        if not self.on:
            return
        acts = not (agent.state.scaling_pending or agent.explorer.map is not None
                    or agent.planning.active)  # fmt: skip
        self.running = None
        if acts:
            gp, actor, st = copy.deepcopy(agent.gp), copy.deepcopy(agent.actor), agent.state
            self.running = QCopy(gp, actor, agent.scaling, agent._lengthscale(), len(agent.buffer),
                                 st.y_mean, st.y_scale)  # fmt: skip

    def end_episode(self, ret: float) -> None:
        """The episode finished with return ``ret``: its copy (if ``Q`` ran it) is kept if
        ``ret`` is at least the ``record``."""
        if self.running is not None and ret >= self.record:
            self.kept, self.record = self.running, float(ret)
        self.running = None

    def greedy(self, agent: _Agent, states: FloatArray) -> FloatArray:
        """The kept copy's greedy actions ``[n, d_a]`` at ``states`` [n, d_s] (module
        docstring); draws nothing from the agent's generator."""
        q = self.kept
        assert q is not None
        if q.actor.ready:
            return q.actor.act(states)
        z = q.gp.predict(q.scaling.transform_pairs(states, agent.candidates))
        mean = (q.y_mean + q.y_scale * z).reshape(states.shape[0], -1)  # as the agent's
        if agent.config.greedy_actions == "data":
            return act_in_data(_Copied(agent, q), states, mean, "greedy", agent.rng)
        return choose_actions(mean, mean, agent.candidates, "greedy", beta=0.0,
                              noise_scale=np.zeros_like(agent.action_low), low=agent.action_low,
                              high=agent.action_high, rng=agent.rng)  # fmt: skip

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> dict[str, Any]:
        """The kept copy and its record (an agent's archive, prefix ``kept_q/``); nothing
        before one is kept. The running copy is not saved: an episode ends (and counts)
        before the agent can be saved, and ``learn`` starts a new one, which copies afresh."""
        q, arrays = self.kept, dict[str, Any]()
        if q is not None:
            arrays["record"] = np.array(self.record)
            arrays |= {f"gp/{k}": v for k, v in q.gp.to_arrays().items()}
            arrays |= {f"actor/{k}": v for k, v in q.actor.to_arrays().items()}
            arrays |= {"scale": np.array(q.scaling.scale, dtype=np.float64),
                       "lengthscale": np.atleast_1d(np.asarray(q.lengthscale, np.float64)),
                       "stored": np.int64(q.stored),
                       "y": np.array([q.y_mean, q.y_scale])}  # fmt: skip
        return arrays

    def restore(self, a: dict[str, Any], agent: _Agent, source: str) -> None:
        """Inverse of :meth:`to_arrays` for ``agent`` (its config, scaling, actor's mode and
        buffer); ``ValueError`` where the arrays do not fit it."""
        if not a:
            return
        if not self.on:
            raise ValueError("the file holds a kept Q, but its config's keep_q is off")
        record = np.asarray(a["record"], dtype=np.float64)
        if record.shape != () or not np.isfinite(record):
            raise ValueError(f"kept_q/record must be one finite return, got {record!r}")
        gp = SparseOnlineGP.from_arrays({k[3:]: v for k, v in a.items() if k.startswith("gp/")},
                                        source=source)  # fmt: skip
        d, stored, n = agent.scaling.dim, np.asarray(a["stored"]), len(agent.buffer)
        if stored.shape != () or stored.dtype.kind not in "iu" or not 0 <= stored <= n:
            raise ValueError(f"kept_q/stored must be one count within the buffer, got {stored!r}")
        scale, ls, y = (np.asarray(a[k], dtype=np.float64) for k in ("scale", "lengthscale", "y"))
        if scale.shape != (d,) or len(ls) not in (1, d) or ls.ndim != 1:
            raise ValueError(f"kept_q/scale must be [{d}] and kept_q/lengthscale [1] or [{d}]")
        if y.shape != (2,) or not (np.all(np.isfinite(y)) and y[1] > 0):
            raise ValueError("kept_q/y must be a finite y_mean and a y_scale > 0")
        if not (np.all(np.isfinite(ls)) and np.all(ls > 0)):
            raise ValueError("kept_q/lengthscale must be finite and > 0")
        if gp.n_bv and gp.basis_vectors.shape[1] != d:
            raise ValueError(f"the kept Q's GP inputs are not {d}-dimensional")
        scaling = InputScaling(tuple(scale.tolist()), agent.scaling.periods, agent.scaling.names)
        actor = QActor(agent.actor.mode, agent.action_low, agent.action_high)
        actor.restore({k[6:]: v for k, v in a.items() if k.startswith("actor/")}, agent.obs_dim)
        lengthscale = float(ls[0]) if len(ls) == 1 else tuple(ls.tolist())
        self.kept = QCopy(gp, actor, scaling, lengthscale, int(stored), float(y[0]), float(y[1]))
        self.record = float(record)
