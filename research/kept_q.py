"""Would ``Q``'s greedy policy hold if the agent kept the ``Q`` that proved itself? (issue 46)

``GPQAgent(ENV, seed=SEED)`` with defaults (or ``--config``'s settings) learns
``--steps`` steps in ``learn(500)`` chunks (the control-suite protocol's checkpoints;
the agent's own column is the benchmark's curve). The agent is copied at the start
of every training episode; where ``Q`` acts in that episode (no policy acting), the
copy is the ``Q`` the episode's return measures. Two records keep a champion:

- ``one``: the copy whose one episode returned the most so far;
- ``two``: the copy that ran the later of two episodes in a row run by ``Q``, whose mean
  return is the most so far (a ``Q`` that did well twice running).

At each checkpoint it prints the mean greedy return of 10 episodes (evaluation seed
``10_000 + SEED``) of the agent and, where the agent's greedy actions are ``Q``'s, of
each champion (``Q`` alone on the copy; a champion evaluated once, as its greedy
actions draw nothing). Nothing here changes what the agent learns::

    .venv/bin/python research/kept_q.py Walker2d-v5 --seed 6 --out kq/6.json

``--pair kq/*.json`` prints each champion's curve less the agent's (finals, last four
checkpoints, every checkpoint: mean, Student-t 95% interval, seeds ahead), and with
``--sac DIR`` (a ``geoq bench-control --baseline sac`` folder of the same seeds) each
curve's finals less SAC's (``research/against_sac.py``'s arithmetic).
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

CHUNK = 500
EPISODES = 10


def _frozen(agent: Any) -> Any:
    """A copy of ``agent`` without its env, whose policy neither acts nor is on trial."""
    env, agent.env = agent.env, None
    try:
        copied = copy.deepcopy(agent)
    finally:
        agent.env = env
    copied.planning.feedback.acting = False
    copied.planning.feedback.kept = None
    return copied


class _Champions:
    """The copies that ran ``Q``'s episodes and the two records' champions."""

    def __init__(self) -> None:
        self.running: Any = None  # the copy running the current episode (None: a policy)
        self.previous: float | None = None  # the return of Q's episode before, in a row
        self.one: tuple[float, Any, int] | None = None
        self.two: tuple[float, Any, int] | None = None

    def start(self, agent: Any) -> None:
        acting = agent.planning.feedback.acting
        self.running = None if acting else _frozen(agent)

    def end(self, agent: Any, ret: float) -> None:
        if self.running is not None:
            t = agent.num_timesteps
            if self.one is None or ret >= self.one[0]:
                self.one = (ret, self.running, t)
            if self.previous is not None:
                mean = 0.5 * (self.previous + ret)
                if self.two is None or mean >= self.two[0]:
                    self.two = (mean, self.running, t)
            self.previous = ret
        else:
            self.previous = None
        self.start(agent)


def pair(files: list[Path], sac: Path | None) -> None:
    """Print the champions against the agent (and each curve's finals against SAC's)."""
    from against_sac import cells, paired

    runs = sorted((json.loads(f.read_text()) for f in files), key=lambda r: r["seed"])
    print("seeds", [r["seed"] for r in runs])
    theirs = cells(sac, baseline=True) if sac is not None else {}
    for name in ("agent", "one", "two"):
        finals = np.array([r[name][-1] for r in runs])
        print(f"{name}: finals {' / '.join(f'{x:.1f}' for x in finals)}, "
              f"median {np.median(finals):.1f}")  # fmt: skip
        if name != "agent":
            for label, part in (("finals", slice(-1, None)), ("last four", slice(-4, None)),
                                ("every checkpoint", slice(None))):  # fmt: skip
                d = np.array([np.mean(r[name][part]) - np.mean(r["agent"][part]) for r in runs])
                print(f"  less the agent, {label}: {paired(d)}")
        if theirs:
            d = np.array([r[name][-1] - theirs[r["seed"]]["eval_return"][-1] for r in runs])
            print(f"  finals less SAC's: {paired(d)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", nargs="?", help="Gymnasium id (or module:id)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--config", type=Path, default=None, help="JSON file of settings")
    parser.add_argument("--out", type=Path, default=None, help="JSON file of the curves")
    parser.add_argument("--pair", type=Path, nargs="+", default=None, help="--out files")
    parser.add_argument("--sac", type=Path, default=None, help="bench-control folder")
    args = parser.parse_args()
    if args.pair is not None:
        pair(args.pair, args.sac)
        return
    if args.env is None:
        parser.error("ENV is needed unless --pair is given")

    from geoq.agents import GPQAgent
    from geoq.experiments.control.evaluation import evaluate_agent

    def greedy(actor: Any) -> float:
        return float(evaluate_agent(actor, args.env, EPISODES, seed=10_000 + args.seed)
                     .returns.mean())  # fmt: skip

    settings = json.loads(args.config.read_text()) if args.config is not None else {}
    agent = GPQAgent(args.env, seed=args.seed, **settings)
    champions, scores = _Champions(), {}
    curves: dict[str, list[float]] = {"agent": [], "one": [], "two": []}
    print("steps | agent | Q greedy | one (record, crowned at) | two (record, crowned at)",
          flush=True)  # fmt: skip
    start = time.perf_counter()
    for k in range(args.steps // CHUNK):
        champions.start(agent)
        agent.learn(CHUNK, callback=lambda rec: champions.end(agent, rec.ret))
        own = greedy(agent)
        curves["agent"].append(own)
        cells = []
        for name in ("one", "two"):
            champion = getattr(champions, name)
            if agent.planning.greedy_active or champion is None:
                value, text = own, "-"
            else:
                if id(champion[1]) not in scores:
                    scores[id(champion[1])] = greedy(champion[1])
                value = scores[id(champion[1])]
                text = f"{value:.1f} ({champion[0]:.1f}, {champion[2]})"
            curves[name].append(value)
            cells.append(text)
        q = "no" if agent.planning.greedy_active else "yes"
        print(f"{(k + 1) * CHUNK} | {own:.1f} | {q} | {cells[0]} | {cells[1]}  "
              f"({time.perf_counter() - start:.0f} s)", flush=True)  # fmt: skip
    if args.out is not None:
        args.out.write_text(json.dumps({"seed": args.seed, "env": args.env} | curves))


if __name__ == "__main__":
    main()
