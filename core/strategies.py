"""Traversal strategies, registered in one place (:data:`REGISTRY`) that the CLI,
the add-on's choices and the benchmark read.  Each strategy is an object made
per engine by its factory; it takes a :class:`core.traversal.Frame`, draws what
it finds visible into the frame's depth buffer, marks what it proves occluded,
and leaves its counters in ``frame.stats``.  Whatever it keeps from one pass to
the next (the 0.7 m rule's ``max_tests``, last pass's visible leaves) lives in
the strategy object; ``reset()`` drops it.

Correctness is the same for all of them and does not depend on the occupancy
map: an object is culled only when it is outside the frustum or when an
occlusion query of a box around it (or around a group containing it) passed no
more than ``threshold`` samples against real geometry already drawn.  Drawing
less before a query can only make it say "visible" more often.

- ``vfc``      hierarchical frustum culling, draws everything inside.
- ``stopwait`` front to back, one query per node, waiting for each answer.
- ``leaf_stopwait`` the leaves in the frustum front to back, one query per leaf,
               waiting for each (no hierarchy, no map): the papers' plain baseline.
- ``om_single`` Staneker et al. 2003 as published: leaves front to back; the
               occupancy map skips queries in still-empty screen regions; every
               other leaf gets its own query, awaited before the next.
- ``om``       the 2003 map with the queries that remain batched: at most
               ``OM_MAX_BATCHES`` occupancy-map-arranged multiple queries.
- ``om_multi`` Staneker et al. 2004: hierarchical.  Stage 1 draws or opens what the
               occupancy map proves visible and defers the rest; stage 2 fills test
               lists through one cleared occupancy map per list (a box joins while
               one of its tiles is still free there) and issues each as one multiple
               query, at most ``max_tests`` rounds, ``max_tests(f + 1) = 0.7 m(f)``;
               stage 3 queries all that remain.
- ``om_coherent`` om_multi that draws last pass's visible leaves first, without
               queries, re-checking each every few passes (temporal coherence);
               after a camera cut or a sparse pass it starts fresh; at most
               ``COHERENT_READS`` multiple queries (GPU round trips) a pass.
- ``two_pass`` GPU-driven: last pass's visible leaves drawn first, every other leaf
               of the frustum tested in one batch, the nearer half of those that pass
               drawn and the rest tested once more (a handful of GL calls a pass);
               after a camera cut, an ``om_multi`` pass.
- ``gpu``      GPU-resident two passes: the units' boxes and matrices on the GPU, five
               compute dispatches and four indirect draws whose commands the GPU writes,
               one read-back a pass (:mod:`core.gl.gpucull`); ``om_coherent`` on the
               4.1 path.
- ``auto``     the default candidate: ``gpu`` where occlusion tests pay on this
               machine (costs measured), frustum culling alone where they cannot.
- ``oracle``   draws exactly the ground-truth set, no queries: the physical limit.
"""

import heapq
import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

from .errors import OccError
from .occupancy import X0, X1, Y0, Y1, free_tile_first
from .tolerance import tol
from .traversal import Visibility

OM_MAX_BATCHES = 5
COHERENT_READS = 5             # read-backs a pass of om_coherent (and auto): a GPU round trip each
MAX_TEST_CANDIDATES = 512      # bounds the pairwise work of one test list


class Strategy:
    """Base of the strategies: stateless unless a subclass keeps something."""

    def __call__(self, frame, chunk=16, truth=None):
        raise NotImplementedError

    def reset(self):
        """Forget what earlier passes taught (objects moved, a camera cut, a new scene)."""

    # A fresh pass asked (the add-on: a camera cut, a scene change): forget what would
    # cost accuracy; by default everything
    forget = reset

    def moved(self, objects=None):
        """Objects moved (``Culler.set_matrices``; ``objects``: their indices, None:
        any): by default, forget everything; a strategy whose memory only orders its
        work may keep it."""
        self.reset()


class Vfc(Strategy):
    def __call__(self, frame, chunk=16, truth=None):
        frame.draw_leaves(frame.frustum_leaves())


