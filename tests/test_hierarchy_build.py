"""The hierarchy builder: invariants on seeded scenes of several shapes, and the level-at-once
SAH grouping checked against the recursive rule it replaces (the same tree, node for node)."""

import numpy as np
import pytest

from core import hierarchy
from core.bounds import MAX, MIN
from core.hierarchy import Hierarchy, _Builder, build_from_tree, build_hierarchy
from tests.reference import sah_split


class _Recursive(_Builder):
    """The recursive grouping rule (one SAH split per Python call), the reference."""

    def groups(self, lists):
        return [self.group(items) for items in lists]

    def group(self, items):
        items = list(items)
        if not items:
            return None
        if len(items) == 1:
            return items[0]
        if len(items) > self.max_children:
            parts = [np.array(items)]
            while len(parts) < self.max_children:
                big = max(range(len(parts)), key=lambda j: len(parts[j]))
                if len(parts[big]) < 2:
                    break
                arr = parts.pop(big)
                left = sah_split(np.array([self.boxes[i] for i in arr]))
                parts += [arr[left], arr[~left]]
            items = [self.group(p.tolist()) for p in parts]
        box = np.array([self.boxes[i] for i in items])
        return self._add(np.stack([box[:, MIN].min(axis=0), box[:, MAX].max(axis=0)])[None], [tuple(items)], [-1])

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


SHAPES = ["random", "zero", "same", "dup", "rows"]
KINDS = ["flat", "deep", "none"]


