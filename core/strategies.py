"""Traversal strategies.  Each takes a :class:`core.traversal.Frame`, draws what it
finds visible into the frame's depth buffer, marks what it proves occluded, and
leaves its counters in ``frame.stats``.

Correctness is the same for all of them and does not depend on the occupancy
map: an object is culled only when it is outside the frustum or when an
occlusion query of a box around it (or around a group containing it) passed no
more than ``threshold`` samples against real geometry already drawn.  Drawing
less before a query can only make it say "visible" more often.

- ``vfc``      hierarchical frustum culling, draws everything inside.
- ``stopwait`` front to back, one query per node, waiting for each answer.
- ``om``       Staneker et al. 2003: leaves front to back; the occupancy map skips
               queries in still-empty screen regions; the rest go into at most
               ``OM_MAX_BATCHES`` occupancy-map-arranged multiple queries.
- ``om_multi`` Staneker et al. 2004: hierarchical.  Stage 1 draws or opens what the
               occupancy map proves visible and defers the rest; stage 2 fills test
               lists through one cleared occupancy map (no two boxes of a list
               overlap on screen) and issues each as one multiple query, at most
               ``max_tests`` rounds, ``max_tests(f + 1) = 0.7 m(f)``; stage 3 queries
               all that remain.
- ``om_coherent`` om_multi that draws last frame's visible leaves first, without
               queries, re-checking each every few frames (temporal coherence).
- ``oracle``   draws exactly the ground-truth set, no queries: the physical limit.
"""

import heapq
import math

import numpy as np

from .errors import OccError
from .occupancy import X0, X1, Y0, Y1, non_overlapping_first
from .traversal import Visibility

OM_MAX_BATCHES = 5
MAX_TEST_CANDIDATES = 512      # bounds the pairwise overlap matrix of one test list


def vfc(frame, **_):
    leaves = np.flatnonzero(frame.in_frustum & frame.h.is_leaf)
    frame.draw_leaves(leaves)


def oracle(frame, truth=None, **_):
    if truth is None:
        raise OccError("the oracle strategy needs the ground-truth visible set")
    h = frame.h
    leaves = np.flatnonzero(frame.in_frustum & h.is_leaf)
    # a chunk of a truly visible object is drawn: the truth is per object
    seen = truth[frame.unit_object[h.leaf_unit[leaves]]]
    frame.draw_leaves(frame.sort_near(leaves[seen]))
    frame.state[h.leaf_unit[leaves[~seen]]] = Visibility.OCCLUDED


def stopwait(frame, **_):
    """One query per node, answer awaited before the next (the baseline to beat)."""
    h = frame.h
    if not frame.in_frustum[0]:
        return
    heap = [(frame.dist[0], 0)]
    while heap:                        # per node by design: this is the slow baseline
        _, node = heapq.heappop(heap)
        one = np.array([node])
        if not frame.crosses[node]:
            if not frame.query(one)[0]:
                frame.occlude(one)
                continue
        else:
            frame.stats["near_visible"] += 1
        if h.is_leaf[node]:
            frame.draw_leaves(one)
        else:
            for c in frame.children_in_frustum(one):
                heapq.heappush(heap, (frame.dist[c], int(c)))


def _stage1(frame, front, chunk):
    """Occupancy-driven descent: front to back in chunks of ``chunk`` nodes; a node
    whose rectangle still has an empty tile (or that crosses the near plane) is
    drawn (leaf) or opened (inner) without a query, the others are returned
    (pending), nearest first."""
    pending = []
    while len(front):
        # The map only ever fills, so a node with no empty tile now never gets one:
        # defer all such nodes at once, chunk only those still in doubt.
        hopeless = (~frame.crosses[front] & ~frame.free[front]
                    & ~frame.om.any_empty_tiles(frame.tiles[front]))
        pending.append(front[hopeless])
        front = frame.sort_near(front[~hopeless])
        head, front = front[:chunk], front[chunk:]
        crosses, free = frame.crosses[head], frame.free[head]
        empty = frame.om.any_empty_tiles(frame.tiles[head])
        leaf = frame.h.is_leaf[head]
        tiles = frame.tiles[head]
        # Within a chunk, a node whose tiles all lie under one nearer leaf that is
        # drawn in this chunk would find them occupied: defer it too.
        proven = crosses | free | (empty & ~_nearer(tiles, empty & leaf, inside=True))
        # A node over (on screen) and behind a nearer inner node opened in this chunk
        # was judged on a map that lacks that node's contents: a query decides.
        proven &= crosses | free | ~_nearer(tiles, proven & ~leaf, inside=False)
        frame.stats["near_visible"] += int(crosses.sum())
        frame.stats["queries_skipped"] += int((proven & ~crosses & ~free).sum())
        frame.draw_leaves(head[proven & leaf & ~frame.predrawn[head]])
        front = np.concatenate([front, frame.children_in_frustum(head[proven & ~leaf])])
        pending.append(head[~proven])
    return np.concatenate(pending) if pending else np.zeros(0, dtype=np.int64)