class Oracle(Strategy):
    def __call__(self, frame, chunk=16, truth=None):
        if truth is None:
            raise OccError("the oracle strategy needs the ground-truth visible set")
        h = frame.h
        leaves = frame.frustum_leaves()
        # a chunk of a truly visible object is drawn: the truth is per object
        seen = truth[frame.unit_object[h.leaf_unit[leaves]]]
        frame.ensure_geometry(leaves[seen])
        frame.draw_leaves(frame.sort_near(leaves[seen]))
        frame.state[h.leaf_unit[leaves[~seen]]] = Visibility.OCCLUDED


class StopWait(Strategy):
    """One query per node, answer awaited before the next (the baseline to beat)."""

    def __call__(self, frame, chunk=16, truth=None):
        h = frame.h
        if not len(frame.root()):
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


class LeafStopWait(Strategy):
    """The leaves in the frustum front to back, one awaited query each (no
    hierarchy above them, no occupancy map)."""

    use_map = False

    def __call__(self, frame, chunk=16, truth=None):
        leaves = frame.frustum_leaves()
        frame.ensure_geometry(leaves)
        for leaf in frame.sort_near(leaves):     # per leaf by design: a baseline
            one = np.array([leaf])
            if frame.crosses[leaf]:
                frame.stats["near_visible"] += 1
            elif self.use_map and frame.om.any_empty_tiles(frame.tiles[one])[0]:
                frame.stats["queries_skipped"] += 1
            elif not frame.query(one)[0]:
                frame.occlude(one)
                continue
            frame.draw_leaves(one)


class OmSingle(LeafStopWait):
    """Staneker et al. 2003 with single queries: leaves front to back; a leaf
    whose rectangle still has an empty tile is drawn without a query, any other
    gets its own query, awaited before the next leaf."""

    use_map = True


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
    """Split sorted ``pending`` into (test list, rest) by the papers' rule: a box
    joins while one of its tiles is free in the list's own (cleared) map."""
    cand = pending[:MAX_TEST_CANDIDATES]
    taken = free_tile_first(frame.tiles[cand], frame.om.rows, frame.om.cols)
    return cand[taken], np.concatenate([cand[~taken], pending[MAX_TEST_CANDIDATES:]])


def _frustum_leaves_below(frame, nodes):
    """Leaves inside the frustum in the subtrees of reached ``nodes`` (reaching the
    nodes between, with their rectangles)."""
    out, front = [], nodes
    while len(front):
        leaf = frame.h.is_leaf[front]
        out.append(front[leaf])
        front = frame.children_in_frustum(front[~leaf])
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def _resolve(frame, nodes, visible):
    """Act on query answers: occlude the hidden, draw visible leaves, open visible
    inner nodes; returns the opened children."""
    frame.occlude(nodes[~visible])
    vis = nodes[visible]
    leaf = frame.h.is_leaf[vis]
    frame.draw_leaves(vis[leaf])
    return frame.children_in_frustum(vis[~leaf])


class Om(Strategy):
    """Staneker et al. 2003 over the leaves of the frustum, remaining queries batched."""

    def __call__(self, frame, chunk=16, truth=None):
        leaves = frame.frustum_leaves()
        frame.ensure_geometry(leaves)
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


def camera_signature(camera):
    """What a coherent strategy compares between passes: eye, view rotation, projection."""
    return camera.eye, camera.view[:3, :3].copy(), camera.projection.copy()


def camera_cut(before, after, scene_size):
    """Whether the camera moved, turned or changed projection beyond the
    coherence thresholds of :mod:`core.tolerance` between two signatures."""
    if before is None:
        return True
    (e0, r0, p0), (e1, r1, p1) = before, after
    if np.linalg.norm(e1 - e0) > tol.coherence_move_rel * max(scene_size, 1e-300):
        return True
    # rotation angle of r1 @ r0.T from its trace (rows of a view rotation are orthonormal)
    cos = np.clip((np.trace(r1 @ r0.T) - 1.0) / 2.0, -1.0, 1.0)
    if math.degrees(math.acos(cos)) > tol.coherence_turn_deg:
        return True
    scale = np.abs(p0).max()
    return bool(np.abs(p1 - p0).max() > tol.coherence_projection_rel * scale)


