"""The agent against SAC (or another agent setting), seed by seed, from benchmark cells.

Reads the cells of ``geoq bench-control --out DIR`` (the agent's, and SAC's where the run
had ``--baseline sac``) and prints, for the seeds both hold: the finals per seed and their
medians, and the paired differences (agent less the other) of the finals, of the mean of
the last four checkpoints and of the mean of every checkpoint, each as the mean with its
Student-t 95% interval over seeds and the count of seeds ahead; then the cost of a
learning step beside the other's (``ms_per_step``, evaluations excluded), per seed::

    geoq bench-control --env Walker2d-v5 --seeds 10 --timesteps 5000 --eval-every 500 \\
        --eval-episodes 10 --baseline sac --out w10 -j 2
    .venv/bin/python research/against_sac.py w10
    .venv/bin/python research/against_sac.py noise_run --against w10  # agent vs agent
    .venv/bin/python research/against_sac.py noise_run --sac w10  # vs w10's SAC cells

With ``--against OTHER`` the agent's cells of ``DIR`` are paired with the agent's cells of
``OTHER`` instead (another setting, same seeds); with ``--sac OTHER``, with ``OTHER``'s SAC
cells (a setting run without ``--baseline``, against the SAC run of another folder).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

BASELINE = "sac"


def cells(folder: Path, baseline: bool) -> dict[int, dict[str, Any]]:
    """The rows of ``folder``'s cells (``cells/*.json``), SAC's or the agent's, by seed."""
    rows = [json.loads(f.read_text())["row"] for f in sorted((folder / "cells").glob("*.json"))]
    return {int(r["seed"]): r for r in rows if (r["label"] == BASELINE) == baseline}


def paired(d: np.ndarray) -> str:
    """``mean [low, high], ahead k/n`` of paired differences ``d`` [n]."""
    n, mean = len(d), float(d.mean())
    half = float(stats.t.ppf(0.975, n - 1) * d.std(ddof=1) / np.sqrt(n)) if n > 1 else np.nan
    return f"{mean:+.1f} [{mean - half:.1f}, {mean + half:.1f}], ahead {(d > 0).sum()}/{n}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="a geoq bench-control --out folder")
    parser.add_argument("--against", type=Path, default=None,
                        help="pair with this folder's agent cells instead of SAC's")  # fmt: skip
    parser.add_argument("--sac", type=Path, default=None,
                        help="pair with this folder's SAC cells instead of FOLDER's")  # fmt: skip
    args = parser.parse_args()
    if args.against is not None and args.sac is not None:
        parser.error("--against and --sac pair with different curves: give one")
    agent = cells(args.folder, baseline=False)
    other = (cells(args.against, False) if args.against
             else cells(args.sac or args.folder, baseline=True))  # fmt: skip
    seeds = sorted(set(agent) & set(other))
    if not seeds:
        raise SystemExit(f"no seed has cells of both in {args.folder}")
    name = str(args.against) if args.against else BASELINE
    curve = {s: np.asarray(agent[s]["eval_return"]) for s in seeds}
    theirs = {s: np.asarray(other[s]["eval_return"]) for s in seeds}
    for label, runs in (("agent", curve), (name, theirs)):
        finals = [runs[s][-1] for s in seeds]
        listed = " / ".join(f"{x:.1f}" for x in finals)
        print(f"{label} finals, seeds {seeds[0]}-{seeds[-1]}: {listed}; "
              f"median {np.median(finals):.1f}")  # fmt: skip
    for label, part in (("finals", slice(-1, None)), ("last four checkpoints", slice(-4, None)),
                        ("every checkpoint", slice(None))):  # fmt: skip
        d = np.array([curve[s][part].mean() - theirs[s][part].mean() for s in seeds])
        print(f"paired, {label}: {paired(d)}")
    ratio = [agent[s]["ms_per_step"] / other[s]["ms_per_step"] for s in seeds]
    print(f"ms per learning step: agent {min(agent[s]['ms_per_step'] for s in seeds):.1f}-"
          f"{max(agent[s]['ms_per_step'] for s in seeds):.1f}, {name} "
          f"{min(other[s]['ms_per_step'] for s in seeds):.1f}-"
          f"{max(other[s]['ms_per_step'] for s in seeds):.1f}; ratio per seed "
          f"{' '.join(f'{r:.1f}' for r in ratio)}")  # fmt: skip


if __name__ == "__main__":
    main()
