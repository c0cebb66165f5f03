"""Bounding-volume hierarchies as flat arrays, built from the scene's own tree.

Layout (breadth-first, root = node 0, the children of a node are contiguous):

- ``bounds``      ``(N, 2, 3) float64`` node boxes, each the union of its children's;
- ``first_child`` ``(N,) int64``, ``-1`` for leaves;
- ``child_count`` ``(N,) int64``, ``0`` for leaves;
- ``leaf_unit``   ``(N,) int64`` draw unit of a leaf (an object, or a chunk of its
                  mesh: see :mod:`core.units`), ``-1`` for inner nodes;
- ``parent``      ``(N,) int64``, ``-1`` for the root;
- ``depth``       ``(N,) int64``.

Builder: the scene tree gives the skeleton (glTF nodes, Blender collections);
chains of single-child groups collapse, and a group wider than ``max_children``
is split by a binned surface-area heuristic over its items' boxes until every
inner node has at most ``max_children`` children.  Other builders
(:mod:`core.subdivision`) can replace the skeleton above objects, and heavy
objects can carry a subtree of chunks below them (:func:`graft_tree`).
"""

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .bounds import MAX, MIN, check_boxes, segment_union, surface_area
from .errors import OccError

SAH_BINS = 16


@dataclass(eq=False)
class Hierarchy:
    bounds: np.ndarray
    first_child: np.ndarray
    child_count: np.ndarray
    leaf_unit: np.ndarray
    parent: np.ndarray
    depth: np.ndarray

    def __len__(self):
        return len(self.first_child)

    @cached_property
    def is_leaf(self):
        """``(N,) bool`` (computed once: a refit changes boxes, never the structure)."""
        return self.leaf_unit >= 0

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

    def refit(self, unit_bounds):
        """Recompute every node box from new unit boxes ``(u, 2, 3)``, bottom-up by depth."""
        ub = check_boxes(unit_bounds, "unit bounds")
        leaves = np.flatnonzero(self.is_leaf)
        self.bounds[leaves] = ub[self.leaf_unit[leaves]]
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
    """Collects nodes as (box, children or unit) before flattening breadth-first."""

    def __init__(self, unit_bounds, max_children):
        self.unit_bounds = unit_bounds
        self.max_children = max_children
        self.boxes, self.kids, self.units = [], [], []

    def leaf(self, unit):
        self.boxes.append(self.unit_bounds[unit])
        self.kids.append(())
        self.units.append(int(unit))
        return len(self.boxes) - 1

    def group(self, items):
        """A node over ``items`` (node ids); None when empty; the item itself when single."""
        items = list(items)
        if not items:
            return None
        if len(items) == 1:
            return items[0]
        if len(items) > self.max_children:
            # SAH-split the largest part until there are max_children parts, then
            # group each part: a k-ary node, about log_k(n) levels deep.
            parts = [np.array(items)]
            while len(parts) < self.max_children:
                big = max(range(len(parts)), key=lambda j: len(parts[j]))
                if len(parts[big]) < 2:
                    break
                arr = parts.pop(big)
                left = _sah_split(np.array([self.boxes[i] for i in arr]))
                parts += [arr[left], arr[~left]]
            items = [self.group(p.tolist()) for p in parts]
        box = np.array([self.boxes[i] for i in items])
        self.boxes.append(np.stack([box[:, MIN].min(axis=0), box[:, MAX].max(axis=0)]))
        self.kids.append(tuple(items))
        self.units.append(-1)
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
            leaf_unit=np.array(self.units, dtype=np.int64)[order],
            parent=np.array(parent, dtype=np.int64),
            depth=np.array(depth, dtype=np.int64),
        )


def _bottom_up(parent):
    """Tree nodes ordered deepest first (children before parents), vectorised depths."""
    t = len(parent)
    depth = np.zeros(t, dtype=np.int64)
    cur = np.asarray(parent, dtype=np.int64).copy()
    for _ in range(t + 1):
        alive = cur >= 0
        if not alive.any():
            return np.argsort(-depth, kind="stable")
        depth[alive] += 1
        cur[alive] = parent[cur[alive]]
    raise OccError("the scene tree has a cycle")


def graft_tree(builder, tree, item_node):
    """Add a :class:`core.subdivision.Tree` to ``builder``; returns its root's node id.

    item_node(item) gives the builder node of one item (a unit leaf or an
    object's subtree); a tree node's items and children become one group.
    """
    items = [[] for _ in range(len(tree.first_child))]
    root = None
    for node in _bottom_up(tree.parent):
        start, count = tree.item_start[node], tree.item_count[node]
        own = [item_node(int(i)) for i in tree.order[start:start + count]]
        sub = builder.group(own + items[node])
        if tree.parent[node] >= 0:
            if sub is not None:
                items[tree.parent[node]].append(sub)
        else:
            root = sub
    return root


def build_hierarchy(unit_bounds, object_units, tree_parent, tree_object, max_children=8,
                    unit_trees=None, object_tree=None):
    """Hierarchy over draw units.

    unit_bounds: ``(u, 2, 3)`` world boxes of the units; object_units: per object
    the ``(k,)`` units it is drawn with (one, or its chunks); unit_trees: per
    object a chunk :class:`core.subdivision.Tree` over its units, or None;
    object_tree: a Tree over the objects replacing the scene tree skeleton, or
    None to follow ``tree_parent`` / ``tree_object``.  Returns None for no units.
    """
    ub = check_boxes(unit_bounds, "unit bounds")
    if max_children < 2:
        raise OccError(f"max_children must be >= 2, got {max_children}")
    n = len(object_units)
    if n == 0 or len(ub) == 0:
        return None
    b = _Builder(ub, max_children)

    def object_node(obj):
        units = object_units[obj]
        tree = unit_trees[obj] if unit_trees is not None else None
        if tree is None:
            return b.group([b.leaf(u) for u in units])
        return graft_tree(b, tree, lambda i: b.leaf(units[i]))

    if object_tree is not None:
        root = graft_tree(b, object_tree, object_node)
    else:
        tree_parent = np.asarray(tree_parent, dtype=np.int64)
        tree_object = np.asarray(tree_object, dtype=np.int64)
        items = [[] for _ in range(len(tree_parent))]
        roots = []
        for node in _bottom_up(tree_parent):       # build time, once per tree node
            own = [object_node(tree_object[node])] if tree_object[node] >= 0 else []
            sub = b.group(own + items[node])
            if sub is not None:
                (items[tree_parent[node]] if tree_parent[node] >= 0 else roots).append(sub)
        carried = np.zeros(n, dtype=bool)
        carried[tree_object[tree_object >= 0]] = True
        roots.extend(object_node(o) for o in np.flatnonzero(~carried))
        root = b.group(roots)
    h = b.flatten(root)
    h.refit(ub)                 # grafted boxes were transformed: make every box the tight union
    return h


def build_from_tree(object_bounds, tree_parent, tree_object, max_children=8):
    """Hierarchy with one unit per object (unit i = object i), following the scene tree.

    object_bounds: ``(n, 2, 3)``; tree_parent, tree_object: ``(t,)`` as in
    :class:`core.scene.Scene`.  Objects the tree does not carry hang under the
    root.  Returns None for an empty scene.
    """
    ob = check_boxes(object_bounds, "object bounds")
    return build_hierarchy(ob, [(i,) for i in range(len(ob))], tree_parent, tree_object,
                           max_children)
