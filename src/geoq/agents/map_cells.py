"""The cells of the exploration map: a grid whose cells are k-d trees (parti-game's splits).

A :class:`CellTree` partitions an observation box. Its grid has a side per
dimension read from the data (the caller's choice); each grid cell is the root of
a k-d tree whose leaves are the map's cells. A leaf is split in two along one
dimension at a threshold; the lower part keeps the leaf's id, the upper part gets
the next one, so leaf ids only grow. Leaves exist only where a point was placed
(``locate(..., create=True)``): a grid cell without one is ``-1``.

The grid is sparse: only the grid cells holding a point are stored (their integer
coordinates, :attr:`CellTree.root_grid`), so memory and time follow the points placed,
never the box's size (a box of side ``2e5`` cut into cells of ``0.15`` has ``1.8e12``
grid cells per 2 dimensions).

Moore & Atkeson, "The parti-game algorithm for variable resolution reinforcement
learning in multidimensional state-spaces", Machine Learning 21, 1995.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from geoq._typing import FloatArray, IntArray

__all__ = ["CellTree", "around_sums"]

_INT_FIELDS = ("grid_low", "grid_high", "root_grid", "root_node", "node_dim", "node_low",
               "node_high", "node_leaf", "leaf_node", "leaf_root")  # fmt: skip
_FLOAT_FIELDS = ("low", "high", "side", "origin", "node_threshold", "leaf_low", "leaf_high")
#: Largest grid coordinate (either sign): coordinates stay exact in float64 and int64.
MAX_GRID = 2**52
#: Past this many grid cells along a dimension, the grid starts at ``anchor``, not at
#: ``low``: ``(x - low) / side`` would lose the bits that tell the cells apart
#: (``float32``'s largest number is a common "unbounded" bound).
MAX_PRECISE_CELLS = 2**40


class CellTree:
    """Leaves of k-d trees rooted at the cells of a grid over ``[low, high]``.

    Parameters
    ----------
    low, high : the box ``[d]`` (finite, ``low <= high``; a dimension with
        ``low == high`` is one grid cell wide).
    side : the grid's cell side ``[d]``; a side that is not a positive finite number
        becomes the box's span (1 where the span is 0).
    anchor : a point ``[d]`` (a state seen) where the grid starts along the dimensions
        whose box holds more than ``MAX_PRECISE_CELLS`` cells; elsewhere it starts at
        ``low`` (default: at ``low`` everywhere).

    Attributes
    ----------
    root_grid : ``[R, d]`` the integer coordinates of the grid cells that hold a point, in
        the order their roots were made; ``root_node`` ``[R]`` each one's root node.
    leaf_root : ``[L]`` the row of ``root_grid`` each leaf lies in.
    """

    def __init__(self, low: FloatArray, high: FloatArray, side: FloatArray,
                 anchor: FloatArray | None = None) -> None:  # fmt: skip
        self.low = _vector(low, "low")
        self.high = _vector(high, "high", self.low.size)
        if np.any(self.high < self.low):
            raise ValueError("the map's box needs low <= high in every dimension")
        span = self.high - self.low
        side = np.broadcast_to(np.asarray(side, dtype=np.float64), span.shape)
        fallback = np.where(span > 0, span, 1.0)
        self.side = np.where(np.isfinite(side) & (side > 0), side, fallback)
        wide = span / self.side > MAX_PRECISE_CELLS
        if anchor is not None:
            anchor = np.clip(_vector(anchor, "anchor", self.low.size), self.low, self.high)
        #: Where the grid starts ``[d]``: grid cell ``g`` spans ``origin + [g, g + 1] side``.
        self.origin = np.where(wide, self.low if anchor is None else anchor, self.low)
        #: The grid coordinates of the box's cells ``[d]``, first and last (``grid_coords``
        #: clips to them).
        self.grid_low = _cell(np.floor((self.low - self.origin) / self.side))
        self.grid_high = np.maximum(_cell(np.ceil((self.high - self.origin) / self.side)) - 1,
                                    self.grid_low)  # fmt: skip
        d = self.low.size
        self.root_grid = np.zeros((0, d), dtype=np.int64)
        self.root_node = np.zeros(0, dtype=np.int64)
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
        self._index_roots()

    @property
    def n_leaves(self) -> int:
        """Number of leaves (the map's cells)."""
        return int(self.leaf_low.shape[0])

    @property
    def n_roots(self) -> int:
        """Number of grid cells that hold a leaf."""
        return int(self.root_node.size)

    @property
    def dim(self) -> int:
        """Dimension of the box."""
        return int(self.low.size)

    # ------------------------------------------------------------------ the grid
    def grid_coords(self, X: FloatArray) -> IntArray:
        """Integer grid coordinates ``[n, d]`` of points ``X [n, d]`` (outside points: the
        nearest grid cell's)."""
        g = np.floor((np.asarray(X, dtype=np.float64) - self.origin) / self.side)
        return np.clip(g, self.grid_low, self.grid_high).astype(np.int64)

    def _index_roots(self) -> None:
        """The sorted keys that :meth:`roots_of` searches (after roots change)."""
        extents = (self.grid_high - self.grid_low + 1).tolist()
        #: C-order strides of the grid when its cells fit an int64 index (else None: the
        #: rows themselves are the keys).
        self._strides = None
        if math.prod(extents) < 2**62:
            self._strides = np.cumprod([1, *extents[:0:-1]])[::-1].astype(np.int64)
        keys = self._keys(self.root_grid)
        self._order = np.argsort(keys, kind="stable")
        self._sorted = keys[self._order]

    def _keys(self, coords: IntArray) -> np.ndarray:
        """One sortable key per row of ``coords [n, d]``, ordered as the rows are
        lexicographically: the flat grid index where it fits an int64, else the row."""
        if self._strides is None:
            return _row_keys(coords)
        return np.asarray((np.asarray(coords, dtype=np.int64) - self.grid_low) @ self._strides,
                          dtype=np.int64).reshape(-1)  # fmt: skip

    def roots_of(self, coords: IntArray) -> IntArray:
        """The row of :attr:`root_grid` ``[n]`` of each grid cell ``coords [n, d]``; -1 where
        the grid cell holds no leaf."""
        keys = self._keys(coords)
        if self.n_roots == 0:
            return np.full(keys.size, -1, dtype=np.int64)
        at = np.minimum(np.searchsorted(self._sorted, keys), self.n_roots - 1)
        return np.where(self._sorted[at] == keys, self._order[at], -1).astype(np.int64)

    def neighbour_pairs(self, coords: IntArray) -> tuple[IntArray, IntArray]:
        """Pairs ``(root, i)`` ``[m]`` each of a grid cell with a leaf and a row ``i`` of
        ``coords [n, d]`` at most one grid cell away along every dimension (the ``3^d``
        grid cells around the root's, itself included); memory and time follow the rows
        and roots, not ``3^d``."""
        if self.n_roots == 0 or len(coords) == 0:
            empty = np.zeros(0, dtype=np.int64)
            return empty, empty
        tree = cKDTree(np.asarray(coords, dtype=np.float64))
        near = tree.query_ball_point(self.root_grid.astype(np.float64), r=1.0, p=np.inf)
        sizes = np.fromiter((len(n) for n in near), dtype=np.int64, count=self.n_roots)
        rows = np.fromiter((i for n in near for i in n), dtype=np.int64, count=int(sizes.sum()))
        return np.repeat(np.arange(self.n_roots, dtype=np.int64), sizes), rows

    # ------------------------------------------------------------------ the trees
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
        grid coordinates, lexicographically, so the ids do not depend on the points'
        order within ``X``).
        """
        X = np.asarray(X, dtype=np.float64)
        coords = self.grid_coords(X)
        root = self.roots_of(coords)
        if create and np.any(root < 0):
            for g in np.unique(coords[root < 0], axis=0):
                low = self.origin + g * self.side
                r = self.n_roots
                self.root_grid = np.vstack([self.root_grid, g])
                self.root_node = np.append(self.root_node, self._add_leaf(low, low + self.side, r))
            self._index_roots()
            root = self.roots_of(coords)
        node = np.where(root >= 0, self.root_node[np.maximum(root, 0)], -1)
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
        if not (0 <= leaf < self.n_leaves and 0 <= dim < self.dim):
            raise ValueError(f"no leaf {leaf} or dimension {dim} to split "
                             f"({self.n_leaves} leaves, {self.dim} dimensions)")  # fmt: skip
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

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> dict[str, np.ndarray]:
        """The tree as named arrays (:meth:`from_arrays` inverts it)."""
        return {name: getattr(self, name) for name in _INT_FIELDS + _FLOAT_FIELDS}

    @classmethod
    def from_arrays(cls, arrays: dict[str, Any]) -> CellTree:
        """A tree from :meth:`to_arrays`' output (or a file's from before the sparse grid,
        with a dense ``root``); ``ValueError`` naming what is inconsistent."""
        arrays = _sparse_roots(arrays) if "root" in arrays else arrays
        tree = cls.__new__(cls)
        for name in _INT_FIELDS:
            setattr(tree, name, _array(arrays, name, np.int64))
        for name in _FLOAT_FIELDS:
            setattr(tree, name, _array(arrays, name, np.float64))
        tree._check()
        tree._index_roots()
        return tree

    def _check(self) -> None:
        """``ValueError`` unless the arrays make one k-d tree per stored grid cell whose
        leaves are exactly the leaf table's (so :meth:`locate` ends and lands on a leaf)."""
        d, n_nodes, L, R = self.low.size, self.node_dim.size, self.leaf_node.size, self.n_roots

        def bad(what: str) -> ValueError:
            return ValueError(f"inconsistent exploration-map cells: {what}")

        shapes = {"high": (d,), "side": (d,), "origin": (d,), "grid_low": (d,),
                  "grid_high": (d,), "root_grid": (R, d),
                  "leaf_low": (L, d), "leaf_high": (L, d), "leaf_root": (L,),
                  "node_threshold": (n_nodes,), "node_low": (n_nodes,),
                  "node_high": (n_nodes,), "node_leaf": (n_nodes,)}  # fmt: skip
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise bad(f"{name} has shape {getattr(self, name).shape}, expected {shape}")
        for name in _FLOAT_FIELDS:
            if not np.all(np.isfinite(getattr(self, name))):
                raise bad(f"{name} is not finite")
        if np.any(self.high < self.low) or np.any(self.side <= 0):
            raise bad("the box needs low <= high and a positive side")
        if (np.any(self.grid_low > self.grid_high) or np.any(np.abs(self.grid_low) > MAX_GRID)
                or np.any(np.abs(self.grid_high) > MAX_GRID)):  # fmt: skip
            raise bad("grid_low, grid_high out of range")
        if np.any(self.root_grid < self.grid_low) or np.any(self.root_grid > self.grid_high):
            raise bad("a root_grid cell lies outside the grid")
        if len(np.unique(self.root_grid, axis=0)) != R:
            raise bad("a grid cell has two roots")
        for name, size in (("root_node", n_nodes), ("leaf_node", n_nodes),
                           ("leaf_root", R)):  # fmt: skip
            values = getattr(self, name)
            if np.any(values < 0) or np.any(values >= size):
                raise bad(f"{name} out of range")
        if np.any(self.node_dim < -1) or np.any(self.node_dim >= d):
            raise bad("node_dim out of range")
        leaf, inner = self.node_dim < 0, self.node_dim >= 0
        children = np.concatenate([self.node_low[inner], self.node_high[inner]])
        if np.any(children < 0) or np.any(children >= n_nodes):
            raise bad("a node's child is out of range")
        if np.any(self.node_leaf[leaf] < 0) or np.any(self.node_leaf[leaf] >= L):
            raise bad("node_leaf out of range")
        # every node is the child of one node or one grid cell's root, exactly once
        parents = np.bincount(np.concatenate([children, self.root_node]), minlength=n_nodes)
        if np.any(parents != 1):
            raise bad("the nodes do not form one tree per grid cell")
        if not np.array_equal(np.sort(self.node_leaf[leaf]), np.arange(L)) or not np.array_equal(
            self.node_leaf[self.leaf_node], np.arange(L)
        ):
            raise bad("the leaves do not match the tree's leaf nodes")
        if np.any(self.leaf_low >= self.leaf_high):
            raise bad("a leaf is empty")
        _check_acyclic(self.root_node, self.node_dim, self.node_low, self.node_high, bad)


