"""Bounding-volume hierarchies as flat arrays, built from the scene's own tree.

Layout (breadth-first, root = node 0, the children of a node are contiguous):

- ``bounds``      ``(N, 2, 3) float64`` node boxes, each the union of its children's;
- ``first_child`` ``(N,) int64``, ``-1`` for leaves;
- ``child_count`` ``(N,) int64``, ``0`` for leaves;
- ``leaf_object`` ``(N,) int64`` object of a leaf, ``-1`` for inner nodes;
- ``parent``      ``(N,) int64``, ``-1`` for the root;
- ``depth``       ``(N,) int64``.

Builder: the scene tree gives the skeleton (glTF nodes, Blender collections);
chains of single-child groups collapse, and a group wider than ``max_children``
is split by a binned surface-area heuristic over its items' boxes until every
inner node has at most ``max_children`` children.
"""

from dataclasses import dataclass

import numpy as np

from .bounds import MAX, MIN, check_boxes, segment_union, surface_area
from .errors import OccError

SAH_BINS = 16


@dataclass(eq=False)
class Hierarchy:
    bounds: np.ndarray
    first_child: np.ndarray
    child_count: np.ndarray
    leaf_object: np.ndarray
    parent: np.ndarray
    depth: np.ndarray

    def __len__(self):
        return len(self.first_child)

    @property
    def is_leaf(self):
        return self.leaf_object >= 0

    def children(self, nodes):
        """All children of ``nodes`` (in order), ``(k,) int64``; leaves contribute none."""
        nodes = np.asarray(nodes, dtype=np.int64)
        counts = self.child_count[nodes]
        total = int(counts.sum())
        if total == 0:
            return np.zeros(0, dtype=np.int64)
        starts = np.repeat(self.first_child[nodes], counts)
        offsets = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        return starts + offsets

    def leaves_below(self, nodes):
        """Leaf nodes in the subtrees of ``nodes`` (the nodes themselves if leaves)."""
        out, front = [], np.asarray(nodes, dtype=np.int64)
        while len(front):
            leaf = self.is_leaf[front]
            out.append(front[leaf])
            front = self.children(front[~leaf])
        return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)

    def refit(self, object_bounds):
        """Recompute every node box from new object boxes ``(n, 2, 3)``, bottom-up by depth."""
        ob = check_boxes(object_bounds, "object bounds")
        leaves = np.flatnonzero(self.is_leaf)
        self.bounds[leaves] = ob[self.leaf_object[leaves]]
        for d in range(int(self.depth.max(initial=0)) - 1, -1, -1):
            inner = np.flatnonzero((self.depth == d) & ~self.is_leaf)
            if len(inner):
                # children of consecutive inner nodes at one depth are consecutive
                self.bounds[inner] = segment_union(
                    self.bounds, self.first_child[inner], self.child_count[inner])


def _sah_split(boxes):
    """Best binned-SAH partition of items with boxes ``(k, 2, 3)``, k >= 2.

    Returns a ``(k,) bool`` mask of the left side, never all-True or all-False.
    """
    k = len(boxes)
    centre = 0.5 * (boxes[:, MIN] + boxes[:, MAX])
    lo, hi = centre.min(axis=0), centre.max(axis=0)
    extent = hi - lo
    best_cost, best = np.inf, None
    for axis in np.flatnonzero(extent > 0.0):
        bins = np.minimum(((centre[:, axis] - lo[axis]) / extent[axis] * SAH_BINS).astype(np.int64),
                          SAH_BINS - 1)
        count = np.bincount(bins, minlength=SAH_BINS)
        bmin = np.full((SAH_BINS, 3), np.inf)
        bmax = np.full((SAH_BINS, 3), -np.inf)
        np.minimum.at(bmin, bins, boxes[:, MIN])
        np.maximum.at(bmax, bins, boxes[:, MAX])
        # prefix (left of split s = bins < s) and suffix unions, splits s = 1..B-1
        lmin, lmax = np.minimum.accumulate(bmin)[:-1], np.maximum.accumulate(bmax)[:-1]
        rmin = np.minimum.accumulate(bmin[::-1])[::-1][1:]
        rmax = np.maximum.accumulate(bmax[::-1])[::-1][1:]
        lcount = np.cumsum(count)[:-1]
        rcount = k - lcount
        la = surface_area(np.stack([lmin, lmax], axis=1))
        ra = surface_area(np.stack([rmin, rmax], axis=1))
        cost = np.where((lcount > 0) & (rcount > 0), la * lcount + ra * rcount, np.inf)
        s = int(np.argmin(cost))
        if cost[s] < best_cost:
            best_cost, best = cost[s], bins <= s
    if best is None:              # all centres coincide: split the list in half
        best = np.arange(k) < k // 2
    return best