class OmMulti(Strategy):
    """Staneker et al. 2004; keeps ``max_tests`` across frames (the 0.7 m rule).

    With ``coherent`` (this project's addition, after Bittner et al.'s CHC): the
    leaves found visible last pass are drawn first, without a query, and their
    ancestors are opened without one; each such leaf is queried again every
    ``RECHECK`` passes (staggered), so one that became hidden is culled soon.
    Only skipping queries, never culling without one, it stays conservative.

    ``read_budget`` (this project's, for the coherent default): at most that many
    multiple queries, hence blocking read-backs, a pass -- stage 2 gets all but two
    of them, and stage 3 asks what remains in one batch and then every leaf below
    the visible ones in another, instead of level by level.
    The memory is used only when the camera barely moved since the last pass
    (:func:`camera_cut`): after a cut, or a sparse pass (the add-on's), the pass
    starts fresh, so memory never makes a pass worse than a fresh one by more
    than what the last small move uncovered.
    """

    RECHECK = 8

    def __init__(self, max_tests=8, coherent=False, read_budget=None):
        self.max_tests = max(1, int(max_tests))
        self.coherent = coherent
        self.read_budget = read_budget
        self.assumed = None
        self.last_camera = None
        self.frame_no = 0

    def __call__(self, frame, chunk=16, truth=None):
        if self.coherent:
            sig = camera_signature(frame.camera)
            if camera_cut(self.last_camera, sig, frame.scene_size):
                self.assumed = None
                frame.stats["fresh"] = 1
            self.last_camera = sig
        if not len(frame.root()):
            return
        if self.coherent:
            self._draw_assumed(frame)
        self._traverse(frame, chunk)
        if self.coherent:
            self._remember(frame)

    def reset(self):
        """Drop the memory of visible leaves (objects moved, or a fresh pass asked)."""
        self.assumed = None
        self.last_camera = None

    forget = reset

    def _draw_assumed(self, frame):
        h = frame.h
        if self.assumed is None or len(self.assumed) != len(h):
            self.assumed = np.zeros(len(h), dtype=bool)
            return
        pre = frame.reach(np.flatnonzero(self.assumed))
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
        stage2 = self.max_tests if self.read_budget is None else min(self.max_tests, max(self.read_budget - 2, 0))
        # Stage 2: occupancy-map-arranged multiple queries.
        while len(pending) and rounds < stage2:
            pending = frame.sort_near(pending)
            test, pending = _test_list(frame, pending)
            opened = _resolve(frame, test, frame.query(test))
            pending = np.concatenate([pending, _stage1(frame, opened, chunk)])
            rounds += 1
        if self.read_budget is None:
            # Stage 3: everything that remains, brute force, level by level.
            while len(pending):
                opened = _resolve(frame, pending, frame.query(pending))
                pending = _stage1(frame, opened, chunk)
                rounds += 1
        elif len(pending):
            # Stage 3 within the read budget: what remains in one batch, then every
            # leaf below those found visible in a second one.
            opened = _resolve(frame, pending, frame.query(pending))
            rounds += 1
            # what the map proves visible below is drawn first, the rest's leaves tested
            leaves = _frustum_leaves_below(frame, _stage1(frame, opened, chunk))
            leaves = leaves[~frame.predrawn[leaves]]
            if len(leaves):
                _resolve(frame, leaves, frame.query(leaves))
                rounds += 1
        self.max_tests = max(1, math.ceil(0.7 * rounds)) if rounds else self.max_tests


