"""The control-suite protocol's cells for chosen seeds only (issue 46, part twenty-nine).

``geoq bench-control --seeds N`` runs seeds ``0 .. N-1``; to add seeds to a setting
measured before, or to run a setting on seeds another run already has beside it, this
runs the same cell (:func:`geoq.experiments.control.benchmark.control_cell`: 5,000 steps,
10 greedy episodes every 500) for each seed given, and writes each row as
``OUT/cells/seedS.json`` (atomically; a seed whose file exists is skipped), which
``research/against_sac.py`` reads::

    .venv/bin/python research/protocol_cells.py Walker2d-v5 OUT --seeds 5 6 7 8 9 \\
        --config '{"noise": 0.1}'
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env", help="Gymnasium id (or module:id)")
    parser.add_argument("out", type=Path, help="folder; rows go to OUT/cells/seedS.json")
    parser.add_argument("--seeds", type=int, nargs="+", required=True)
    parser.add_argument("--config", default="{}", help="JSON object of GPQConfig settings")
    args = parser.parse_args()

    from geoq.experiments.control.benchmark import control_cell
    from geoq.experiments.control.evaluation import ControlCell

    config = json.loads(args.config)
    folder = args.out / "cells"
    folder.mkdir(parents=True, exist_ok=True)
    for seed in args.seeds:
        path = folder / f"seed{seed}.json"
        if path.exists():
            continue
        row = control_cell(ControlCell(args.env, "euclidean", seed, 5000, 500, 10, config))
        staged = path.with_suffix(".tmp")
        staged.write_text(json.dumps({"row": row}))
        staged.replace(path)
        print(f"seed {seed}: final {row['eval_return'][-1]:.1f}", flush=True)


if __name__ == "__main__":
    main()