def _check_acyclic(roots: IntArray, dims: IntArray, lows: IntArray, highs: IntArray,
                   bad: Any) -> None:  # fmt: skip
    """``bad(...)`` unless walking down from the roots visits every node once (no cycle)."""
    seen = np.zeros(dims.size, dtype=bool)
    front = roots.copy()
    while front.size:
        if np.any(seen[front]):
            raise bad("a node is reached twice")
        seen[front] = True
        inner = front[dims[front] >= 0]
        front = np.concatenate([lows[inner], highs[inner]])
    if not seen.all():
        raise bad("a node is not reached from any root")


def _vector(x: Any, name: str, size: int | None = None) -> FloatArray:
    v = np.asarray(x, dtype=np.float64).copy()
    if v.ndim != 1 or v.size == 0 or (size is not None and v.size != size):
        want = "" if size is None else f" of {size}"
        raise ValueError(f"the map's box {name} must be a non-empty vector{want}, got shape "
                         f"{v.shape}")  # fmt: skip
    if not np.all(np.isfinite(v)):
        raise ValueError(f"the map's box {name} must be finite, got {v}")
    return v


def _cell(g: FloatArray) -> IntArray:
    """Float grid coordinates as int64, clipped to ``[-MAX_GRID, MAX_GRID]``."""
    return np.clip(g, -MAX_GRID, MAX_GRID).astype(np.int64)