class TwoPass(Strategy):
    """GPU-driven two passes (as nvpro's temporal culling and zeux's niagara do):
    last pass's visible leaves are drawn first, without a test; every other leaf
    in the frustum is tested in ONE multiple query against that depth; of those
    that pass, the nearer half is drawn and the farther half tested once more
    against it; whatever fails a test is occluded.  A handful of GL calls and at
    most two read-backs a pass, whatever the scene's size; the per-leaf work is
    numpy over the frustum's leaves, none per node of the traversal.

    Each remembered leaf is tested again every ``RECHECK`` passes (staggered), so
    one that became hidden is culled soon; after a camera cut (see
    :func:`camera_cut`) there is no memory, and the pass is an ``om_multi`` pass
    (the occupancy map finds the first occluders) whose visible leaves the next
    pass starts from.  Conservative: a test only fails against geometry really
    drawn.
    """

    RECHECK = 8

    def __init__(self, max_tests=8):
        self.assumed = None
        self.last_camera = None
        self.frame_no = 0
        self.fresh = OmMulti(max_tests)

    def reset(self):
        self.assumed = None
        self.last_camera = None

    forget = reset

    def __call__(self, frame, chunk=16, truth=None):
        sig = camera_signature(frame.camera)
        if camera_cut(self.last_camera, sig, frame.scene_size):
            self.assumed = None
            frame.stats["fresh"] = 1
        self.last_camera = sig
        h = frame.h
        if self.assumed is None or len(self.assumed) != len(h):
            self.assumed = np.zeros(len(h), dtype=bool)
        if not self.assumed.any():
            self.fresh(frame, chunk)                         # no memory: the occupancy map's pass
        else:
            self._two_passes(frame)
        self.frame_no += 1
        seen = h.is_leaf & frame.in_frustum
        seen[seen] = frame.state[h.leaf_unit[seen]] == Visibility.VISIBLE
        self.assumed = seen


    def _two_passes(self, frame):
        leaves = frame.frustum_leaves()
        frame.ensure_distance(leaves)
        # the recheck slot of remembered leaves is tested like the rest
        known = self.assumed[leaves] & ((leaves + self.frame_no) % self.RECHECK != 0)
        first, rest = leaves[known], leaves[~known]
        frame.draw_leaves(frame.sort_near(first))
        frame.stats["queries_skipped"] += len(first)
        visible = frame.query(rest)
        frame.occlude(rest[~visible])
        passed = frame.sort_near(rest[visible])
        half = (len(passed) + 1) // 2
        frame.draw_leaves(passed[:half])
        second = passed[half:]
        visible = frame.query(second)
        frame.occlude(second[~visible])
        frame.draw_leaves(second[visible])


