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
inner node has at most ``max_children`` children; every wide group of one
tree depth, and every part of one split level, is split at once
(:func:`_split_segments`, over :mod:`core.sah`).  Other builders
(:mod:`core.subdivision`) can replace the skeleton above objects, and heavy
objects can carry a subtree of chunks below them (:func:`graft_tree`).
"""

from dataclasses import dataclass
from functools import cached_property
from itertools import chain

import numpy as np

from .bounds import MAX, MIN, check_boxes, segment_union
from .errors import OccError
from .sah import bin_unions, sweep
from .tree import FlatTree

SAH_BINS = 16


@dataclass(eq=False)
class Hierarchy(FlatTree):
    """The culling hierarchy: a :class:`~core.tree.FlatTree` whose leaves are draw units
    (``leaf_unit``, ``-1`` for inner nodes)."""

    leaf_unit: np.ndarray = None

    @cached_property
    def is_leaf(self):
        """``(N,) bool`` (computed once: a refit changes boxes, never the structure)."""
        return self.leaf_unit >= 0

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


def _split_segments(box, start, length):
    """The binned-SAH split of many segments at once: per segment, the left side of the
    cheapest split ``S(L)|L| + S(R)|R|`` over ``SAH_BINS`` bins of the centres on all
    three axes (ties: lowest axis, then lowest split; all centres equal: the first half).

    box: ``(k, 2, 3)`` item boxes; segment i is ``box[start[i]:start[i] + length[i]]``,
    lengths >= 2, segments disjoint.  Returns ``(rows, left)``: the rows of the
    segments in order and the ``bool`` mask of each row's left side.
    """
    p, b_ = len(start), SAH_BINS
    seg = np.repeat(np.arange(p), length)
    offs = np.cumsum(length) - length
    rows = np.repeat(start - offs, length) + np.arange(int(length.sum()))
    b = box[rows]
    centre = 0.5 * (b[:, MIN] + b[:, MAX])
    lo = np.minimum.reduceat(centre, offs, axis=0)
    extent = np.maximum.reduceat(centre, offs, axis=0) - lo
    ok = extent > 0.0                                           # (p, 3) axes with a spread
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (centre - lo[seg]) / extent[seg] * b_
    bins = np.minimum(np.where(ok[seg], t, 0.0).astype(np.int64), b_ - 1)      # (r, 3)
    # bins outermost, so the prefix and suffix scans below run over contiguous blocks
    key = (bins * p + seg[:, None]) * 3 + np.arange(3)        # (r, 3): the bin of a row on each axis
    count = np.bincount(key.ravel(), minlength=b_ * p * 3).reshape(b_, p, 3)
    bmin = np.full((3, b_ * p * 3), np.inf)
    bmax = np.full((3, b_ * p * 3), -np.inf)
    for axis in range(3):                                       # per-bin unions
        bin_unions(key[:, axis], b[:, MIN].T, b[:, MAX].T, bmin, bmax)
    bmin, bmax = bmin.T.reshape(b_, p, 3, 3), bmax.T.reshape(b_, p, 3, 3)
    # both sides of every split, per (segment, axis)
    la, lcount, ra, rcount = sweep(bmin, bmax, count)
    cost = np.where((lcount > 0) & (rcount > 0) & ok, la * lcount + ra * rcount, np.inf)
    cost = cost.transpose(1, 2, 0)                              # (segment, axis, split)
    cost = cost.reshape(p, -1)
    best = np.argmin(cost, axis=1)           # first minimum: lowest axis, then lowest split
    found = cost[np.arange(p), best] < np.inf
    axis, s = best // (b_ - 1), best % (b_ - 1)
    left = bins[np.arange(len(rows)), axis[seg]] <= s[seg]
    half = np.arange(len(rows)) - offs[seg] < (length // 2)[seg]   # all centres coincide
    return rows, np.where(found[seg], left, half)


class _Builder:
    """Collects nodes as (box, children or unit) before flattening breadth-first."""

    def __init__(self, unit_bounds, max_children):
        self.unit_bounds = unit_bounds
        self.max_children = max_children
        self._box = np.zeros((max(16, len(unit_bounds)), 2, 3))   # node boxes, grown by doubling
        self.n = 0
        self.kids, self.units = [], []

    @property
    def boxes(self):
        """``(n, 2, 3)`` the boxes of the nodes so far (a view)."""
        return self._box[:self.n]

    def _add(self, boxes, kids, units):
        """Append nodes: ``(k, 2, 3)`` boxes, their children, their units; returns the first id."""
        first, need = self.n, self.n + len(boxes)
        if need > len(self._box):
            grown = np.zeros((max(need, 2 * len(self._box)), 2, 3))
            grown[:first] = self._box[:first]
            self._box = grown
        self._box[first:need] = boxes
        self.n = need
        self.kids.extend(kids)
        self.units.extend(units)
        return first

    def leaf(self, unit):
        return self._add(self.unit_bounds[unit][None], [()], [int(unit)])

    def leaves(self, units):
        """Leaves of ``units`` (``(k,) int``) at once; returns their node ids ``(k,) int64``."""
        units = np.asarray(units, dtype=np.int64)
        first = self._add(self.unit_bounds[units], [()] * len(units), units.tolist())
        return np.arange(first, first + len(units))

    def group(self, items):
        """A node over ``items`` (node ids); None when empty; the item itself when single."""
        return self.groups([items])[0]

    def groups(self, lists):
        """:meth:`group` of each list of node ids; the wide ones split all together."""
        out, wide = [], []
        for items in lists:
            items = list(items)
            if len(items) > self.max_children:
                wide.append((len(out), items))
                out.append(None)
            elif len(items) > 1:
                box = self._box[items]
                union = np.stack([box[:, MIN].min(axis=0), box[:, MAX].max(axis=0)])
                out.append(self._add(union[None], [tuple(items)], [-1]))
            else:
                out.append(items[0] if items else None)
        if wide:
            for (j, _), node in zip(wide, self._split_groups([w for _, w in wide]), strict=True):
                out[j] = node
        return out

    def _split_groups(self, lists):
        """Nodes over lists of more than max_children items: all groups of a level split at once.

        Builds what the recursive rule builds (tests/test_hierarchy_build.py checks it
        against that rule): SAH-split the largest part of a group (the first one on a tie)
        until there are max_children parts; parts of one item are that item, parts of at
        most max_children items a node over them, larger parts groups of the next level.
        """
        m = self.max_children
        glen = np.array([len(items) for items in lists], dtype=np.int64)
        gstart = np.cumsum(glen) - glen
        perm = np.fromiter(chain.from_iterable(lists), np.int64, int(glen.sum()))
        box = self._box[perm]
        # kids set below, as every group's
        gnode = self._add(segment_union(box, gstart, glen), [()] * len(lists), [-1] * len(lists)) \
            + np.arange(len(lists))
        roots = gnode.tolist()
        while len(gstart):
            g = len(gstart)
            pg, ps, pl, pk = np.arange(g), gstart.copy(), glen.copy(), np.zeros(g, np.int64)
            nparts, active, nextkey = np.ones(g, np.int64), np.ones(g, bool), 1
            while True:
                cand = np.flatnonzero((active & (nparts < m))[pg])
                if not len(cand):
                    break
                c = cand[np.lexsort((pk[cand], -pl[cand], pg[cand]))]
                big = c[np.r_[True, pg[c][1:] != pg[c][:-1]]]   # largest part per group, first on a tie
                small = pl[big] < 2
                active[pg[big[small]]] = False
                big = big[~small]
                if not len(big):
                    break
                rows, left = _split_segments(box, ps[big], pl[big])
                seg = np.repeat(np.arange(len(big)), pl[big])
                order = np.lexsort((~left, seg))               # stable: left side first, in order
                perm[rows], box[rows] = perm[rows[order]], box[rows[order]]
                nl = np.bincount(seg, weights=left, minlength=len(big)).astype(np.int64)
                pg = np.concatenate([pg, pg[big]])
                ps = np.concatenate([ps, ps[big] + nl])
                pl = np.concatenate([pl, pl[big] - nl])
                pk = np.concatenate([pk, np.full(len(big), nextkey + 1)])
                pl[big], pk[big] = nl, nextkey
                nparts[pg[big]] += 1
                nextkey += 2
            o = np.lexsort((pk, pg))                            # each group's parts, in list order
            pg, ps, pl = pg[o], ps[o], pl[o]
            multi = np.flatnonzero(pl > 1)
            ubox = segment_union(box, ps[multi], pl[multi])
            child = perm[ps].copy()                            # a part of one item is the item
            child[multi] = self.n + np.arange(len(multi))
            few = pl[multi] <= m                               # nodes over their items; the rest: next level
            rows = np.repeat(ps[multi] - np.cumsum(pl[multi]) + pl[multi], pl[multi]) + np.arange(pl[multi].sum())
            self._add(ubox, _slices(perm[rows].tolist(), pl[multi], few), [-1] * len(multi))
            for node, k in zip(gnode.tolist(), _slices(child.tolist(), np.bincount(pg, minlength=g)), strict=True):
                self.kids[node] = k
            deeper = pl > m
            gstart, glen, gnode = ps[deeper], pl[deeper], child[deeper]
        return roots

    def flatten(self, root):
        """The breadth-first :class:`Hierarchy` below ``root``, one level at a time."""
        count = np.fromiter(map(len, self.kids), np.int64, len(self.kids))
        kids = np.fromiter(chain.from_iterable(self.kids), np.int64, int(count.sum()))
        start = np.cumsum(count) - count
        order, first, parent, depth = [], [], [], []
        front, pos, n, d = np.array([root], np.int64), np.zeros(1, np.int64), 1, 0
        while len(front):           # breadth-first: children of a node land contiguously
            c = count[front]
            total = int(c.sum())
            at = np.cumsum(c) - c
            order.append(front)
            first.append(np.where(c > 0, n + at, -1))
            parent.append(pos if d else np.full(1, -1, np.int64))
            depth.append(np.full(len(front), d, np.int64))
            sub = np.repeat(start[front] - at, c) + np.arange(total)
            pos = np.repeat(np.arange(n - len(front), n), c)     # each child's parent position
            front, n, d = kids[sub], n + total, d + 1
        order = np.concatenate(order)
        return Hierarchy(
            bounds=self.boxes[order],
            first_child=np.concatenate(first),
            child_count=count[order],
            leaf_unit=np.array(self.units, dtype=np.int64)[order],
            parent=np.concatenate(parent),
            depth=np.concatenate(depth),
        )


def _slices(flat, lengths, keep=None):
    """Consecutive runs of ``lengths`` of the list ``flat`` as tuples (``keep``: ``(k,)
    bool``, the runs not kept are empty tuples), without an array per run."""
    ends = np.cumsum(lengths).tolist()
    starts = [0, *ends[:-1]]
    if keep is None:
        return [tuple(flat[a:b]) for a, b in zip(starts, ends, strict=True)]
    return [tuple(flat[a:b]) if k else () for a, b, k in zip(starts, ends, keep.tolist(), strict=True)]


def _depth(parent):
    """Depth of each tree node (roots 0), vectorised; OccError on a cycle."""
    t = len(parent)
    depth = np.zeros(t, dtype=np.int64)
    cur = np.asarray(parent, dtype=np.int64).copy()
    for _ in range(t + 1):
        alive = cur >= 0
        if not alive.any():
            return depth
        depth[alive] += 1
        cur[alive] = parent[cur[alive]]
    raise OccError("the scene tree has a cycle")


def _fold(builder, parent, own):
    """Group a tree bottom-up: each node's own items (node ids) then its children's groups.

    All nodes of one depth are grouped in one :meth:`_Builder.groups` call.  Returns
    the groups of the roots (None for an empty one), in tree order.
    """
    parent = np.asarray(parent, dtype=np.int64)
    depth = _depth(parent)
    items = [list(o) for o in own]
    roots = []
    for d in range(int(depth.max(initial=-1)), -1, -1):
        nodes = np.flatnonzero(depth == d).tolist()
        for node, sub in zip(nodes, builder.groups([items[i] for i in nodes]), strict=True):
            if parent[node] >= 0:
                if sub is not None:
                    items[parent[node]].append(sub)
            else:
                roots.append(sub)
    return roots


def graft_tree(builder, tree, item_node):
    """Add a :class:`core.subdivision.Tree` to ``builder``; returns its root's node id.

    item_node(item) gives the builder node of one item (a unit leaf or an
    object's subtree); a tree node's items and children become one group.
    """
    own = [[item_node(int(i)) for i in tree.order[start:start + count]]
           for start, count in zip(tree.item_start.tolist(), tree.item_count.tolist(), strict=True)]
    roots = _fold(builder, tree.parent, own)
    return roots[-1] if roots else None


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
        if tree is None and len(units) == 1:
            return b.leaf(units[0])
        if tree is None:
            return b.group([b.leaf(u) for u in units])
        return graft_tree(b, tree, lambda i: b.leaf(units[i]))

    if object_tree is not None:
        root = graft_tree(b, object_tree, object_node)
    else:
        tree_parent = np.asarray(tree_parent, dtype=np.int64)
        tree_object = np.asarray(tree_object, dtype=np.int64)
        # objects of one unit and no subtree (most of a large scene): their leaves at once
        single = np.array([len(u) == 1 and (unit_trees is None or unit_trees[i] is None)
                           for i, u in enumerate(object_units)], dtype=bool)
        leaf_of = np.full(n, -1, dtype=np.int64)
        at = np.flatnonzero(single)
        if len(at):
            leaf_of[at] = b.leaves([object_units[i][0] for i in at.tolist()])
        own = [[] if o < 0 else [int(leaf_of[o])] if single[o] else [object_node(o)]
               for o in tree_object.tolist()]
        roots = [r for r in _fold(b, tree_parent, own) if r is not None]
        carried = np.zeros(n, dtype=bool)
        carried[tree_object[tree_object >= 0]] = True
        roots.extend(int(leaf_of[o]) if single[o] else object_node(o) for o in np.flatnonzero(~carried).tolist())
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
