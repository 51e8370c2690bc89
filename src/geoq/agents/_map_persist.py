"""Reading an exploration map back from its arrays, every array checked; the checks of
a transition's candidate index and termination flag that the map shares with it."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from geoq._typing import IntArray
from geoq._validation import as_float_matrix, as_float_vector
from geoq.agents.map_cells import CellTree
from geoq.agents.map_settings import MapSettings

if TYPE_CHECKING:
    from geoq.agents.state_map import StateMap

__all__ = ["check_choices", "check_flags", "map_from_arrays"]


def map_from_arrays(cls: type[StateMap], arrays: dict[str, Any],
                    settings: MapSettings | None = None) -> StateMap:  # fmt: skip
    """A map from :meth:`to_arrays`' output; ``ValueError`` naming the first array that
    is inconsistent (every array is checked: a map that loads plans and acts).

    A map saved with its plans out of date (``changed``; files written from inside
    ``learn`` before the plans were brought up to date on save) loads too: its plans
    are solved again before they are used, from the values it holds."""

    def bad(what: str) -> ValueError:
        return ValueError(f"inconsistent exploration map: {what}")

    m = cls.__new__(cls)
    m.settings = settings or MapSettings()
    m.cells = CellTree.from_arrays({k[6:]: v for k, v in arrays.items() if k.startswith("cells/")})
    if "Q_greedy" not in arrays and "Q_exploit" in arrays:  # saved before the greedy plan
        arrays = {**arrays, "Q_greedy": arrays["Q_exploit"]}
    missing = [name for name in (*cls._ARRAYS, "counters") if name not in arrays]
    if missing:
        raise bad(f"no {missing}")
    d = m.cells.dim
    try:
        m.candidates = as_float_matrix(arrays["candidates"], "candidates")
        m.S = as_float_matrix(arrays["S"], "S", d)
        n = len(m.S)
        m.S2 = as_float_matrix(arrays["S2"], "S2", d)
        m.k = check_choices(arrays["k"], n, len(m.candidates))
        m.r = as_float_vector(arrays["r"], "r", n)
        m.done = check_flags(arrays["done"], n)
        counters = as_float_vector(arrays["counters"], "counters")
    except ValueError as exc:
        raise bad(str(exc)) from None
    if n == 0 or len(m.S2) != n or len(m.candidates) == 0:
        raise bad("no transitions, or S2 not one per state")
    if counters.shape not in ((4,), (6,)):
        raise bad(f"counters has shape {counters.shape}")
    # a map saved before the halving: none done, and none to do (it keeps on as it did)
    gamma, changed, plans, sweeps, halvings, declared = (*counters, 0.0, 0.0)[:6]
    if not 0.0 <= gamma < 1.0 or changed not in (0.0, 1.0) or declared not in (0.0, 1.0):
        raise bad("counters: gamma outside [0, 1) or a flag that is not 0 or 1")
    if any(c < 0 or c != int(c) for c in (plans, sweeps, halvings)):
        raise bad("counters: a count that is not a whole number >= 0")
    m.gamma, m.changed, m.plans, m.sweeps = float(gamma), bool(changed), int(plans), int(sweeps)
    m.halvings, m.declared_box = int(halvings), bool(declared)
    for name, points in (("leaf_s", m.S), ("leaf_s2", m.S2)):
        leaves = np.asarray(arrays[name])
        if leaves.shape != (n,) or not np.array_equal(leaves, m.cells.locate(points)):
            raise bad(f"{name} is not the leaf of each point")
        setattr(m, name, leaves.astype(np.int64))
    if np.any(m.leaf_s < 0):
        raise bad("a state lies in no leaf")
    L, K = m.cells.n_leaves, m.n_candidates
    for name in ("V_explore", "V_exploit", "Q_explore", "Q_exploit", "Q_greedy"):
        shape = (L,) if name[0] == "V" else (L, K)
        value = np.asarray(arrays[name])
        if value.dtype.kind not in "f" or value.shape[1:] != shape[1:]:
            raise bad(f"{name} has shape {value.shape} of dtype {value.dtype}")
        rows = value.shape[0]
        if rows != L and not (m.changed and rows < L):  # stale plans: solved again first
            raise bad(f"{name} has {rows} rows for {L} leaves")
        if (
            np.any(np.isnan(value))
            or np.any(value == np.inf)
            or (name[0] == "V" and not np.all(np.isfinite(value)))
        ):
            raise bad(f"{name} holds NaN or infinite values")
        pad = np.zeros((L - rows, *shape[1:]))
        setattr(m, name, np.concatenate([value.astype(np.float64), pad]))
    m._set_typical_moves()
    return m


def check_choices(k: Any, n: int, K: int) -> IntArray:
    """Candidate indices ``[n]`` in ``[0, K)`` (``ValueError`` otherwise)."""
    raw = np.asarray(k)
    if raw.shape != (n,) or (raw.size and raw.dtype.kind not in "iu"):
        raise ValueError(f"choices must be {n} integer candidate indices, got shape "
                         f"{raw.shape} of dtype {raw.dtype}")  # fmt: skip
    out = raw.astype(np.int64)
    if np.any(out < 0) or np.any(out >= K):
        raise ValueError(f"a choice is not a candidate index in [0, {K})")
    return out


def check_flags(terminated: Any, n: int) -> np.ndarray:
    """Termination flags ``[n]`` (bool, or numbers 0 and 1)."""
    raw = np.asarray(terminated)
    ok = raw.shape == (n,) and raw.dtype.kind in "biuf" and bool(np.all((raw == 0) | (raw == 1)))
    if not ok:
        raise ValueError(f"terminated must be {n} flags (True / False), got {raw!r:.80}")
    return raw.astype(bool).copy()
