"""Scene subdivision that models only what a scene requires (Meißner, Bartz et al.).

Builders over item boxes -- triangles inside a heavy mesh, or objects above
them -- each returning a :class:`Tree` of flat arrays (breadth-first, root =
node 0, the children of a node contiguous):

- ``order``       ``(k,) int64`` permutation of the items (int32 for :class:`ItemBoxes`
                  below 2**31 items); each node owns a
                  contiguous range ``order[item_start : item_start + item_count]``;
- ``bounds``      ``(N, 2, 3) float64``: union of the node's own items and children (tight);
- ``first_child`` / ``child_count`` / ``parent`` / ``depth``: ``(N,) int64``;
- ``item_start`` / ``item_count``: ``(N,) int64``; leaves own >= 1 item, inner
  nodes only the items pulled up to them (usually none).

Builders:

- ``pHBVO``    binary splits minimising ``S(L)/S(H)|L| + S(R)/S(H)|R|`` over binned
               candidate planes on all three axes;
- ``DBVS``     the largest dimension cut into ``round(largest / second largest)``
               near-cubes;
- ``octree``   regular eight-way splits at the node centre, with a load threshold;
- ``balanced`` median split on the longest axis (the opoptimize-like baseline).

Items far larger than their node (longest side above ``PULL_UP`` of the node's)
stay at that node instead of inflating every box below (``pull_up``).  Binary
trees collapse into ``max_children``-ary ones by opening the largest child.

Memory: items are axis-major corner arrays reordered in place (a node is a
range of them, split by stable partitions through one scratch row per item size;
a labelled split sorts by blocks of ``PARTITION_BLOCK`` items, each with its own
uint16 order, so no int64 order of a node's length is made); a heavy mesh hands
in float32 corners as :class:`ItemBoxes` and nothing of the size of its
triangles is copied: at 20 M triangles the build peaks at 1.46 x the corners'
own size (the corners, the int32 item order, the scratch row, a split's labels
and block orders).

Speed: above ``PLAN_ITEMS`` items (and two leaves' worth) pHBVO decides up to
``PLAN_DEPTH`` levels at once (:func:`_plans`): the nodes waiting for a plan are
planned together (a wave, in groups of ``WAVE_SAMPLE`` sample items), every level's
splits of all their parts on spread samples in one call (:func:`_sah_planes`); each
node's items then walk down its plan's levels together (:func:`_classify`) and move
once, by label.  A 20 M
triangle mesh moves its items about twice instead of once a level, and the Python
work a node costs is spent once a plan: the 10 M-vertex grid's chunking took 16.7 s
before, 8.9 s after, one after the other here (``tools/bench/blender_scale.py engine --vertices
10000000``; the same peak, 655 MB above the scene).
"""

import time
from dataclasses import dataclass

import numpy as np

from .bounds import MAX, MIN, check_boxes, surface_area
from .errors import OccError
from .sah import bin_unions, sweep
from .tolerance import tol
from .tree import FlatTree

BUILDERS = ("pHBVO", "DBVS", "octree", "balanced")
SAH_BINS = 32
SAH_CHECK_ITEMS = 200_000  # up to here pHBVO also builds the balanced tree and keeps the cheaper
SAH_SAMPLE = 1024      # items the SAH cost curves of one split are evaluated on (10 M grid: 512,
                       # 1024, 2048 give the same SAH cost, 6.2, 6.5, 7.1 s of CPU for make_units)
PULL_UP = 0.5            # an item longer than half its node's longest side stays there
FORCE_SPLIT = 4          # above FORCE_SPLIT * leaf_size items a node is split even if SAH says no
TRAVERSAL_COST = 1.0     # SAH cost of visiting a node, in units of one item
PLAN_ITEMS = 4 * SAH_SAMPLE  # pHBVO nodes above this many items (and two leaves' worth) decide up to
PLAN_DEPTH = 7           # PLAN_DEPTH levels at once (255 parts at most: a byte a label) from one
PLAN_PART_SAMPLE = 64    # sample, PLAN_PART_SAMPLE items for each part, and move their items once
WAVE_SAMPLE = 1 << 13    # nodes waiting for plans are planned together up to this many sample items


@dataclass(eq=False)
class Tree(FlatTree):
    """A builder's tree: a :class:`~core.tree.FlatTree` over a permutation of the items."""

    order: np.ndarray = None
    item_start: np.ndarray = None
    item_count: np.ndarray = None
    build_seconds: float = 0.0