def _row_keys(coords: IntArray) -> np.ndarray:
    """Rows of ``coords [n, d]`` (int64) as one sortable value each (lexicographic)."""
    c = np.ascontiguousarray(coords, dtype=np.int64)
    dtype = np.dtype([(f"f{i}", np.int64) for i in range(c.shape[1])])
    return c.view(dtype).reshape(-1)


def _array(arrays: dict[str, Any], name: str, dtype: Any) -> np.ndarray:
    if name not in arrays:
        raise ValueError(f"inconsistent exploration-map cells: no {name}")
    a = np.asarray(arrays[name])
    if a.dtype.kind not in "biuf":
        raise ValueError(f"inconsistent exploration-map cells: {name} is not numeric")
    out = a.astype(dtype)
    if dtype == np.int64 and a.dtype.kind == "f" and not np.array_equal(out, a):
        raise ValueError(f"inconsistent exploration-map cells: {name} is not integer")
    return out


def _sparse_roots(arrays: dict[str, Any]) -> dict[str, Any]:
    """A file's dense ``root`` (one entry per grid cell, -1: none; ``leaf_root`` flat
    grid indices) as the sparse grid's arrays."""
    root = np.asarray(arrays["root"], dtype=np.int64).ravel()
    n_grid = np.asarray(arrays.get("n_grid", []), dtype=np.int64).ravel()
    if n_grid.size == 0 or np.any(n_grid < 1) or root.size != math.prod(n_grid.tolist()):
        raise ValueError("inconsistent exploration-map cells: root does not match n_grid")
    flat = np.flatnonzero(root >= 0)
    flat = flat[np.argsort(root[flat], kind="stable")]  # in the order the roots were made
    position = np.full(root.size, -1, dtype=np.int64)
    position[flat] = np.arange(flat.size)
    leaf_root = np.asarray(arrays["leaf_root"], dtype=np.int64)
    if np.any(leaf_root < 0) or np.any(leaf_root >= root.size):
        raise ValueError("inconsistent exploration-map cells: leaf_root out of range")
    out = {k: v for k, v in arrays.items() if k not in ("root", "n_grid")}
    out["origin"] = arrays.get("low")
    out["grid_low"], out["grid_high"] = np.zeros_like(n_grid), n_grid - 1
    out["root_grid"] = np.stack(np.unravel_index(flat, tuple(n_grid)), axis=1).astype(np.int64)
    out["root_grid"] = out["root_grid"].reshape(flat.size, n_grid.size)
    out["root_node"] = root[flat]
    out["leaf_root"] = position[leaf_root]
    return out