class _Builder:
    """Collects nodes as (box, children or object) before flattening breadth-first."""

    def __init__(self, object_bounds, max_children):
        self.object_bounds = object_bounds
        self.max_children = max_children
        self.boxes, self.kids, self.objects = [], [], []

    def leaf(self, obj):
        self.boxes.append(self.object_bounds[obj])
        self.kids.append(())
        self.objects.append(int(obj))
        return len(self.boxes) - 1

    def group(self, items):
        """A node over ``items`` (node ids); None when empty; the item itself when single."""
        items = list(items)
        if not items:
            return None
        if len(items) == 1:
            return items[0]
        if len(items) > self.max_children:
            boxes = np.array([self.boxes[i] for i in items])
            left = _sah_split(boxes)
            arr = np.array(items)
            items = [self.group(arr[left].tolist()), self.group(arr[~left].tolist())]
        box = np.array([self.boxes[i] for i in items])
        self.boxes.append(np.stack([box[:, MIN].min(axis=0), box[:, MAX].max(axis=0)]))
        self.kids.append(tuple(items))
        self.objects.append(-1)
        return len(self.boxes) - 1

    def flatten(self, root):
        order, first, count, parent, depth = [root], [], [], [-1], [0]
        i = 0
        while i < len(order):      # breadth-first: children of a node land contiguously
            node = order[i]
            kids = self.kids[node]
            first.append(len(order) if kids else -1)
            count.append(len(kids))
            for c in kids:
                order.append(c)
                parent.append(i)
                depth.append(depth[i] + 1)
            i += 1
        order = np.array(order)
        return Hierarchy(
            bounds=np.array(self.boxes, dtype=np.float64).reshape(-1, 2, 3)[order],
            first_child=np.array(first, dtype=np.int64),
            child_count=np.array(count, dtype=np.int64),
            leaf_object=np.array(self.objects, dtype=np.int64)[order],
            parent=np.array(parent, dtype=np.int64),
            depth=np.array(depth, dtype=np.int64),
        )


def build_from_tree(object_bounds, tree_parent, tree_object, max_children=8):
    """Hierarchy over objects following the scene tree, with SAH splits of wide groups.

    object_bounds: ``(n, 2, 3)``; tree_parent, tree_object: ``(t,)`` as in
    :class:`core.scene.Scene`.  Objects the tree does not carry hang under the
    root.  Returns None for an empty scene.
    """
    ob = check_boxes(object_bounds, "object bounds")
    if max_children < 2:
        raise OccError(f"max_children must be >= 2, got {max_children}")
    tree_parent = np.asarray(tree_parent, dtype=np.int64)
    tree_object = np.asarray(tree_object, dtype=np.int64)
    n, t = len(ob), len(tree_parent)
    if n == 0:
        return None
    b = _Builder(ob, max_children)
    # Depth of each tree node, vectorised (one step per level), then deepest first.
    depth = np.zeros(t, dtype=np.int64)
    cur = tree_parent.copy()
    for _ in range(t + 1):
        alive = cur >= 0
        if not alive.any():
            break
        depth[alive] += 1
        cur[alive] = tree_parent[cur[alive]]
    else:
        raise OccError("the scene tree has a cycle")
    items = [[] for _ in range(t)]
    roots = []
    for node in np.argsort(-depth, kind="stable"):      # build time, once per tree node
        own = [b.leaf(tree_object[node])] if tree_object[node] >= 0 else []
        sub = b.group(own + items[node])
        if sub is not None:
            (items[tree_parent[node]] if tree_parent[node] >= 0 else roots).append(sub)
    carried = np.zeros(n, dtype=bool)
    carried[tree_object[tree_object >= 0]] = True
    roots.extend(b.leaf(o) for o in np.flatnonzero(~carried))
    return b.flatten(b.group(roots))
