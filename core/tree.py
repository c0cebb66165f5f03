"""The one flat tree type: nodes as arrays, breadth-first, root = node 0, the children
of a node contiguous.  :class:`core.hierarchy.Hierarchy` (the culling hierarchy, whose
leaves are draw units) and :class:`core.subdivision.Tree` (a builder's tree over item
ranges) are this type with their own per-node payload."""

from dataclasses import dataclass

import numpy as np


@dataclass(eq=False)
class FlatTree:
    """``bounds (N, 2, 3) float64``; ``first_child`` (``-1`` for a leaf), ``child_count``,
    ``parent`` (``-1`` for the root) and ``depth``, ``(N,) int64`` each."""

    bounds: np.ndarray
    first_child: np.ndarray
    child_count: np.ndarray
    parent: np.ndarray
    depth: np.ndarray

    def __len__(self) -> int:
        return len(self.first_child)

    def children(self, nodes) -> np.ndarray:
        """All children of ``nodes`` (in order), ``(k,) int64``; leaves contribute none."""
        nodes = np.asarray(nodes, dtype=np.int64)
        counts = self.child_count[nodes]
        total = int(counts.sum())
        if total == 0:
            return np.zeros(0, dtype=np.int64)
        starts = np.repeat(self.first_child[nodes], counts)
        offsets = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        return starts + offsets