def around_sums(cells: CellTree, starts: IntArray, values: FloatArray) -> FloatArray:
    """Sums ``[R, w]`` over the ``3^d`` grid cells around each of ``cells``' roots of the
    ``values [C, w]`` of the grid cells ``starts [C, d]`` (the others hold 0).

    The terms are added as a dense grid's shifted sums would add them (one axis after
    the other, each as ``(cell - 1 + cell) + cell + 1``), so the sums have the same bits;
    only the pairs of a root and a grid cell next to it are visited, so memory and time
    follow the data, never ``3^d`` or the box.
    """
    R = cells.n_roots
    root, row = cells.neighbour_pairs(starts)
    if root.size == 0:
        return np.zeros((R, values.shape[1]))
    offset = starts[row] - cells.root_grid[root]  # [m, d] in {-1, 0, 1}
    value = values[row].astype(np.float64)
    for ax in range(cells.dim):
        if not np.any(offset[:, ax]):
            continue  # (0 + x) + 0 is x
        keys = np.column_stack([root, offset[:, ax + 1 :]])
        groups, group = np.unique(keys, axis=0, return_inverse=True)
        slot = np.zeros((len(groups), 3, value.shape[1]))
        slot[group.reshape(-1), offset[:, ax] + 1] = value
        value = (slot[:, 0] + slot[:, 1]) + slot[:, 2]
        root, offset = groups[:, 0], np.column_stack([np.zeros((len(groups), ax + 1), np.int64),
                                                      groups[:, 1:]])  # fmt: skip
    out = np.zeros((R, values.shape[1]))
    out[root] = value
    return out