class ItemBoxes:
    """Item boxes as axis-major corner arrays, ``lo`` and ``hi`` ``(3, k)`` (float32 or
    float64), that a build may reorder in place: afterwards ``lo[:, i]`` is the box
    of item ``tree.order[i]``.  A heavy mesh's triangle boxes come this way (see
    :func:`core.units.triangle_bounds`), so building its tree copies no item data.
    """

    def __init__(self, lo, hi):
        if lo.shape != hi.shape or lo.ndim != 2 or lo.shape[0] != 3:
            raise OccError(f"item corners must be two (3, k) arrays, got {lo.shape} and {hi.shape}")
        self.lo, self.hi = lo, hi

    def __len__(self):
        return self.lo.shape[1]


def _box(lo, hi):
    """Box ``(2, 3) float64`` of items from axis-major ``(3, m)`` min and max corner arrays."""
    return np.stack([lo.min(axis=1), hi.max(axis=1)]).astype(np.float64)


def _centre(lo, hi, axis):
    """Centres of items on one axis, ``(m,)`` in the corners' dtype."""
    c = lo[axis] + hi[axis]
    c *= 0.5
    return c


def _sample(lo, hi, size):
    """Every ``m / size``-th item's corners as float64 ``(3, <= size)``: a spread
    sample at no gather cost."""
    step = -(-lo.shape[1] // size)
    return lo[:, ::step].astype(np.float64), hi[:, ::step].astype(np.float64)


def _split_sah(lo, hi, box, leaf_size):
    """Binned SAH over three axes -> part labels ``(m,) bool`` (nodes above leaf_size
    are always split, so leaves hold at most leaf_size items as with every builder).

    The cost curves of the three axes are evaluated at once on at most
    ``SAH_SAMPLE`` items of the node's (:func:`_sample`), then every item is
    partitioned by the chosen plane.
    """
    slo, shi = _sample(lo, hi, SAH_SAMPLE)
    found, axis, twice = _sah_planes(slo, shi, slo + shi, np.zeros(1, dtype=np.int64), np.array([slo.shape[1]]))
    if not found[0]:
        return _split_median(lo, hi, box, leaf_size)
    right = lo[axis[0]] + hi[axis[0]] >= twice[0]
    if right.all() or not right.any():           # the sample missed the rest's spread
        return _split_median(lo, hi, box, leaf_size)
    return right


@dataclass(eq=False)
class _Plan:
    """pHBVO splits of several levels decided on spread samples (:func:`_plans`).

    Plan nodes breadth first, node 0 the root, ``(P,)`` arrays: ``axis`` and ``twice``
    (twice the plane's position: items whose ``lo + hi`` on that axis reach it go
    right), ``child`` ``(P, 2)`` (a part left whole: itself twice, ``twice`` +inf),
    ``limit`` the longest side above which an item stays at the node (pulled up; +inf:
    none); ``label`` the part of the items that stop at a node (an inner node's own
    items), ``first``/``parts`` the node's parts.  Parts are numbered depth first, an
    inner node's own part before its left and right parts', so every node's items
    are one range once partitioned by label."""

    axis: np.ndarray
    twice: np.ndarray
    child: np.ndarray
    limit: np.ndarray
    label: np.ndarray
    first: np.ndarray
    parts: np.ndarray
    depth: int

    def split(self, root):
        """Whether plan root ``root`` is split (else its items are left whole)."""
        return bool(self.child[root, 0] != root)


def _plan_sample(n, leaf_size):
    """Sample items of a plan of ``n`` items: ``PLAN_PART_SAMPLE`` for each part it may make."""
    return min(n, PLAN_PART_SAMPLE << max(1, min(PLAN_DEPTH, int(np.ceil(np.log2(n / leaf_size))))))


def _plans(ranges, leaf_size, pull_up):
    """The plans of several nodes' items (``ranges``: corners ``(3, n)`` each) down to
    parts of about ``leaf_size`` items, ``PLAN_DEPTH`` levels at most, made together:
    every level's splits of all of them decided at once on spread samples
    (:func:`_sah_planes`).  Plan node ``i`` is the root of ``ranges[i]`` (left whole
    where its sample could not be split).  Sample items longer than a node's pull-up
    limit stay there, as the items will."""
    samples, per = [], []
    for lo, hi in ranges:
        samples.append(_sample(lo, hi, _plan_sample(lo.shape[1], leaf_size)))
        per.append(lo.shape[1] / samples[-1][0].shape[1])    # items a sample item stands for
    slo = np.concatenate([a for a, _ in samples], axis=1)
    shi = np.concatenate([b for _, b in samples], axis=1)
    c, size = slo + shi, (shi - slo).max(axis=0)
    roots = len(ranges)
    axis, twice, limit = [0] * roots, [np.inf] * roots, [np.inf] * roots
    child = [[i, i] for i in range(roots)]
    node = np.arange(roots)                      # the plan node of each segment of the samples
    per = np.array(per)                          # and the items a sample item of it stands for
    length = np.array([a.shape[1] for a, _ in samples])
    rows = np.arange(slo.shape[1])               # the segments' sample items, segment by segment
    levels = 0
    for _ in range(PLAN_DEPTH):
        sid = np.repeat(np.arange(len(node)), length)
        if pull_up:                              # the sample's big items stay where the items' will
            keep = size[rows] <= np.asarray(limit)[node][sid]
            rows, sid = rows[keep], sid[keep]
            length = np.bincount(sid, minlength=len(node))
        ok = (length >= 2 * SAH_BINS) & (length * per > leaf_size)
        if not ok.any():
            break
        rows, sid = rows[ok[sid]], (np.cumsum(ok) - 1)[sid[ok[sid]]]
        node, length, per = node[ok], length[ok], per[ok]
        # each segment's plane from SAH_SAMPLE of its sample items at most, every k-th
        step = -(-length // SAH_SAMPLE)
        count = -(-length // step)
        first = np.cumsum(count) - count
        pick = rows[np.repeat(np.cumsum(length) - length, count)
                    + (np.arange(int(count.sum())) - np.repeat(first, count)) * np.repeat(step, count)]
        found, ax, pos = _sah_planes(slo[:, pick], shi[:, pick], c[:, pick], first, count)
        if not found.any():
            break
        levels += 1
        right = c[ax[sid], rows] >= pos[sid]
        go = found[sid]
        rows, sid, right = rows[go], sid[go], right[go]
        order = np.argsort(2 * sid + right, kind="stable")
        rows, key = rows[order], (2 * sid + right)[order]
        split = np.flatnonzero(found)
        kids = len(axis) + 2 * np.arange(len(split))
        for i, p in enumerate(node[split].tolist()):
            axis[p], twice[p], child[p] = int(ax[split[i]]), float(pos[split[i]]), [int(kids[i]), int(kids[i]) + 1]
        for _ in range(2 * len(split)):
            axis.append(0)
            twice.append(np.inf)
            child.append([len(child), len(child)])
            limit.append(np.inf)
        # the new segments: each split's left, then right part (their keys, in order)
        node, per = np.stack([kids, kids + 1], axis=1).ravel(), np.repeat(per[split], 2)
        length = np.bincount(np.searchsorted((2 * split[:, None] + [0, 1]).ravel(), key), minlength=len(node))
        if pull_up:                              # a part's limit: half the longest side of its sample's box
            full = np.flatnonzero(length)
            at = (np.cumsum(length) - length)[full]
            side = (np.maximum.reduceat(shi[:, rows], at, axis=1)
                    - np.minimum.reduceat(slo[:, rows], at, axis=1)).max(axis=0)
            for p, v in zip(node[full].tolist(), (PULL_UP * side).tolist(), strict=True):
                limit[p] = v
    P = len(axis)
    label, first, parts = np.zeros(P, np.uint8), np.zeros(P, np.int64), np.zeros(P, np.int64)

    def number(p, at):                           # depth first from each root: a byte a label
        first[p] = label[p] = at
        if child[p][0] == p:
            parts[p] = 1
            return at + 1
        at = number(child[p][1], number(child[p][0], at + 1))
        parts[p] = at - first[p]
        return at

    for i in range(roots):
        number(i, 0)
    return _Plan(np.array(axis), np.array(twice), np.array(child, dtype=np.int64), np.array(limit),
                 label, first, parts, max(levels, 1))


def _sah_planes(slo, shi, c, start, length):
    """The cheapest binned SAH plane of every segment of a sample at once (the items
    of segment i are columns ``start[i]:start[i] + length[i]``, in order, >= 2 each):
    ``(found, axis, twice the position)``, each ``(p,)``; ties go to the lowest axis,
    then the lowest plane.  ``c``: ``slo + shi``.  A single node's split
    (:func:`_split_sah`) is one segment."""
    p, b_ = len(start), SAH_BINS
    sid = np.repeat(np.arange(p), length)
    cmin, cmax = np.minimum.reduceat(c, start, axis=1), np.maximum.reduceat(c, start, axis=1)
    ext = cmax - cmin
    scale = np.where(ext > 0.0, b_ / np.where(ext > 0.0, ext, 1.0), 0.0)
    best = np.full(p, np.inf)
    axis, split = np.zeros(p, dtype=np.int64), np.zeros(p, dtype=np.int64)
    for a in range(3):
        bins = np.minimum(((c[a] - cmin[a][sid]) * scale[a][sid]).astype(np.int64), b_ - 1)
        key = sid * b_ + bins
        count = np.bincount(key, minlength=p * b_).reshape(p, b_)
        bmin = np.full((3, p * b_), np.inf)
        bmax = np.full((3, p * b_), -np.inf)
        bin_unions(key, slo, shi, bmin, bmax)
        bmin, bmax = bmin.reshape(3, p, b_).transpose(2, 1, 0), bmax.reshape(3, p, b_).transpose(2, 1, 0)
        la, lc, ra, rc = sweep(bmin, bmax, count.T)                 # (b_ - 1, p) each
        cost = np.where((lc > 0) & (rc > 0) & (ext[a] > 0.0), la * lc + ra * rc, np.inf)
        s = np.argmin(cost, axis=0)
        low = cost[s, np.arange(p)]
        better = low < best
        best[better], axis[better], split[better] = low[better], a, s[better]
    found = np.isfinite(best)
    at = np.arange(p)
    return found, axis, cmin[axis, at] + (split + 1) / b_ * ext[axis, at]


def _classify(lo, hi, plan, root=0):
    """Part of each item (corners ``(3, m)``) in the plan below ``root``: ``(m,) uint8``,
    the plan's levels walked for all items at once, ``CLASSIFY_BLOCK`` items at a time."""
    labels = np.empty(lo.shape[1], dtype=np.uint8)
    # tables by twice the node (the step to a child adds the side): no multiply a level
    twice = np.repeat(plan.twice.astype(lo.dtype), 2)
    step = 2 * plan.child.ravel()
    limit = np.repeat(plan.limit, 2)
    label = np.repeat(plan.label, 2)
    least = plan.limit.min()
    for b in range(0, len(labels), CLASSIFY_BLOCK):
        lb, hb = lo[:, b:b + CLASSIFY_BLOCK], hi[:, b:b + CLASSIFY_BLOCK]
        m = lb.shape[1]
        c = (lb + hb).ravel()                                      # twice the centres, axis-major
        offset = np.repeat(plan.axis * m, 2)
        at = np.arange(m)
        size = None
        if np.isfinite(least):
            size = hb[0] - lb[0]
            for a in (1, 2):
                np.maximum(size, hb[a] - lb[a], out=size)
            if size.max() <= least:                                # none of them is pulled up anywhere
                size = None
        d = np.full(m, 2 * root, dtype=np.intp)
        for _ in range(plan.depth):
            nxt = step[d + (c[offset[d] + at] >= twice[d])]
            d = nxt if size is None else np.where(size > limit[d], d, nxt)
        labels[b:b + m] = label[d]
    return labels


def _split_median(lo, hi, box, leaf_size):
    """Median of the centres on the longest axis (balanced item counts)."""
    ext = [np.ptp(_centre(lo, hi, a)) for a in range(3)]      # one axis at a time: no (3, m) temporary
    c = _centre(lo, hi, int(np.argmax(ext)))
    n = len(c)
    labels = np.zeros(n, dtype=bool)
    labels[np.argpartition(c, n // 2)[n // 2:]] = True
    return labels


def _split_dbvs(lo, hi, box, leaf_size):
    """round(largest / second largest) near-cubes along the largest dimension."""
    ext = box[MAX] - box[MIN]
    if ext.max() <= 0.0:                          # all items at one point
        return _split_median(lo, hi, box, leaf_size)
    order = np.argsort(ext)[::-1]
    axis = int(order[0])
    k = min(16, max(2, int(round(ext[order[0]] / max(ext[order[1]], ext[order[0]] * 1e-3)))))
    t = (_centre(lo, hi, axis) - box[MIN, axis]) / max(ext[axis], tol.tiny)
    labels = np.minimum((t * k).astype(np.int64), k - 1).astype(np.uint8)
    if labels.min() != labels.max():
        return labels
    return _split_median(lo, hi, box, leaf_size)


def _split_octree(lo, hi, box, leaf_size):
    """Eight octants around the node centre; empty ones dropped."""
    mid = 0.5 * (box[MIN] + box[MAX])
    labels = np.zeros(lo.shape[1], dtype=np.uint8)
    for a in range(3):
        labels |= (_centre(lo, hi, a) > mid[a]).astype(np.uint8) << a
    if labels.min() != labels.max():
        return labels
    n = lo.shape[1]
    return _split_median(lo, hi, box, leaf_size) if n > FORCE_SPLIT * leaf_size else None


SPLITTERS = {"pHBVO": _split_sah, "DBVS": _split_dbvs, "octree": _split_octree,
             "balanced": _split_median}


def build_tree(boxes, builder="pHBVO", leaf_size=64, max_children=2, pull_up=True):
    """A subdivision of items (k >= 1); see the module doc.

    boxes: ``(k, 2, 3)`` item boxes, or :class:`ItemBoxes` whose corner arrays
    the build reorders in place into the tree's item order (no copy of them); the
    tree's ``order`` is then int32 where ``k < 2**31`` (no int64 copy of it).
    """
    t0 = time.perf_counter()
    if isinstance(boxes, ItemBoxes):
        items = boxes
    else:
        b = check_boxes(boxes, "item boxes")
        items = ItemBoxes(np.ascontiguousarray(b[:, MIN].T), np.ascontiguousarray(b[:, MAX].T))
    k = len(items)
    if not k:
        raise OccError("cannot subdivide zero items")
    if not (np.isfinite(items.lo).all() and np.isfinite(items.hi).all()):
        raise OccError("item boxes contain NaN or infinite values")
    if builder not in SPLITTERS:
        raise OccError(f"unknown builder '{builder}'; choose one of {', '.join(BUILDERS)}")
    if leaf_size < 1 or max_children < 2:
        raise OccError(f"leaf_size must be >= 1 and max_children >= 2, got {leaf_size}, {max_children}")
    original = None
    if builder == "pHBVO" and k <= SAH_CHECK_ITEMS:
        original = (items.lo.copy(), items.hi.copy())       # small: the balanced build below needs them
    tree = _build(items, SPLITTERS[builder], leaf_size, max_children, pull_up)
    if original is not None:
        # Greedy top-down SAH is not globally optimal: keep the balanced tree
        # when it is cheaper, so pHBVO never costs more than a median split
        # (checked up to SAH_CHECK_ITEMS items, where the second build is cheap).
        other = ItemBoxes(*original)
        balanced = _build(other, _split_median, leaf_size, max_children, pull_up)
        if sah_cost(balanced) < sah_cost(tree):
            tree = balanced
            items.lo[...], items.hi[...] = other.lo, other.hi
    if not isinstance(boxes, ItemBoxes):
        tree.order = tree.order.astype(np.int64)
    tree.build_seconds = time.perf_counter() - t0
    return tree


PARTITION_BLOCK = 1 << 16  # items per block of a labelled partition: a block's own order fits uint16
CLASSIFY_BLOCK = 1 << 14   # items walked down a plan together (their temporaries stay in cache)
COMPRESS_ITEMS = 1 << 16   # up to here a two-way partition compresses (faster on few items than by blocks)


class _Partitioner:
    """Stable in-place partitions of ranges of the item arrays (corners and order),
    through one scratch row per item size (float32 corners and int32 indices share
    it): a node's items move, nothing is copied whole."""

    def __init__(self, rows):
        self.rows = rows
        self.scratch = {}
        for r in rows:
            size = r.dtype.itemsize
            if size not in self.scratch:
                self.scratch[size] = np.empty(len(r) * size, dtype=np.uint8)

    def _tmp(self, row, n):
        """The first ``n`` entries of the scratch row for ``row``'s dtype (a view)."""
        return self.scratch[row.dtype.itemsize][:n * row.dtype.itemsize].view(row.dtype)

    def __call__(self, s, e, labels, parts=None):
        """Order ``[s, e)`` by ``labels`` (stable); returns the part counts.

        labels: ``(e - s,)`` bool or uint8, or a function ``(a, b) -> (b - a,) uint8``
        of the labels of items ``s + a`` to ``s + b``, called block by block (the
        labels of the whole range are never held), with ``parts`` their count.
        """
        if not callable(labels) and labels.dtype == bool and e - s <= COMPRESS_ITEMS:
            right = labels
            nl = len(right) - int(np.count_nonzero(right))
            left = ~right
            for r in self.rows:
                seg, tmp = r[s:e], self._tmp(r, e - s)
                np.compress(left, seg, out=tmp[:nl])
                np.compress(right, seg, out=tmp[nl:])
                seg[...] = tmp
            return np.array([nl, e - s - nl])
        if callable(labels):
            label_of, k = labels, parts
        else:
            flat = labels.view(np.uint8)
            k = int(flat.max()) + 1 if e > s else 1

            def label_of(a, b):
                return flat[a:b]
        # A counting sort by blocks: each block sorted on its own (a uint16 order, a
        # quarter of an int64 argsort's), then each block's run of each label
        # copied to that label's next free places.
        local, counts = _block_orders(label_of, e - s, k)
        total = counts.sum(axis=0)
        to = np.cumsum(counts, axis=0) - counts + (np.cumsum(total) - total)
        at = np.cumsum(counts, axis=1) - counts
        # each block's runs, (to, from, end) of its labels that occur (once for every row)
        moves = [list(zip(to[i][c > 0].tolist(), at[i][c > 0].tolist(), (at[i] + c)[c > 0].tolist(), strict=True))
                 for i, c in enumerate(counts)]
        for r in self.rows:
            seg, tmp = r[s:e], self._tmp(r, e - s)
            for i, b in enumerate(range(0, e - s, PARTITION_BLOCK)):
                block = seg[b:b + PARTITION_BLOCK][local[b:b + PARTITION_BLOCK]]
                for d, a, z in moves[i]:
                    tmp[d:d + z - a] = block[a:z]
            seg[...] = tmp
        return total if callable(labels) or labels.dtype != bool else np.pad(total, (0, 2 - len(total)))


def _block_orders(label_of, m, k):
    """Per block of ``PARTITION_BLOCK`` of ``m`` items whose uint8 labels (< k) are
    ``label_of(a, b)``: the block's stable sort as offsets in it, ``(m,) uint16``,
    and its count of each label, ``(blocks, k)``."""
    local = np.empty(m, dtype=np.uint16)
    counts = np.empty((-(-m // PARTITION_BLOCK), k), dtype=np.int64)
    for i, b in enumerate(range(0, m, PARTITION_BLOCK)):
        lb = label_of(b, min(b + PARTITION_BLOCK, m))
        local[b:b + PARTITION_BLOCK] = np.argsort(lb, kind="stable")      # radix sort of a block
        counts[i] = np.bincount(lb, minlength=k)
    return local, counts


def _longer_than(lo, hi, limit):
    """Whether each item's longest side exceeds ``limit``: ``(m,) bool``, found in
    blocks of ``PARTITION_BLOCK`` items (temporaries of a few MB)."""
    out = np.empty(lo.shape[1], dtype=bool)
    for b in range(0, len(out), PARTITION_BLOCK):
        lb, hb = lo[:, b:b + PARTITION_BLOCK], hi[:, b:b + PARTITION_BLOCK]
        size = hb[0] - lb[0]
        for a in (1, 2):
            np.maximum(size, hb[a] - lb[a], out=size)
        np.greater(size, limit, out=out[b:b + PARTITION_BLOCK])
    return out


def _build(items, split, leaf_size, max_children, pull_up):
    """Top-down build over ``items`` (:class:`ItemBoxes`, reordered in place): every
    node is a contiguous range of the item order, its pulled-up items first."""
    lo, hi = items.lo, items.hi
    k = lo.shape[1]
    perm = np.arange(k, dtype=np.int32 if k < 2**31 else np.int64)    # 4 bytes a move where they suffice
    partition = _Partitioner([*lo, *hi, perm])
    own, kids, box, wave = [], [], [], []
    stack = [(0, k, -1, None)]
    while stack or wave:                           # one iteration per node, or per wave of plans
        if not stack:
            stack += _wave(wave, lo, hi, partition, split, leaf_size, pull_up, own, kids, box)
            wave = []
            continue
        s, e, parent, nb = stack.pop()
        node = len(own)
        nb = _box(lo[:, s:e], hi[:, s:e]) if nb is None else nb
        own.append(None)
        kids.append([])
        box.append(nb)
        if parent >= 0:
            kids[parent].append(node)
        rest, r = nb, s
        if pull_up and e - s > leaf_size:
            big = _longer_than(lo[:, s:e], hi[:, s:e], PULL_UP * (nb[MAX] - nb[MIN]).max())
            nbig = int(np.count_nonzero(big))
            if 0 < nbig < e - s:
                partition(s, e, ~big)              # the big items first: the node owns them
                own[node] = (s, nbig)
                r = s + nbig
                rest = _box(lo[:, r:e], hi[:, r:e])
            del big                                # a byte an item: gone before the split's temporaries
        if split is _split_sah and e - r > max(PLAN_ITEMS, 2 * leaf_size):
            wave.append((node, r, e, rest))        # planned with the others of its wave
            continue
        labels = None
        if e - r > leaf_size:
            labels = split(lo[:, r:e], hi[:, r:e], rest, leaf_size)
        if labels is None:
            own[node] = (s, e - s)
        else:
            stack += _split_into(partition, r, e, labels, node)
    if max_children > 2:
        _collapse(kids, own, box, max_children)
    del partition                                  # its scratch rows go before the tree is flattened
    return _flatten(own, kids, box, perm)


def _split_into(partition, r, e, labels, node):
    """Partition ``[r, e)`` by a split's labels: its parts, as ranges to build below ``node``."""
    counts = partition(r, e, labels)
    starts = r + np.cumsum(counts) - counts
    return [(int(starts[p]), int(starts[p] + counts[p]), node, None) for p in np.flatnonzero(counts)[::-1]]


def _wave(wave, lo, hi, partition, split, leaf_size, pull_up, own, kids, box):
    """Plan the nodes of a wave, ``(node, r, e, box)`` whose items ``[r, e)`` are to be
    split, all together (:func:`_plans`), and move each one's items once; returns the
    ranges left to build (a node whose plan was not followed is split as any other)."""
    todo = []
    for group in _groups(wave, leaf_size):
        plan = _plans([(lo[:, r:e], hi[:, r:e]) for _, r, e, _ in group], leaf_size, pull_up)
        todo += _follow(plan, group, lo, hi, partition, split, leaf_size, own, kids, box)
    return todo


def _groups(wave, leaf_size):
    """The wave in groups whose samples together stay under ``WAVE_SAMPLE`` items."""
    group, rows = [], 0
    for w in wave:
        m = _plan_sample(w[2] - w[1], leaf_size)
        if group and rows + m > WAVE_SAMPLE:
            yield group
            group, rows = [], 0
        group.append(w)
        rows += m
    if group:
        yield group


def _follow(plan, group, lo, hi, partition, split, leaf_size, own, kids, box):
    """Move each group node's items once by its plan and make the plan's nodes; returns
    the ranges left to build."""
    todo = []
    for i, (node, r, e, rest) in enumerate(group):
        if plan.split(i):
            n = int(plan.parts[i])
            counts = partition(r, e, lambda a, b, lo=lo[:, r:e], hi=hi[:, r:e], i=i:
                               _classify(lo[:, a:b], hi[:, a:b], plan, i), n)
            done = _planned(plan, i, np.pad(counts, (0, n - len(counts))), r, lo, hi, node, own, kids, box)
            if done is not None:
                todo += done
                continue
        todo += _split_into(partition, r, e, split(lo[:, r:e], hi[:, r:e], rest, leaf_size), node)
    return todo


def _planned(plan, root, counts, r, lo, hi, node, own, kids, box):
    """The nodes of the plan below ``root`` whose items lie at ``r`` on, partitioned by
    part (``counts``), below tree node ``node``: plan nodes that own items or have two
    parts with items become tree nodes, their boxes from their parts'; returns the
    ranges left to build, ``(s, e, parent, box)`` on the stack, or None where the root's
    items all fell on one side (the node is then split as any other)."""
    bounds = r + np.concatenate([[0], np.cumsum(counts)])
    full = np.flatnonzero(counts)
    part_lo, part_hi = np.full((len(counts), 3), np.inf), np.full((len(counts), 3), -np.inf)
    at = bounds[full] - r
    part_lo[full] = np.minimum.reduceat(lo[:, r:bounds[-1]], at, axis=1).T
    part_hi[full] = np.maximum.reduceat(hi[:, r:bounds[-1]], at, axis=1).T

    sub, i = [root], 0                            # the plan's nodes below the root
    while i < len(sub):
        if plan.split(sub[i]):
            sub += plan.child[sub[i]].tolist()
        i += 1
    # every one's box at once: the union of its parts (one reduceat over [first, end) pairs,
    # a row of +inf / -inf after the parts so that an end may be the last part's)
    pairs = np.stack([plan.first[sub], plan.first[sub] + plan.parts[sub]], axis=1).ravel()
    node_box = np.stack([np.minimum.reduceat(np.vstack([part_lo, np.full(3, np.inf)]), pairs)[::2],
                         np.maximum.reduceat(np.vstack([part_hi, np.full(3, -np.inf)]), pairs)[::2]], axis=1)
    row = {p: j for j, p in enumerate(sub)}

    def extent(p):
        return int(bounds[plan.first[p]]), int(bounds[plan.first[p] + plan.parts[p]])

    def box_of(p):
        return node_box[row[p]]

    left, right = plan.child[root]
    if extent(left)[0] == extent(left)[1] or extent(right)[0] == extent(right)[1]:
        return None
    todo = []

    def emit(p, parent):
        s, e = extent(p)
        if s == e:
            return
        if plan.child[p, 0] == p:                  # a part: built as any node
            todo.append((s, e, parent, box_of(p)))
            return
        mine = int(counts[plan.label[p]])
        sides = [c for c in plan.child[p] if extent(c)[0] < extent(c)[1]]
        if not mine and len(sides) == 1:           # a split the items did not follow
            emit(sides[0], parent)
            return
        if len(sides) < 2:                         # its items all pulled up, or one side: split anew
            todo.append((s, e, parent, box_of(p)))
            return
        n = len(own)
        own.append((s, mine) if mine else None)
        kids.append([])
        box.append(box_of(p))
        kids[parent].append(n)
        for c in plan.child[p]:
            emit(c, n)

    for c in plan.child[root]:
        emit(c, node)
    return todo[::-1]                              # the stack pops the leftmost first


def _collapse(kids, own, box, max_children):
    """Open the largest inner child (that owns no items) while the node stays <= max_children."""
    area = surface_area(np.array(box))
    for node in range(len(kids)):
        while True:
            ch = kids[node]
            openable = [c for c in ch if kids[c] and own[c] is None
                        and len(ch) - 1 + len(kids[c]) <= max_children]
            if not openable:
                break
            c = max(openable, key=lambda x: area[x])
            i = ch.index(c)
            kids[node] = ch[:i] + kids[c] + ch[i + 1:]
            kids[c] = []
            own[c] = "dropped"


def _flatten(own, kids, box, order):
    order_nodes = [0]
    i = 0
    while i < len(order_nodes):
        order_nodes.extend(kids[order_nodes[i]])
        i += 1
    new = {old: k for k, old in enumerate(order_nodes)}
    n = len(order_nodes)
    first = np.full(n, -1, dtype=np.int64)
    count = np.zeros(n, dtype=np.int64)
    parent = np.full(n, -1, dtype=np.int64)
    depth = np.zeros(n, dtype=np.int64)
    start = np.zeros(n, dtype=np.int64)
    icount = np.zeros(n, dtype=np.int64)
    for k, old in enumerate(order_nodes):          # once per node
        ch = kids[old]
        if ch:
            first[k] = new[ch[0]]
            count[k] = len(ch)
            for c in ch:
                parent[new[c]] = k
                depth[new[c]] = depth[k] + 1
        if isinstance(own[old], tuple):
            start[k], icount[k] = own[old]
    return Tree(order=order, bounds=np.array([box[o] for o in order_nodes], dtype=np.float64).reshape(-1, 2, 3),
                first_child=first, child_count=count, item_start=start, item_count=icount,
                parent=parent, depth=depth)


def sah_cost(tree):
    """Surface-area cost of a tree: visits of inner nodes plus items tested, each
    weighted by the probability ``S(node) / S(root)`` of reaching the node."""
    area = surface_area(tree.bounds)
    p = area / max(area[0], tol.tiny)
    inner = tree.child_count > 0
    return float((p[inner] * TRAVERSAL_COST).sum() + (p * tree.item_count).sum())


def choose_leaf_size(n_items, cost_query_us, cost_node_us, cost_ktri_us, lo=256, per_query=1.0):
    """Chunk size (triangles) at which drawing a chunk costs about what testing it
    costs: ``L = 1000 * per_query * (c_q + c_n) / c_t``, clamped to [lo, N].

    Coarser chunks are drawn whole when any part shows (on the sample city, 4k
    triangle chunks ran 7x faster than 588k ones); finer chunks cost more
    queries than their triangles would take to draw.
    """
    n = max(int(n_items), 1)
    size = 1000.0 * per_query * (cost_query_us + cost_node_us) / max(float(cost_ktri_us), 1e-6)
    return int(min(max(size, lo), n))


def worth_chunking(n_triangles, cost_query_us, cost_ktri_us, min_triangles=20000, queries=8):
    """Cut a mesh only when drawing it whole costs more than ``queries`` queries
    and it has at least ``min_triangles``: no chunking of small meshes."""
    return n_triangles >= min_triangles and n_triangles / 1000.0 * cost_ktri_us > queries * cost_query_us