class Gpu(Strategy):
    """GPU-resident two passes (nvpro's temporal culling, zeux's niagara): the units'
    boxes and matrices live on the GPU; a pass is five compute dispatches, two
    multi-draw-indirect draws and two box-test draws whose commands the GPU writes,
    and ONE read-back of every unit's state (:mod:`core.gl.gpucull`).  Pass 1 draws
    last pass's visible units (and those at the near plane); every other unit of
    the frustum is tested against a max-depth pyramid of that depth, and those that
    pass as rasterised boxes (as queries); those that pass both are drawn in pass 2;
    every drawn unit's box is then tested against the completed depth, which gives
    the states and the next pass's memory.  No per-node Python work in steady state; per unit, a few numpy
    reductions over the read-back words (the counters).

    On the first pass, and after ``reset()`` (``cull(fresh=True)``, a new scene),
    there is no memory: the pass is an ``om_coherent`` pass without memory (the
    occupancy map finds the first occluders), whose visible units the GPU then
    remembers.  Camera cuts, moved objects and the add-on's ``forget()`` keep the
    memory: it only chooses what pass 1 draws, so a cut costs drawing, never correctness.
    Conservative: a unit is OCCLUDED only when its grown box (the engine's guard) passed
    no sample against depth real geometry wrote.

    Falls back to ``om_coherent`` where the GPU path cannot run: the OpenGL 4.1 path
    (``OCC_GL=4.1``, macOS: no compute shaders, storage buffers or indirect draws),
    a ``visible_threshold`` above 0 (sample counts, not flags), or a driver whose
    compiler refuses the shaders (float64 in shaders is required); ``reason`` says
    which.  A display resolution above the query resolution is honoured (the whole
    depth is reduced before each test).
    """

    def __init__(self, max_tests=8):
        self.fallback = OmMulti(max_tests, coherent=True, read_budget=COHERENT_READS)
        self.fresh = OmMulti(max_tests, coherent=True, read_budget=COHERENT_READS)
        self.gpu = None
        self.reason = None
        self.uploaded_for = None          # (hierarchy, its bounds array) the GPU's boxes come from
        self.moved_objects = []           # objects moved since the last upload
        self.leaf_of_unit = None          # (units,) the hierarchy leaf of each unit, -1: none
        self.remembered = False
        self.last_camera = None

    def reset(self):
        self.uploaded_for = None
        self.remembered = False
        self.last_camera = None
        self.fallback.reset()

    def forget(self):
        """A fresh pass asked by the add-on (a click, a camera cut, a scene edit): the
        GPU's boxes and memory stay.  The memory only chooses what pass 1 draws and every
        state is still tested against the depth drawn, so it costs no accuracy, and a
        pass with it costs a fraction of a first pass (an ``om_coherent`` pass and a full
        upload).  The fallback's memory would cost accuracy: it goes."""
        self.fallback.reset()

    def moved(self, objects=None):
        """Objects moved: their units' boxes and matrices are uploaded again (all of
        them when ``objects`` is None or many moved); the memory is kept (it only
        chooses what pass 1 draws, at the new places; every state is still tested
        against the depth drawn), so live scenes with moving objects stay on the GPU
        path.  The fallback forgets as usual."""
        if objects is None or self.uploaded_for is None:
            self.uploaded_for = None
        else:
            self.moved_objects.append(np.asarray(objects, dtype=np.int64).reshape(-1))
        self.fallback.reset()

    def _unusable(self, frame):
        """Why this frame cannot run on the GPU path, or None."""
        if getattr(frame.r, "path", None) != "4.3":
            return "the OpenGL 4.1 path has no compute shaders, storage buffers or indirect draws"
        if frame.threshold > 0:
            return "a visible threshold above 0 needs sample counts"
        return None

    def _culler(self, frame):
        """The GPU side for this frame's renderer (made once per renderer), or None."""
        if self.gpu is not None and self.gpu.r is frame.r:
            return self.gpu
        from .gl.gpucull import for_renderer
        gpu, self.reason = for_renderer(frame.r)
        if gpu is None:
            # not the expected 4.1 fallback: a driver that refuses the shaders, said once
            warnings.warn(f"{self.reason}; the gpu strategy runs om_coherent instead", stacklevel=4)
        self.gpu, self.uploaded_for, self.remembered = gpu, None, False
        return gpu

    def __call__(self, frame, chunk=16, truth=None):
        self.reason = self._unusable(frame) or self.reason
        gpu = None if self.reason else self._culler(frame)
        if gpu is None:
            self.fallback(frame, chunk)
            return
        h = frame.h
        if self.uploaded_for is None or self.uploaded_for[0] is not h or self.uploaded_for[1] is not h.bounds:
            self._upload(frame, gpu)
        elif self.moved_objects:
            self._upload(frame, gpu, np.unique(np.concatenate(self.moved_objects)))
        if not self.remembered:
            frame.stats["fresh"] = 1
            self.fresh.reset()
            self.fresh(frame, chunk)                 # no memory: the occupancy map's pass
            gpu.remember(frame.state == Visibility.VISIBLE)
            self.remembered = True
            return
        t = time.perf_counter()
        pixels = max(frame.options.pixel_guard, tol.query_guard_px, frame.reduce_guard_px)
        words = gpu.run(frame, pixels)
        frame.t_query += time.perf_counter() - t
        self._record(frame, words)

    MAX_MOVED = 16      # objects moved at once beyond which every unit is uploaded again (one write)

    def _upload(self, frame, gpu, objects=None):
        """The units' boxes (the hierarchy's leaves) and matrices to the GPU: all of
        them, or those of ``objects`` (each object's units are consecutive)."""
        h, r = frame.h, frame.r
        self.moved_objects = []
        if objects is None or len(objects) > self.MAX_MOVED:
            leaves = np.flatnonzero(h.is_leaf)
            self.leaf_of_unit = np.full(len(r.units), -1, dtype=np.int64)
            self.leaf_of_unit[h.leaf_unit[leaves]] = leaves
            units = np.arange(len(r.units))
        else:
            units = np.concatenate([r.units.of_object[o] for o in objects]).astype(np.int64)
        leaf = self.leaf_of_unit[units]
        boxes = np.where((leaf >= 0)[:, None, None], h.bounds[np.maximum(leaf, 0)], 0.0)
        gpu.upload(boxes, leaf >= 0, r.world[r.units.object[units]], units)
        self.uploaded_for = (h, h.bounds)

    @staticmethod
    def _record(frame, words):
        """The states and counters of the pass from the units' words."""
        from .gl import gpucull as G
        state = (words & G.STATE).astype(np.uint8)
        frame.state[:] = state
        drawn = (words & (G.DRAWN1 | G.DRAWN2)) != 0
        near = (words & G.NEAR) != 0
        tri = frame.r.tri_counts
        s = frame.stats
        s["units_drawn"] = int(drawn.sum())
        s["triangles_drawn"] = int(tri[drawn].sum())
        # what the pass saved: occluded and never drawn (a unit drawn and then found hidden is not)
        s["triangles_occluded"] = int(tri[(state == Visibility.OCCLUDED) & ~drawn].sum())
        s["queries"] = int(np.count_nonzero(words & G.TESTED1) + np.count_nonzero(words & G.TESTED2))
        s["multiple_queries"] = 2
        s["queries_skipped"] = int(np.count_nonzero((words & G.DRAWN1) != 0) - near.sum())
        s["near_visible"] = int(near.sum())
        s["nodes_visited"] = len(words)