def _nearer(tiles, marked, inside):
    """``(k,) bool``: rectangle i lies inside (``inside``) or overlaps rectangle j for
    some earlier j with ``marked[j]``."""
    t = tiles
    if inside:
        rel = ((t[None, :, X0] <= t[:, None, X0]) & (t[:, None, X1] <= t[None, :, X1])
               & (t[None, :, Y0] <= t[:, None, Y0]) & (t[:, None, Y1] <= t[None, :, Y1]))
    else:
        rel = ((t[None, :, X0] <= t[:, None, X1]) & (t[:, None, X0] <= t[None, :, X1])
               & (t[None, :, Y0] <= t[:, None, Y1]) & (t[:, None, Y0] <= t[None, :, Y1]))
    rel &= np.tri(len(t), len(t), -1, dtype=bool) & marked[None, :]
    return rel.any(axis=1)


def _test_list(frame, pending):
    """Split sorted ``pending`` into (test list, rest): greedy, no two overlapping."""
    cand = pending[:MAX_TEST_CANDIDATES]
    taken = _non_overlapping(frame, cand)
    return cand[taken], np.concatenate([cand[~taken], pending[MAX_TEST_CANDIDATES:]])


def _non_overlapping(frame, nodes):
    return non_overlapping_first(frame.tiles[nodes])


def _resolve(frame, nodes, visible):
    """Act on query answers: occlude the hidden, draw visible leaves, open visible
    inner nodes; returns the opened children."""
    frame.occlude(nodes[~visible])
    vis = nodes[visible]
    leaf = frame.h.is_leaf[vis]
    frame.draw_leaves(vis[leaf])
    return frame.children_in_frustum(vis[~leaf])


def om(frame, chunk=16, **_):
    """Staneker et al. 2003 over the leaves of the frustum."""
    leaves = np.flatnonzero(frame.in_frustum & frame.h.is_leaf)
    pending = _stage1(frame, leaves, chunk)
    for batch in range(OM_MAX_BATCHES):
        if not len(pending):
            break
        pending = frame.sort_near(pending)
        if batch == OM_MAX_BATCHES - 1:
            test, pending = pending, pending[:0]
        else:
            test, pending = _test_list(frame, pending)
        _resolve(frame, test, frame.query(test))


class OmMulti:
    """Staneker et al. 2004; keeps ``max_tests`` across frames (the 0.7 m rule).

    With ``coherent`` (this project's addition, after Bittner et al.'s CHC): the
    leaves found visible last frame are drawn first, without a query, and their
    ancestors are opened without one; each such leaf is queried again every
    ``RECHECK`` frames (staggered), so one that became hidden is culled soon.
    Only skipping queries, never culling without one, it stays conservative.
    """

    RECHECK = 8

    def __init__(self, max_tests=8, coherent=False):
        self.max_tests = max(1, int(max_tests))
        self.coherent = coherent
        self.assumed = None
        self.frame_no = 0

    def __call__(self, frame, chunk=16, **_):
        if not frame.in_frustum[0]:
            return
        if self.coherent:
            self._draw_assumed(frame)
        self._traverse(frame, chunk)
        if self.coherent:
            self._remember(frame)

    def forget(self):
        """Drop the memory of visible leaves (objects moved)."""
        self.assumed = None

    def _draw_assumed(self, frame):
        h = frame.h
        if self.assumed is None or len(self.assumed) != len(h):
            self.assumed = np.zeros(len(h), dtype=bool)
        pre = np.flatnonzero(self.assumed & frame.in_frustum)
        frame.draw_leaves(frame.sort_near(pre))
        frame.predrawn[pre] = True
        frame.stats["queries_skipped"] += len(pre)
        up = pre
        while len(up):                              # ancestors, one level per step
            frame.free[up] = True
            up = np.unique(h.parent[up])
            up = up[(up >= 0) & ~frame.free[up]]

    def _remember(self, frame):
        h = frame.h
        seen = h.is_leaf & frame.in_frustum
        seen[seen] = frame.state[h.leaf_unit[seen]] == Visibility.VISIBLE
        self.frame_no += 1
        self.assumed = seen & ((np.arange(len(h)) + self.frame_no) % self.RECHECK != 0)

    def _traverse(self, frame, chunk):
        pending = _stage1(frame, np.zeros(1, dtype=np.int64), chunk)
        rounds = 0
        # Stage 2: occupancy-map-arranged multiple queries.
        while len(pending) and rounds < self.max_tests:
            pending = frame.sort_near(pending)
            test, pending = _test_list(frame, pending)
            opened = _resolve(frame, test, frame.query(test))
            pending = np.concatenate([pending, _stage1(frame, opened, chunk)])
            rounds += 1
        # Stage 3: everything that remains, brute force, level by level.
        while len(pending):
            opened = _resolve(frame, pending, frame.query(pending))
            pending = _stage1(frame, opened, chunk)
            rounds += 1
        self.max_tests = max(1, math.ceil(0.7 * rounds)) if rounds else self.max_tests


STRATEGIES = ("vfc", "stopwait", "om", "om_multi", "om_coherent", "oracle")
DEFAULT_STRATEGY = "om_coherent"


def make_strategy(name, max_tests=8):
    """A callable ``strategy(frame, **options)`` for a strategy name."""
    table = {"vfc": vfc, "stopwait": stopwait, "om": om, "oracle": oracle}
    if name in ("om_multi", "om_coherent"):
        return OmMulti(max_tests, coherent=name == "om_coherent")
    if name not in table:
        raise OccError(f"unknown strategy '{name}'; choose one of {', '.join(STRATEGIES)}")
    return table[name]
