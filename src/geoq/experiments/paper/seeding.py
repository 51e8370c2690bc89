"""Named random streams of a reproduction, all derived from one root seed.

Every stream is ``SeedSequence(root_seed, spawn_key=key)``, which is exactly
what ``SeedSequence(root_seed).spawn(...)`` hands out, so a stream depends only
on the root seed and its key, never on the order in which cells run.
"""

from __future__ import annotations

import numpy as np

__all__ = ["STREAM", "rng_for"]

#: Stream ids. Per-seed streams use ``(seed, STREAM[...])``; run-wide streams
#: use a single key far above any seed index.
STREAM = {
    "train": 0,  # per seed: the GP's training roll-outs
    "eval_pairs": 1,  # per seed: held-out roll-outs the evaluation pairs come from
    "monte_carlo": 2,  # per seed: Monte-Carlo ground truth at the evaluation pairs
    "probe": 3,  # per seed: the perturbation of a rounding probe's training data
    "tuning": 1_000_001,  # run-wide: hyper-parameter selection data
    "graphs": 1_000_002,  # run-wide: Fig. 1 roll-outs
    "maps": 1_000_003,  # run-wide: Fig. 2 Monte-Carlo value map
    "td": 1_000_004,  # run-wide: the paper's TD baseline
}


def rng_for(root_seed: int, *key: int) -> np.random.Generator:
    """The generator of stream ``key`` under ``root_seed``."""
    return np.random.default_rng(
        np.random.SeedSequence(int(root_seed), spawn_key=tuple(int(k) for k in key))
    )