class Auto(Strategy):
    """The default: occlusion tests (``gpu``, which is ``om_coherent`` where the GPU
    path cannot run) where they pay on this machine, frustum culling alone where they
    cannot (few or cheap triangles behind what is seen, or a GPU that draws
    everything faster than the tests' round trips).

    Costs are measured on real passes, not assumed: the first pass tests occlusion
    (and times a query batch's round trip); the second draws everything in the
    frustum, which gives the cost of a triangle as the scene really draws (fill
    included) and of a frustum-only pass beyond its drawing; one such pass comes
    again every ``PROBE_EVERY`` test passes while the tests cost more than ``CLOSE``
    of that estimate (where they clearly win, re-learning would only cost).  After each test pass it compares the
    pass's time with what frustum culling would have cost -- the triangles drawn
    plus those the tests proved hidden, at the measured cost, plus the frustum-only
    overhead -- and after ``LOSSES`` passes in a row where the tests did not pay it
    switches to frustum culling, probing the tests again after ``PROBE_EVERY``
    passes (twice as many after each probe that loses, up to ``PROBE_MAX``: on a
    scene where the tests never pay, the probes fade out; back to ``PROBE_EVERY``
    once one wins), or at once when a frustum-only pass is ``PROBE_SLOWER`` times
    slower than the last test pass (``FIRST_SLOWER`` for the first one after a
    switch), so a view that gets heavy is tested at once whatever the interval.
    Both modes are conservative, so the choice changes speed only.
    """

    ROUND_TRIPS = 3          # blocking reads that time a batch's round trip (median of them)

    LOSSES = 3                   # passes in a row where the tests did not pay (timing noise is common)
    PROBE_EVERY = 16
    PROBE_MAX = 128              # the longest interval between probes, after probes that lost
    PROBE_SLOWER = 2.0           # a frustum-only pass this much slower than the last test pass: probe at once
    FIRST_SLOWER = 1.0           # ... and the first frustum-only pass after a switch: was the switch right?
    PROBE_MARGIN = 0.9           # a probe switches back when it beats the frustum-only estimate by this much
    LOSS_MARGIN = 1.05           # a test pass loses when it costs this much more than the estimate (noise)
    SAVED_MIN = 0.05             # a test pass that hides less than this share of the frustum's triangles loses
    CLOSE = 0.5                  # test passes above this share of the estimate re-learn the costs every PROBE_EVERY
    LEARN = 0.3                  # weight of a new measurement in the running cost

    def __init__(self, max_tests=8, costs=None):
        self.occlusion = Gpu(max_tests)
        # tri_ms: ms per triangle a frustum-only pass draws; vfc_cpu_ms: such a pass's
        # time beyond its drawing; round_trip_ms: one query batch
        self.costs = dict(costs) if costs is not None else None
        self.use_tests = True
        self.losses = 0
        self.since_probe = 0             # frustum-only passes since the last test pass
        self.probe_every = self.PROBE_EVERY  # frustum-only passes before the next probe
        self.since_learn = 0             # test passes since the last frustum-only one
        self.last_test_ms = None
        self.close = True                # the last test pass was near the frustum-only estimate
        self.learn_count = 0             # frustum-only passes made to learn the costs

    def reset(self):
        self.occlusion.reset()

    def forget(self):
        self.occlusion.forget()

    def moved(self, objects=None):
        self.occlusion.moved(objects)

    @property
    def learned(self):
        """Whether a frustum-only pass's costs were measured (or given)."""
        return self.costs is not None and self.costs.get("tri_ms") is not None

    def _round_trip(self, frame):
        start = time.perf_counter()
        # a small box ahead of the eye (only the round trip's time is used)
        centre = frame.camera.direction * (0.01 * frame.scene_size)
        box = (centre + np.array([[-1.0], [1.0]]) * (1e-3 * frame.scene_size))[None]
        trips = []
        for _ in range(self.ROUND_TRIPS):
            t = time.perf_counter()
            frame.r.query(box, counts=False)
            trips.append(1e3 * (time.perf_counter() - t))
        frame.t_query += time.perf_counter() - start     # GL work: not the pass's CPU time
        self.costs = {"tri_ms": None, "vfc_cpu_ms": 0.0, "round_trip_ms": float(np.median(trips))}

    def __call__(self, frame, chunk=16, truth=None):
        if self.costs is None:
            self._round_trip(frame)
        if self.use_tests:
            # learn on the second pass, again on the fourth (the first frustum-only pass
            # pays first-draw costs), then every PROBE_EVERY while the result is close
            due = 1 if self.learn_count < 2 else (self.PROBE_EVERY if self.close else None)
            if due is not None and self.since_learn >= due:
                self._frustum_only(frame, learning=True)
            else:
                self._tests(frame, chunk, probe=False)
        elif self.since_probe >= self.probe_every:
            self._tests(frame, chunk, probe=True)
        else:
            self._frustum_only(frame, learning=False)

    def _tests(self, frame, chunk, probe):
        self.since_probe = 0
        self.since_learn += 1
        frame.stats["occlusion_pass"] = 1
        self.occlusion(frame, chunk)
        frame.finish_gl()
        spent = self.last_test_ms = 1e3 * (time.perf_counter() - frame.t0)
        if not self.learned:
            return                                   # nothing to compare with yet
        c, s = self.costs, frame.stats
        frustum_only = (s["triangles_drawn"] + s["triangles_occluded"]) * c["tri_ms"] + c["vfc_cpu_ms"]
        paid = spent < frustum_only * (self.PROBE_MARGIN if probe else self.LOSS_MARGIN)
        # whatever the clock says: tests that hide almost nothing cannot pay for themselves
        saved = s["triangles_occluded"]
        paid &= saved >= self.SAVED_MIN * (s["triangles_drawn"] + saved)
        self.close = spent > self.CLOSE * frustum_only
        self.losses = 0 if paid else self.losses + 1
        self.use_tests = paid if probe else self.losses < self.LOSSES
        if probe:
            self.probe_every = self.PROBE_EVERY if paid else min(2 * self.probe_every, self.PROBE_MAX)

    def _frustum_only(self, frame, learning):
        if learning:
            self.since_learn = 0
        else:
            self.since_probe += 1
        leaves = frame.frustum_leaves()
        t = time.perf_counter()
        frame.draw_leaves(leaves)
        frame.finish_gl()
        end = time.perf_counter()
        c = self.costs
        drawn = frame.stats["triangles_drawn"]
        learn = self.LEARN if self.learned else 1.0
        if drawn:
            self.learn_count += learning
            # down at once, up slowly: load, and first draws, only ever add time
            tri_ms = 1e3 * (end - t) / drawn
            c["tri_ms"] = tri_ms if c["tri_ms"] is None else min(tri_ms, c["tri_ms"] + learn * (tri_ms - c["tri_ms"]))
        elif c["tri_ms"] is None:
            return                                   # nothing drawn: learn on a later pass
        c["vfc_cpu_ms"] += learn * (1e3 * (t - frame.t0) - c["vfc_cpu_ms"])
        if learning:
            return
        # the first frustum-only pass after a switch is measured against the last test
        # pass as it is (was the switch right?), later ones with a margin (the view got heavier)
        slower = self.PROBE_SLOWER if self.since_probe > 1 else self.FIRST_SLOWER
        if self.last_test_ms is not None and 1e3 * (end - frame.t0) > slower * self.last_test_ms:
            self.since_probe = self.probe_every = self.PROBE_EVERY     # test again next pass


