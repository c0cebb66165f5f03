"""Scene subdivision that models only what a scene requires (Meißner, Bartz et al.).

Builders over item boxes -- triangles inside a heavy mesh, or objects above
them -- each returning a :class:`Tree` of flat arrays (breadth-first, root =
node 0, the children of a node contiguous):

- ``order``       ``(k,) int64`` permutation of the items; each node owns a
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
"""

import time
from dataclasses import dataclass

import numpy as np

from .bounds import MAX, MIN, check_boxes, surface_area
from .errors import OccError

BUILDERS = ("pHBVO", "DBVS", "octree", "balanced")
SAH_BINS = 32
SAH_CHECK_ITEMS = 200_000  # up to here pHBVO also builds the balanced tree and keeps the cheaper
SAH_SAMPLE = 32768     # items the SAH cost curve of one split is evaluated on
PULL_UP = 0.5            # an item longer than half its node's longest side stays there
FORCE_SPLIT = 4          # above FORCE_SPLIT * leaf_size items a node is split even if SAH says no
TRAVERSAL_COST = 1.0     # SAH cost of visiting a node, in units of one item


@dataclass(eq=False)
class Tree:
    order: np.ndarray
    bounds: np.ndarray
    first_child: np.ndarray
    child_count: np.ndarray
    item_start: np.ndarray
    item_count: np.ndarray
    parent: np.ndarray
    depth: np.ndarray
    build_seconds: float = 0.0

    def __len__(self):
        return len(self.first_child)


def _box(lo, hi):
    """Box of items from axis-major ``(3, m)`` min and max corner arrays."""
    return np.stack([lo.min(axis=1), hi.max(axis=1)])


def _bin_bounds(bins, lo, hi):
    """Per-bin box of items ``(3, m)`` in ``bins (m,)``: ``(SAH_BINS, 2, 3)``,
    empty bins inverted (+inf, -inf).  Sort-based (ufunc.at is slow)."""
    order = np.argsort(bins.astype(np.uint8), kind="stable")    # radix sort: SAH_BINS <= 256
    count = np.bincount(bins, minlength=SAH_BINS)
    present = np.flatnonzero(count)
    start = (np.cumsum(count) - count)[present]
    out = np.empty((SAH_BINS, 2, 3))
    out[:, MIN], out[:, MAX] = np.inf, -np.inf
    out[present, MIN] = np.minimum.reduceat(lo[:, order], start, axis=1).T
    out[present, MAX] = np.maximum.reduceat(hi[:, order], start, axis=1).T
    return out


def _split_sah(lo, hi, centre, box, leaf_size):
    """Binned SAH over three axes -> part labels ``(m,)`` (nodes above leaf_size are
    always split, so leaves hold at most leaf_size items as with every builder).

    The cost curve is evaluated on at most ``SAH_SAMPLE`` items (a fixed-seed
    sample), then every item is partitioned by the chosen plane: a 4-million
    triangle mesh builds in seconds.
    """
    n = centre.shape[1]
    sample = slice(None)
    if n > SAH_SAMPLE:
        sample = np.sort(np.random.default_rng(n).choice(n, SAH_SAMPLE, replace=False))
    c, slo, shi = centre[:, sample], lo[:, sample], hi[:, sample]
    m = c.shape[1]
    cmin, cmax = c.min(axis=1), c.max(axis=1)
    ext = cmax - cmin
    area = max(surface_area(box[None])[0], 1e-300)
    best, best_cost = None, np.inf
    for axis in np.flatnonzero(ext > 0.0):
        bins = np.minimum(((c[axis] - cmin[axis]) / ext[axis] * SAH_BINS).astype(np.int64), SAH_BINS - 1)
        count = np.bincount(bins, minlength=SAH_BINS)
        bb = _bin_bounds(bins, slo, shi)
        lmin, lmax = np.minimum.accumulate(bb[:, MIN])[:-1], np.maximum.accumulate(bb[:, MAX])[:-1]
        rmin = np.minimum.accumulate(bb[::-1, MIN])[::-1][1:]
        rmax = np.maximum.accumulate(bb[::-1, MAX])[::-1][1:]
        lc = np.cumsum(count)[:-1]
        rc = m - lc
        la = surface_area(np.stack([lmin, lmax], axis=1))
        ra = surface_area(np.stack([rmin, rmax], axis=1))
        cost = np.where((lc > 0) & (rc > 0), TRAVERSAL_COST + (la * lc + ra * rc) / area * (n / m), np.inf)
        s = int(np.argmin(cost))
        if cost[s] < best_cost:
            best_cost, best = cost[s], (axis, cmin[axis] + (s + 1) / SAH_BINS * ext[axis])
    if best is None:
        return _split_median(lo, hi, centre, box, leaf_size)
    axis, plane = best
    right = centre[axis] >= plane
    if right.all() or not right.any():           # the sample missed the rest's spread
        return _split_median(lo, hi, centre, box, leaf_size)
    return right.astype(np.int64)


