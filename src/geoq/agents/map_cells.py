"""The cells of the exploration map: a grid whose cells are k-d trees (parti-game's splits).

A :class:`CellTree` partitions an observation box. Its grid has a side per
dimension read from the data (the caller's choice); each grid cell is the root of
a k-d tree whose leaves are the map's cells. A leaf is split in two along one
dimension at a threshold; the lower part keeps the leaf's id, the upper part gets
the next one, so leaf ids only grow. Leaves exist only where a point was placed
(``locate(..., create=True)``): a grid cell without one is ``-1``.

Moore & Atkeson, "The parti-game algorithm for variable resolution reinforcement
learning in multidimensional state-spaces", Machine Learning 21, 1995.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from geoq._typing import FloatArray, IntArray

__all__ = ["CellTree"]

_INT_FIELDS = ("n_grid", "root", "node_dim", "node_low", "node_high", "node_leaf",
               "leaf_node", "leaf_root")  # fmt: skip
_FLOAT_FIELDS = ("low", "high", "side", "node_threshold", "leaf_low", "leaf_high")


class CellTree:
    """Leaves of k-d trees rooted at the cells of a grid over ``[low, high]``.

    Parameters
    ----------
    low, high : the box ``[d]`` (finite, ``low < high``).
    side : the grid's cell side ``[d]``; a side that is not positive becomes the box's span.
    """

    def __init__(self, low: FloatArray, high: FloatArray, side: FloatArray) -> None:
        self.low = np.asarray(low, dtype=np.float64).copy()
        self.high = np.asarray(high, dtype=np.float64).copy()
        span = self.high - self.low
        side = np.asarray(side, dtype=np.float64)
        self.side = np.where(side > 0, side, span)
        self.n_grid: IntArray = np.maximum(np.ceil(span / self.side).astype(np.int64), 1)
        self.root: IntArray = np.full(int(np.prod(self.n_grid)), -1, dtype=np.int64)
        d = self.low.size
        # nodes: split dimension (-1: a leaf), threshold, children, leaf id
        self.node_dim = np.zeros(0, dtype=np.int64)
        self.node_threshold = np.zeros(0)
        self.node_low = np.zeros(0, dtype=np.int64)
        self.node_high = np.zeros(0, dtype=np.int64)
        self.node_leaf = np.zeros(0, dtype=np.int64)
        self.leaf_node = np.zeros(0, dtype=np.int64)
        self.leaf_low = np.zeros((0, d))
        self.leaf_high = np.zeros((0, d))
        self.leaf_root = np.zeros(0, dtype=np.int64)

    @property
    def n_leaves(self) -> int:
        """Number of leaves (the map's cells)."""
        return int(self.leaf_low.shape[0])

    @property
    def dim(self) -> int:
        """Dimension of the box."""
        return int(self.low.size)

    def grid_index(self, X: FloatArray) -> IntArray:
        """Flat grid-cell index ``[n]`` of points ``X [n, d]`` (outside points: the nearest)."""
        g = np.floor((X - self.low) / self.side).astype(np.int64)
        flat = np.ravel_multi_index(np.clip(g, 0, self.n_grid - 1).T, tuple(self.n_grid))
        return np.asarray(flat, dtype=np.int64)

    def _add_node(self, leaf: int) -> int:
        node = self.node_dim.size
        self.node_dim = np.append(self.node_dim, -1)
        self.node_threshold = np.append(self.node_threshold, 0.0)
        self.node_low = np.append(self.node_low, -1)
        self.node_high = np.append(self.node_high, -1)
        self.node_leaf = np.append(self.node_leaf, leaf)
        return node

    def _add_leaf(self, low: FloatArray, high: FloatArray, root: int) -> int:
        leaf = self.n_leaves
        node = self._add_node(leaf)
        self.leaf_node = np.append(self.leaf_node, node)
        self.leaf_low = np.vstack([self.leaf_low, low])
        self.leaf_high = np.vstack([self.leaf_high, high])
        self.leaf_root = np.append(self.leaf_root, root)
        return node

    def locate(self, X: FloatArray, create: bool = False) -> IntArray:
        """Leaf ids ``[n]`` of points ``X [n, d]``; -1 in a grid cell without a leaf.

        ``create``: first give every grid cell holding a point a leaf (in increasing
        grid index, so the ids do not depend on the points' order within ``X``).
        """
        flat = self.grid_index(X)
        if create:
            for f in np.unique(flat[self.root[flat] < 0]):
                g = np.array(np.unravel_index(int(f), tuple(self.n_grid)))
                low = self.low + g * self.side
                self.root[f] = self._add_leaf(low, low + self.side, int(f))
        node = self.root[flat]
        inner = node >= 0
        while True:
            idx = np.flatnonzero(inner & (self.node_dim[np.maximum(node, 0)] >= 0))
            if idx.size == 0:
                break
            nd = node[idx]
            above = X[idx, self.node_dim[nd]] >= self.node_threshold[nd]
            node[idx] = np.where(above, self.node_high[nd], self.node_low[nd])
        return np.where(inner, self.node_leaf[np.maximum(node, 0)], -1)

    def split(self, leaf: int, dim: int, threshold: float) -> int:
        """Split ``leaf`` at ``threshold`` along ``dim``; it keeps the part below, the part
        above becomes a new leaf, whose id is returned."""
        node = int(self.leaf_node[leaf])
        if not self.leaf_low[leaf, dim] < threshold < self.leaf_high[leaf, dim]:
            raise ValueError(f"threshold {threshold} is outside leaf {leaf} along dim {dim}")
        upper_low = self.leaf_low[leaf].copy()
        upper_low[dim] = threshold
        high_node = self._add_leaf(upper_low, self.leaf_high[leaf], int(self.leaf_root[leaf]))
        low_node = self._add_node(leaf)
        self.leaf_node[leaf] = low_node
        self.leaf_high[leaf, dim] = threshold
        self.node_dim[node], self.node_threshold[node] = dim, threshold
        self.node_low[node], self.node_high[node], self.node_leaf[node] = low_node, high_node, -1
        return self.n_leaves - 1

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The tree as named arrays (:meth:`from_arrays` inverts it)."""
        return {name: getattr(self, name) for name in _INT_FIELDS + _FLOAT_FIELDS}

    @classmethod
    def from_arrays(cls, arrays: dict[str, Any]) -> CellTree:
        """A tree from :meth:`to_arrays`' output; ``ValueError`` if it is inconsistent."""
        tree = cls.__new__(cls)
        for name in _INT_FIELDS:
            setattr(tree, name, np.asarray(arrays[name], dtype=np.int64))
        for name in _FLOAT_FIELDS:
            setattr(tree, name, np.asarray(arrays[name], dtype=np.float64))
        d, n_nodes, n_leaves = tree.low.size, tree.node_dim.size, tree.leaf_node.size
        if (
            tree.high.shape != (d,) or tree.side.shape != (d,) or tree.n_grid.shape != (d,)
            or tree.root.size != int(np.prod(tree.n_grid))
            or tree.leaf_low.shape != (n_leaves, d) or tree.leaf_high.shape != (n_leaves, d)
            or tree.leaf_root.shape != (n_leaves,)
            or any(getattr(tree, f).shape != (n_nodes,)
                   for f in ("node_threshold", "node_low", "node_high", "node_leaf"))
            or np.any(tree.root >= n_nodes) or np.any(tree.leaf_node >= n_nodes)
            or np.any(tree.node_leaf >= n_leaves)
            or np.any(np.maximum(tree.node_low, tree.node_high) >= n_nodes)
        ):  # fmt: skip
            raise ValueError("inconsistent exploration-map cells")
        return tree