@dataclass(frozen=True)
class StrategyInfo:
    """One registered strategy: its factory ``(max_tests) -> Strategy``, a short
    label and description (the add-on's menu), and whether the default may pick it."""

    name: str
    factory: object
    label: str
    description: str
    default_candidate: bool = False
    needs_truth: bool = False


REGISTRY = {info.name: info for info in (
    StrategyInfo("vfc", lambda m: Vfc(), "Frustum only", "Hide only what is outside the view", True),
    StrategyInfo("stopwait", lambda m: StopWait(), "Stop and wait",
                 "Hierarchical, one query per node, waiting for each"),
    StrategyInfo("leaf_stopwait", lambda m: LeafStopWait(), "Leaf queries",
                 "One query per object part, waiting for each (baseline)"),
    StrategyInfo("om_single", lambda m: OmSingle(), "Occupancy map, single queries",
                 "Staneker et al. 2003 as published: occupancy map, one query at a time"),
    StrategyInfo("om", lambda m: Om(), "Occupancy map",
                 "Staneker et al. 2003: occupancy map, remaining queries batched"),
    StrategyInfo("om_multi", lambda m: OmMulti(m), "Multiple queries",
                 "Staneker et al. 2004: occupancy-map-arranged multiple queries", True),
    StrategyInfo("om_coherent", lambda m: OmMulti(m, coherent=True, read_budget=COHERENT_READS), "Coherent",
                 "Occupancy map, multiple queries, last pass's visible first", True),
    StrategyInfo("two_pass", lambda m: TwoPass(m), "Two passes",
                 "Last pass's visible first, every other leaf tested in one batch (GPU-driven)", True),
    StrategyInfo("gpu", lambda m: Gpu(m), "GPU-driven",
                 "Units' boxes on the GPU: last pass's visible drawn, everything else tested there, "
                 "one read a pass; Coherent where the GPU path cannot run (OpenGL 4.1, macOS)", True),
    StrategyInfo("auto", lambda m: Auto(m), "Automatic",
                 "Occlusion tests where they pay on this machine, frustum culling where they cannot", True),
    StrategyInfo("oracle", lambda m: Oracle(), "Oracle",
                 "Draws exactly the truly visible set (benchmark limit, needs the truth)",
                 needs_truth=True),
)}
STRATEGIES = tuple(REGISTRY)
DEFAULT_STRATEGY = "auto"


def make_strategy(name, max_tests=8):
    """A strategy object (``strategy(frame, chunk=, truth=)``) for a registered name."""
    if name not in REGISTRY:
        raise OccError(f"unknown strategy '{name}'; choose one of {', '.join(STRATEGIES)}")
    return REGISTRY[name].factory(max_tests)