def _split_median(lo, hi, centre, box, leaf_size):
    """Median of the centres on the longest axis (balanced item counts)."""
    axis = int(np.argmax(centre.max(axis=1) - centre.min(axis=1)))
    n = centre.shape[1]
    labels = np.zeros(n, dtype=np.int64)
    labels[np.argpartition(centre[axis], n // 2)[n // 2:]] = 1
    return labels


def _split_dbvs(lo, hi, centre, box, leaf_size):
    """round(largest / second largest) near-cubes along the largest dimension."""
    ext = box[MAX] - box[MIN]
    if ext.max() <= 0.0:                          # all items at one point
        return _split_median(lo, hi, centre, box, leaf_size)
    order = np.argsort(ext)[::-1]
    axis = int(order[0])
    k = min(16, max(2, int(round(ext[order[0]] / max(ext[order[1]], ext[order[0]] * 1e-3)))))
    t = (centre[axis] - box[MIN, axis]) / max(ext[axis], 1e-300)
    labels = np.minimum((t * k).astype(np.int64), k - 1)
    if labels.min() != labels.max():
        return labels
    return _split_median(lo, hi, centre, box, leaf_size)


def _split_octree(lo, hi, centre, box, leaf_size):
    """Eight octants around the node centre; empty ones dropped."""
    mid = 0.5 * (box[MIN] + box[MAX])
    labels = ((centre > mid[:, None]) * np.array([[1], [2], [4]])).sum(axis=0)
    if labels.min() != labels.max():
        return labels
    n = centre.shape[1]
    return _split_median(lo, hi, centre, box, leaf_size) if n > FORCE_SPLIT * leaf_size else None


SPLITTERS = {"pHBVO": _split_sah, "DBVS": _split_dbvs, "octree": _split_octree,
             "balanced": _split_median}


def build_tree(boxes, builder="pHBVO", leaf_size=64, max_children=2, pull_up=True):
    """A subdivision of items with boxes ``(k, 2, 3)`` (k >= 1); see the module doc."""
    t0 = time.perf_counter()
    b = check_boxes(boxes, "item boxes")
    if not len(b):
        raise OccError("cannot subdivide zero items")
    if not np.all(np.isfinite(b)):
        raise OccError("item boxes contain NaN or infinite values")
    if builder not in SPLITTERS:
        raise OccError(f"unknown builder '{builder}'; choose one of {', '.join(BUILDERS)}")
    if leaf_size < 1 or max_children < 2:
        raise OccError(f"leaf_size must be >= 1 and max_children >= 2, got {leaf_size}, {max_children}")
    split = SPLITTERS[builder]
    # Each stack entry carries its items' data (axis-major copies), so every
    # level reads memory in order instead of gathering from the whole input.
    lo_all, hi_all = np.ascontiguousarray(b[:, MIN].T), np.ascontiguousarray(b[:, MAX].T)
    size_all = (b[:, MAX] - b[:, MIN]).max(axis=1)            # largest side of each item, once
    own, kids, box = [], [], []
    stack = [(np.arange(len(b)), lo_all, hi_all, size_all, -1)]
    while stack:                                   # one iteration per node
        idx, lo, hi, size, parent = stack.pop()
        node = len(own)
        nb = _box(lo, hi)
        own.append(None)
        kids.append([])
        box.append(nb)
        if parent >= 0:
            kids[parent].append(node)
        rest = nb
        if pull_up and len(idx) > leaf_size:
            big = size > PULL_UP * (nb[MAX] - nb[MIN]).max()
            if big.any() and not big.all():
                own[node] = idx[big]
                keep = ~big
                idx, lo, hi, size = idx[keep], np.compress(keep, lo, axis=1), np.compress(keep, hi, axis=1), size[keep]
                rest = _box(lo, hi)
        labels = None
        if len(idx) > leaf_size:
            labels = split(lo, hi, 0.5 * (lo + hi), rest, leaf_size)
        if labels is None:
            own[node] = idx if own[node] is None else np.concatenate([own[node], idx])
            continue
        for part in np.flatnonzero(np.bincount(labels))[::-1]:     # no sort of all labels
            sel = labels == part
            stack.append((idx[sel], np.compress(sel, lo, axis=1), np.compress(sel, hi, axis=1), size[sel],
                          node))
    if max_children > 2:
        _collapse(kids, own, box, max_children)
    tree = _flatten(own, kids, box)
    if builder == "pHBVO" and len(b) <= SAH_CHECK_ITEMS:
        # Greedy top-down SAH is not globally optimal: keep the balanced tree
        # when it is cheaper, so pHBVO never costs more than a median split
        # (checked up to SAH_CHECK_ITEMS items, where the second build is cheap).
        balanced = build_tree(boxes, "balanced", leaf_size, max_children, pull_up)
        if sah_cost(balanced) < sah_cost(tree):
            tree = balanced
    tree.build_seconds = time.perf_counter() - t0
    return tree


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


def _flatten(own, kids, box):
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
    items, pos = [], 0
    for k, old in enumerate(order_nodes):          # once per node
        ch = kids[old]
        if ch:
            first[k] = new[ch[0]]
            count[k] = len(ch)
            for c in ch:
                parent[new[c]] = k
                depth[new[c]] = depth[k] + 1
        mine = own[old] if isinstance(own[old], np.ndarray) else None
        start[k] = pos
        if mine is not None:
            items.append(mine)
            icount[k] = len(mine)
            pos += len(mine)
    return Tree(order=np.concatenate(items).astype(np.int64),
                bounds=np.array([box[o] for o in order_nodes], dtype=np.float64).reshape(-1, 2, 3),
                first_child=first, child_count=count, item_start=start, item_count=icount,
                parent=parent, depth=depth)


def sah_cost(tree):
    """Surface-area cost of a tree: visits of inner nodes plus items tested, each
    weighted by the probability ``S(node) / S(root)`` of reaching the node."""
    area = surface_area(tree.bounds)
    p = area / max(area[0], 1e-300)
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
