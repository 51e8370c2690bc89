"""The model's one-step transitions in every fitted-Q phase, through the replay seam (issue 46).

The issue's item 3 in the loop: ``GPQAgent(ENV, seed=SEED)`` with defaults learns
``--steps`` steps in ``learn(500)`` chunks (the control-suite protocol's checkpoints) with
its phase's replay strategy replaced by :class:`ModelReplay`. Where the agent's own
dynamics model (``agent.planning.model``, fitted on the agent's own schedule) is fitted,
every phase adds, from each stored state of the window, one transition imagined by the
model's mean: the stored action plus ``--noise`` half-ranges of Gaussian noise (clipped to
the box; drawn from a generator of the seed's own, so the agent's draws are untouched
until the runs part), its next state, reward, and termination where its probability is
above 1/2; kept only where the next state is among the data (``model.support`` distance at
most 1). As the agent's ``replay="graph"`` does, the imagined rows shape the stored
targets through the sweeps, and the GP the agent acts with is refit to the stored rows
only (``FittedQPhase.run``), so its noise and its rows are the default's (a refit to more
rows is a lower-noise fit: ``research/model_targets.py --actions copy``).

At each checkpoint the mean greedy return of 10 episodes (evaluation seed
``10_000 + SEED``, the benchmark's) is recorded; ``--out DIR`` writes the curve as a cell
of ``geoq bench-control``'s form (``DIR/cells/SEED.json``), so that
``research/against_sac.py DIR --against OTHER`` pairs it with the default's cells::

    python research/model_replay.py Walker2d-v5 --seed 3 --out mr
    python research/against_sac.py mr --against w10   # w10: a bench-control folder
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

CHUNK = 500
EPISODES = 10


class ModelReplay:
    """The stored transitions and one imagined by the model per stored state (module
    docstring); no model fitted yet: the stored ones alone, as ``replay="uniform"``."""

    sweeps = True

    def __init__(self, agent: Any, noise: float, rng: np.random.Generator) -> None:
        self.agent, self.noise, self.rng = agent, noise, rng

    def extend(self, phase: Any, inp: Any) -> tuple[Any, np.ndarray, int | None]:
        from geoq.agents.buffer import Transitions

        stored, model = inp.stored, self.agent.planning.model
        if not model.fitted:
            return stored, inp.targets, 0
        lo, hi = self.agent.action_low, self.agent.action_high
        A = stored.actions + self.noise * 0.5 * (hi - lo) * self.rng.standard_normal(
            stored.actions.shape
        )
        A = np.clip(A, lo, hi)
        mean, d = model.predict_mean(stored.states, A), inp.obs_dim
        S2 = stored.states + mean[:, :d]
        inside = model.support.distance(S2) <= 1.0
        im = Transitions(stored.states[inside], A[inside], mean[inside, d], S2[inside],
                         mean[inside, d + 1] > 0.5)  # fmt: skip
        if len(im) == 0:
            return stored, inp.targets, 0
        y_im = inp.y_mean + inp.y_scale * inp.gp.predict(inp.inputs(im))
        return stored.then(im), np.concatenate([inp.targets, np.clip(y_im, *inp.bounds)]), len(im)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--noise", type=float, default=0.3)
    parser.add_argument("--out", type=Path, required=True, help="folder for the cell")
    args = parser.parse_args()

    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent

    agent = GPQAgent(args.env, seed=args.seed)
    replay = ModelReplay(agent, args.noise, np.random.default_rng([args.seed, 46]))
    agent.phase.replay = replay
    curve: list[float] = []
    learn = 0.0
    for k in range(args.steps // CHUNK):
        start = time.perf_counter()
        agent.learn(CHUNK)
        learn += time.perf_counter() - start
        result = evaluate_agent(agent, args.env, EPISODES, seed=10_000 + args.seed)
        curve.append(float(result.returns.mean()))
        imagined = agent.log.imagined_counts[-1] if agent.log.imagined_counts else 0
        print(f"{(k + 1) * CHUNK} | {curve[-1]:.1f} | imagined {imagined} | {learn:.0f} s",
              flush=True)  # fmt: skip
    row = {"label": "euclidean", "seed": args.seed, "eval_return": curve,
           "checkpoints": [(k + 1) * CHUNK for k in range(len(curve))],
           "ms_per_step": 1e3 * learn / args.steps, "learn_seconds": learn}  # fmt: skip
    (args.out / "cells").mkdir(parents=True, exist_ok=True)
    path = args.out / "cells" / f"{args.seed}.json"
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({"row": row}))
    tmp.replace(path)


if __name__ == "__main__":
    main()
