"""Effective resistances of a graph: from scratch, and updated per added / removed node.

Array functions behind :class:`geoq.kernels.graph_pd.ResistanceDistance`.
``R`` [s, s] is the effective-resistance matrix of one connected component;
every update is written in ``R`` alone (Woodbury on the Laplacian's
pseudo-inverse ``L^+``, whose differences ``(e_i - e_j)^T L^+ (e_p - e_q)`` are
``(R_iq + R_jp - R_ip - R_jq) / 2``), costs O(s^2 k) for ``k`` edges, and is two
matrix products plus a few passes over ``R``:

* **add** node ``v`` with edge resistances ``w_e`` to nodes ``q_e``: ``v`` is hung
  as a leaf on its strongest neighbour ``a`` (``R[v, j] = w_a + R[a, j]``); an
  edge into another component merges it (``R[x, y] = R[x, v] + w_b + R[b, y]``);
  the ``k'`` remaining edges close cycles and enter at once by Woodbury on the
  Laplacian's pseudo-inverse, written in ``R`` alone (:func:`add_edges`)::

      Y[i, e] = (R[i, q_e] - R[i, v]) / 2               # [s, k'] potentials
      S = diag(w) + B^T L^+ B,  (B^T L^+ B)_ef = (R[v, q_e] + R[v, q_f] - R[q_e, q_f]) / 2
      R'_ij = R_ij - (Y_i - Y_j)^T S^{-1} (Y_i - Y_j)

  (for one edge: ``R' = R - (Y_i - Y_j)^2 / (w + R[v, q])``; ``w = 0``, a short
  circuit, is its limit and needs no special case).
* **remove** node ``v`` (:func:`remove_node_resistances`): ``v`` is first shorted
  to its strongest neighbour ``a`` (one rank-one term, ``R^H``), then its other
  edges, now edges from ``a``, are taken out by Woodbury with the capacitance
  ``K = diag(w) - H_NN``, ``H_nm = (R^H[n, a] + R^H[m, a] - R^H[n, m]) / 2``:
  ``R'_ij = R^H_ij + (Y_i - Y_j)^T K^{-1} (Y_i - Y_j)``. A leaf goes without any
  update. ``K`` is singular when the removal splits the component (``v`` is a
  cut vertex) and undefined for a zero-length edge of ``v``: the caller checks
  both first and recomputes the component instead; a failed Cholesky
  factorisation of ``K`` returns None, with the same remedy.

From scratch (:func:`effective_resistance`): short circuits merged, then per
component the Laplacian grounded at its first node is inverted through its
Cholesky factor (``potrf``, ``potri``), O(s^3).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse
from scipy.sparse.csgraph import connected_components

from geoq._typing import FloatArray, IntArray

__all__ = [
    "add_edges",
    "components_of",
    "effective_resistance",
    "parallel_part",
    "remove_node_resistances",
]


def effective_resistance(W: FloatArray, components: IntArray | None = None) -> FloatArray:
    """Effective resistances [n, n] of a graph with edge resistances ``W`` [n, n].

    ``W`` is symmetric, ``inf`` where there is no edge; zero entries are short
    circuits. ``R = inf`` between different connected components.
    ``components`` [n] optionally gives the connected-component label of each
    node (0, 1, ...), e.g. from :func:`components_of`, sparing the search.
    """
    n = W.shape[0]
    if n == 0:
        return np.zeros((0, 0))
    edge = np.isfinite(W)
    np.fill_diagonal(edge, False)
    short = edge & (W == 0.0)
    if short.any():  # merge the ends of short circuits; conductances of parallel edges add
        n_super, label = connected_components(scipy.sparse.csr_array(short), directed=False)
        rows, cols = np.nonzero(edge & ~short)
        C = np.zeros((n_super, n_super))
        np.add.at(C, (label[rows], label[cols]), 1.0 / W[rows, cols])
        np.fill_diagonal(C, 0.0)
        components = None  # labels of the merged nodes: searched below
    else:
        n_super, label = n, None
        C = np.divide(1.0, W, out=np.zeros_like(W), where=edge)  # [n, n] conductances
    if components is None:
        n_comp, comp = connected_components(scipy.sparse.csr_array(C > 0), directed=False)
    else:
        n_comp, comp = int(components.max()) + 1, components
    Rq = np.full((n_super, n_super), np.inf)
    for c in range(n_comp):
        idx = np.flatnonzero(comp == c) if n_comp > 1 else np.arange(n_super)
        Rc = _component_resistance(C if n_comp == 1 else C[np.ix_(idx, idx)])
        if n_comp == 1:
            Rq = Rc
        else:
            Rq[np.ix_(idx, idx)] = Rc
    return Rq if label is None else Rq[np.ix_(label, label)]


def components_of(P: FloatArray) -> IntArray:
    """Connected-component labels [n] (0, 1, ... in order of first node) from a matrix
    [n, n] that is finite exactly between connected nodes (shortest paths, ``R``)."""
    n = P.shape[0]
    label = np.full(n, -1, dtype=np.int64)
    c = 0
    for i in range(n):
        if label[i] < 0:
            label[np.isfinite(P[i])] = c
            c += 1
    return label


def _component_resistance(C: FloatArray) -> FloatArray:
    """Effective resistances [s, s] of a connected graph of conductances ``C`` [s, s].

    ``G`` = inverse of the Laplacian grounded at node 0 (PD: connected), by its
    Cholesky factor (``potrf``, ``potri``); ``R_ij = G_ii + G_jj - 2 G_ij``.
    """
    s = C.shape[0]
    if s == 1:
        return np.zeros((1, 1))
    L = -C  # [s, s] Laplacian
    L[np.diag_indices(s)] = C.sum(axis=1)
    G = np.zeros((s, s))
    Lf, info = scipy.linalg.lapack.dpotrf(L[1:, 1:], lower=0)
    if info == 0:
        Gi, info = scipy.linalg.lapack.dpotri(Lf, lower=0)  # upper triangle of the inverse
    if info == 0:
        Gu = np.triu(Gi)
        G[1:, 1:] = Gu + np.triu(Gu, 1).T
    else:  # conductances spanning ~1e16: fall back to L^+ (itself inaccurate there)
        G = scipy.linalg.pinvh(L)
    g = np.diag(G).copy()
    Rc = np.add.outer(g, g)
    Rc -= 2.0 * G
    np.maximum(Rc, 0.0, out=Rc)
    np.fill_diagonal(Rc, 0.0)
    Rc += Rc.T  # exactly symmetric
    Rc *= 0.5
    return Rc


def _low_rank_update(R: FloatArray, Y: FloatArray, S: FloatArray, sign: float) -> FloatArray | None:
    """``R + sign * D(Y S^{-1} Y^T)`` [s, s] with ``D(G)_ij = G_ii + G_jj - 2 G_ij``, clipped at 0.

    ``Y`` [s, k], ``S`` [k, k] symmetric positive definite; None if its Cholesky
    factorisation fails (the update does not apply). ``S^{-1} = L^{-T} L^{-1}``, so
    ``Y S^{-1} Y^T = T T^T`` with ``T = Y L^{-T}``: two matrix products; the second
    is symmetrised, so the result is exactly symmetric.
    """
    try:
        L = scipy.linalg.cholesky(S, lower=True, check_finite=False)  # [k, k]
    except np.linalg.LinAlgError:
        return None
    Linv, info = scipy.linalg.lapack.dtrtri(L, lower=1)
    if info != 0:
        return None
    T = Y @ Linv.T  # [s, k]
    G = T @ T.T  # [s, s]; symmetric only to rounding, so:
    G += G.T  # 2 x the symmetric part, exactly symmetric
    G *= 0.5
    g = np.diag(G).copy()
    D = np.add.outer(g, g)
    D -= 2.0 * G
    out = R + D if sign > 0 else R - D
    np.maximum(out, 0.0, out=out)
    return out


def add_edges(R: FloatArray, p: int, q: IntArray, w: FloatArray) -> FloatArray | None:
    """Effective resistances [s, s] after adding resistors ``w`` [k] from node ``p`` to ``q`` [k].

    ``R`` [s, s] is one connected component (finite). Woodbury on ``L^+`` written
    in ``R`` (module docstring): ``R' = R - D(Y S^{-1} Y^T)``,
    ``Y[:, e] = (R[:, q_e] - R[:, p]) / 2``, ``S = diag(w) + B^T L^+ B``. A zero
    ``w`` (short circuit) is allowed; one between ends already at ``R = 0``
    changes nothing and is skipped. None if ``S`` is singular (several short
    circuits that coincide): recompute instead.
    """
    keep = (w > 0.0) | (R[p, q] > 0.0)
    q, w = q[keep], w[keep]
    if q.size == 0:
        return R
    Y = 0.5 * (R[:, q] - R[:, p : p + 1])  # [s, k]
    rp = R[p, q]  # [k]
    S = 0.5 * (np.add.outer(rp, rp) - R[np.ix_(q, q)])  # [k, k] = B^T L^+ B
    S[np.diag_indices_from(S)] += w
    return _low_rank_update(R, Y, S, -1.0)


def remove_node_resistances(
    R: FloatArray, v: int, nbr: IntArray, w: FloatArray
) -> FloatArray | None:
    """Effective resistances [s, s] of one component after node ``v`` loses its edges.

    ``R`` [s, s] is the component with ``v`` (finite); ``nbr`` [k >= 2] the
    neighbours of ``v``, ``w`` [k] > 0 their resistances. Row and column ``v`` of
    the result are meaningless (the caller drops them). ``v`` is shorted to its
    strongest neighbour ``a`` (``R^H``, a rank-one term), then the other edges,
    now resistors from the grounded ``a``, are removed by Woodbury with the
    capacitance ``K = diag(w) - H_NN`` (module docstring). None if ``K`` is not
    positive definite: the remaining graph is disconnected (or nearly so);
    recompute instead.
    """
    order = np.argsort(w, kind="stable")
    a, rest, wr = int(nbr[order[0]]), nbr[order[1:]], w[order[1:]]
    u = 0.5 * (R[:, a] - R[:, v])  # [s]
    du = np.subtract.outer(u, u)
    RH = R - du * du / R[a, v]  # v shorted to a
    Y = 0.5 * (RH[:, a : a + 1] - RH[:, rest])  # [s, k - 1]
    h = RH[rest, a]
    K = -0.5 * (np.add.outer(h, h) - RH[np.ix_(rest, rest)])  # -H_NN
    K[np.diag_indices_from(K)] += wr
    return _low_rank_update(RH, Y, K, 1.0)


def parallel_part(w_old: float, w_new: float) -> float:
    """Resistance of the resistor that, in parallel with ``w_old``, gives ``w_new <= w_old``."""
    if np.isinf(w_old) or w_new == 0.0:
        return w_new
    return w_old * w_new / (w_old - w_new)