def _boxes(rng, n, shape):
    if shape == "zero":                       # points: zero-size boxes
        c = rng.uniform(-50, 50, (n, 3))
        return np.stack([c, c], axis=1)
    if shape == "same":                       # every box at one point
        return np.zeros((n, 2, 3))
    if shape == "rows":                       # boxes in rows behind a wall, as the scale scene
        i = np.arange(n)
        c = np.column_stack([i % 250 * 2.0, i // 250 * 2.0 + 5.0, np.zeros(n)])
        b = np.stack([c - 0.5, c + 0.5], axis=1)
        b[0] = [[-10, 0, -5], [510, 1, 20]]   # the wall
        return b
    lo = rng.uniform(-100, 100, (n, 3))
    if shape == "dup":                        # many duplicates of three boxes
        lo = rng.uniform(-100, 100, (3, 3))[rng.integers(0, 3, n)]
    return np.stack([lo, lo + rng.uniform(0, 5, (n, 3))], axis=1)


def _tree(rng, n, kind):
    """(tree_parent, tree_object) of a flat collection, a deep random tree, or none."""
    if kind == "none":
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    if kind == "flat":                        # one collection (node 0) holding every object
        parent = np.r_[-1, np.zeros(n, np.int64)]
        return parent, np.r_[-1, np.arange(n)]
    t = n + n // 3 + 1                        # random deep tree, some objects left out
    parent = np.r_[-1, [rng.integers(0, i) for i in range(1, t)]].astype(np.int64)
    obj = np.full(t, -1, np.int64)
    carriers = rng.choice(np.arange(1, t), size=n - n // 10, replace=False)
    obj[carriers] = rng.permutation(n)[:len(carriers)]
    return parent, obj


def _check(h, ub, m):
    n_nodes = len(h)
    assert h.parent[0] == -1 and h.depth[0] == 0
    leaves = np.flatnonzero(h.is_leaf)
    assert np.array_equal(np.sort(h.leaf_unit[leaves]), np.arange(len(ub)))   # each unit in one leaf
    assert np.array_equal(h.bounds[leaves], ub[h.leaf_unit[leaves]])
    inner = np.flatnonzero(~h.is_leaf)
    assert (h.child_count[inner] >= 2).all() or n_nodes == 1
    assert (h.child_count[inner] <= m).all()
    assert (h.first_child[leaves] == -1).all() and (h.child_count[leaves] == 0).all()
    kids = h.children(inner)
    par = np.repeat(inner, h.child_count[inner])
    assert np.array_equal(np.sort(kids), np.arange(1, n_nodes))                # a tree over all nodes
    assert np.array_equal(h.parent[kids], par)
    assert np.array_equal(h.depth[kids], h.depth[par] + 1)
    assert (h.bounds[par, MIN] <= h.bounds[kids, MIN]).all()                  # boxes contain children's
    assert (h.bounds[par, MAX] >= h.bounds[kids, MAX]).all()
    assert np.array_equal(np.sort(h.leaves_below([0])), leaves)


def _same(a, b):
    for f in ("bounds", "first_child", "child_count", "leaf_unit", "parent", "depth"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("m", [2, 3, 8])
def test_invariants_and_same_tree_as_recursive_rule(monkeypatch, shape, kind, m):
    rng = np.random.default_rng([SHAPES.index(shape), KINDS.index(kind), m])
    for n in (1, 2, 9, 300):
        ub = _boxes(rng, n, shape)
        parent, obj = _tree(rng, n, kind)
        h = build_from_tree(ub, parent, obj, m)
        _check(h, ub, m)
        monkeypatch.setattr(hierarchy, "_Builder", _Recursive)
        _same(h, build_from_tree(ub, parent, obj, m))
        monkeypatch.undo()


def test_chunked_objects_same_tree_as_recursive_rule(monkeypatch):
    rng = np.random.default_rng(7)
    ub = _boxes(rng, 500, "random")
    cuts = np.sort(rng.choice(np.arange(1, 500), 60, replace=False))
    units = np.split(rng.permutation(500), cuts)                # objects of 1..many units
    parent, obj = _tree(rng, len(units), "flat")
    h = build_hierarchy(ub, units, parent, obj, 4)
    _check(h, ub, 4)
    monkeypatch.setattr(hierarchy, "_Builder", _Recursive)
    _same(h, build_hierarchy(ub, units, parent, obj, 4))


def test_split_segments_matchessah_split():
    rng = np.random.default_rng(3)
    for shape in ("random", "zero", "same", "dup", "rows"):
        lengths = np.array([2, 3, 17, 40, 100])
        box = _boxes(rng, int(lengths.sum()), shape)
        starts = np.cumsum(lengths) - lengths
        order = rng.permutation(len(lengths))                  # segments in any order
        rows, left = hierarchy._split_segments(box, starts[order], lengths[order])
        at = 0
        for i in order:
            assert np.array_equal(rows[at:at + lengths[i]], np.arange(starts[i], starts[i] + lengths[i]))
            assert np.array_equal(left[at:at + lengths[i]], sah_split(box[rows[at:at + lengths[i]]]))
            at += lengths[i]


@pytest.mark.parametrize("seed", range(3))
def test_bin_unions_by_sort_equal_ufunc_at(seed, monkeypatch):
    """The SAH bins' box unions: numpy 1.25+'s fast ``ufunc.at`` and the sort and
    ``reduceat`` used before it give the same unions, and so the same trees (the
    object hierarchy and a planned mesh subdivision)."""
    import core.sah as sah
    import core.subdivision as sd

    rng = np.random.default_rng(seed)
    m, bins = 5000, 300
    key = rng.integers(0, bins - 7, m)                         # some bins stay empty
    lo = rng.uniform(-10, 10, (3, m))
    hi = lo + rng.exponential(1.0, (3, m))
    out = []
    for fast in (True, False):
        monkeypatch.setattr(sah, "FAST_AT", fast)
        bmin, bmax = np.full((3, bins), np.inf), np.full((3, bins), -np.inf)
        sah.bin_unions(key, lo, hi, bmin, bmax)
        sah.bin_unions(key[:100], lo[:, :100] + 1, hi[:, :100] - 1, bmin, bmax)   # a second union, inside the first
        out.append((bmin, bmax))
    assert np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1])
    assert np.isinf(out[0][0][:, bins - 7:]).all()
    boxes = np.stack([lo.T, hi.T], axis=1)
    units = [[i] for i in range(m)]
    trees = []
    for fast in (True, False):
        monkeypatch.setattr(sah, "FAST_AT", fast)
        h = build_hierarchy(boxes, units, np.array([-1, *[0] * m]), np.array([-1, *range(m)]), max_children=4)
        t = sd.build_tree(np.concatenate([boxes] * 4), "pHBVO", leaf_size=64, max_children=4)
        trees.append((h, t))
    (h1, t1), (h2, t2) = trees
    assert np.array_equal(h1.bounds, h2.bounds) and np.array_equal(h1.leaf_unit, h2.leaf_unit)
    assert np.array_equal(t1.order, t2.order) and np.array_equal(t1.bounds, t2.bounds)
