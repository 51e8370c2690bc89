"""An :class:`~geoq.graph.MDPGraph` as plain arrays (``.npz`` without pickle) and back.

:func:`graph_from_arrays` restores the state bit for bit (no replay of the
additions) after :func:`check_saved_state` has checked the invariants a genuine
state satisfies, so a tampered or corrupt file fails with a ``ValueError``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from geoq._typing import FloatArray, IntArray

if TYPE_CHECKING:
    from geoq.graph.mdp_graph import MDPGraph

__all__ = ["check_saved_state", "graph_from_arrays", "graph_to_arrays"]


def graph_to_arrays(g: MDPGraph) -> dict[str, np.ndarray]:
    """Configuration and full state (nodes, weights, P, roll-out bookkeeping) as arrays."""
    g._refresh_paths()
    n = g._n
    out: dict[str, np.ndarray] = {
        "eps": np.asarray(g.eps),
        "edge_weight": np.asarray(g.edge_weight),
        "temporal_edges": np.asarray(g.temporal_edges),
        "dim": np.asarray(-1 if g._dim is None else g._dim),
        "nodes": g._X[:n].copy(),
        "weights": g._W[:n, :n].copy(),
        "shortest_paths": g._P[:n, :n].copy(),
        "rollout_ids": g._ids[:n].copy(),
        "current_rollout": np.asarray(g._rollout),
    }
    if g.period is not None:
        out["period"] = g.period.copy()
    return out


def graph_from_arrays(cls: type[MDPGraph], arrays: dict[str, np.ndarray]) -> MDPGraph:
    """Inverse of :func:`graph_to_arrays`: a ``cls`` with the saved state, bit for bit."""
    edge_weight = str(arrays["edge_weight"])
    if edge_weight not in ("squared", "euclidean"):
        raise ValueError(f"saved graph has an unknown edge_weight {edge_weight!r}")
    nodes = np.atleast_2d(np.asarray(arrays["nodes"], dtype=np.float64))
    n = int(nodes.shape[0])
    g = cls(
        float(arrays["eps"]),
        edge_weight=edge_weight,  # type: ignore[arg-type]
        period=arrays.get("period"),
        temporal_edges=bool(arrays["temporal_edges"]),
        capacity=max(n, 16),
    )
    dim = int(arrays["dim"])
    W = np.asarray(arrays["weights"], dtype=np.float64)
    P = np.asarray(arrays["shortest_paths"], dtype=np.float64)
    ids = np.asarray(arrays["rollout_ids"], dtype=np.int64)
    check_saved_state(nodes, W, P, ids, dim)
    if dim >= 0:
        g._dim = dim
        g._X = np.zeros((g._cap, dim))
    g._X[:n] = nodes
    g._W[:n, :n] = W
    g._P[:n, :n] = P
    g._ids[:n] = ids
    g._n = n
    g._rollout = int(arrays["current_rollout"])
    g._view_cache = None
    return g


def check_saved_state(
    nodes: FloatArray, W: FloatArray, P: FloatArray, ids: IntArray, dim: int
) -> None:
    """Raise ``ValueError`` unless a saved graph state is self-consistent.

    Cheap (O(n^2)) invariants of a genuine state: shapes agree, nodes finite,
    weights symmetric and >= 0 (``inf`` = no edge, none on the diagonal), ``P``
    symmetric, >= 0, zero on the diagonal, never longer than a direct edge.
    """
    n = nodes.shape[0]
    if nodes.ndim != 2 or (dim >= 0 and n and nodes.shape[1] != dim):
        raise ValueError(f"saved graph nodes have shape {nodes.shape}; expected (n, {dim})")
    if W.shape != (n, n) or P.shape != (n, n) or ids.shape != (n,):
        raise ValueError(
            f"saved graph is inconsistent: {n} nodes but weights {W.shape}, "
            f"shortest_paths {P.shape}, rollout_ids {ids.shape}"
        )
    problems = []
    if not np.all(np.isfinite(nodes)):
        problems.append("nodes are not all finite")
    if np.any(np.isnan(W)) or np.any(W < 0) or not np.array_equal(W, W.T):
        problems.append("weights are not symmetric, non-negative and NaN-free")
    elif n and np.any(np.isfinite(np.diag(W))):
        problems.append("weights contain self-loops")
    if np.any(np.isnan(P)) or np.any(P < 0) or not np.array_equal(P, P.T):
        problems.append("shortest_paths are not symmetric, non-negative and NaN-free")
    elif np.any(np.diag(P) != 0.0):
        problems.append("shortest_paths have a non-zero diagonal")
    elif np.any(P > W * (1.0 + 1e-9)):
        problems.append("shortest_paths are longer than direct edges")
    if problems:
        raise ValueError(
            f"saved graph is corrupt or tampered with ({'; '.join(problems)}); save it again"
        )
