"""One culling pass (:class:`CullPass`): everything a strategy reads and the counters
it fills: camera-relative boxes, frustum flags, screen rectangles, front-to-back
distances, the occupancy map and the guard that keeps every query conservative."""

import time

import numpy as np

from ..bounds import BOX_FACES, MAX, MIN, corners
from ..frustum import classify, planes_from_matrix
from ..occupancy import OccupancyMap, project_rects
from ..tolerance import tol
from .result import PassStats, Visibility


class CullPass:
    """One culling pass: everything a strategy reads and the counters it fills.

    Node arrays are indexed by hierarchy node and filled only for the nodes the
    pass reaches (work proportional to what the pass touches, not to the
    hierarchy): a node is *reached* when its parent is opened (or it is the
    root, or a strategy asks for it by name); reaching it classifies it against
    the frustum (with its parent's plane mask) and, when it is inside and
    ``geometry`` is on, computes its screen rectangle, tiles, near-plane flag
    and front-to-back distance.  A leaf reached inside the frustum starts
    VISIBLE; strategies demote it to OCCLUDED with a query.

    skip: ``(N,) bool`` nodes never drawn nor queried (objects with NaN or
    infinite values: kept visible by the engine, never occluders).
    """

    def __init__(self, tree, renderer, camera, options, scene_size, query_pixels: bool = True):
        self.tree = tree
        # count the pixels each query box rasterises (the 2003 paper's figure: a projection
        # of every box tested); without it, query_raster_pixels stays 0
        self.query_pixels = query_pixels
        self.renderer = renderer
        self.camera = camera
        self.options = options
        self.threshold = int(options.visible_threshold)
        self.stats = PassStats()
        self.t_query = self.t_draw = self.t_reach = 0.0
        self.t0 = time.perf_counter()
        self.unit_object = renderer.units.object
        self.n_objects = renderer.n
        # per draw unit; reduced to objects (the most visible of their units) at the end
        self.state = np.full(len(self.unit_object), Visibility.VIEW_CULLED, dtype=np.uint8)
        self.om = OccupancyMap(renderer.width, renderer.height, options.tiles)
        t = time.perf_counter()
        renderer.begin_frame(camera)
        self.t_begin = time.perf_counter() - t
        self.clip = renderer.clip
        self.eye = np.asarray(renderer.eye, dtype=np.float64)
        self.planes = planes_from_matrix(self.clip)
        self.scene_size = scene_size
        n = len(tree)
        self.is_leaf = tree.is_leaf
        # calloc'd: untouched pages cost nothing, so these are O(reached) in practice
        self.reached = np.zeros(n, dtype=bool)
        self.in_frustum = np.zeros(n, dtype=bool)
        self.mask = np.zeros(n, dtype=np.uint8)
        self.rects = np.zeros((n, 4), dtype=np.int64)
        self.tiles = np.zeros((n, 4), dtype=np.int64)
        self.crosses = np.zeros(n, dtype=bool)
        self.dist = np.zeros(n, dtype=np.float64)
        self.has_geometry = np.zeros(n, dtype=bool)
        # Set by coherent strategies: nodes opened or drawn without a query, and
        # leaves drawn before the traversal started.
        self.free = np.zeros(n, dtype=bool)
        self.predrawn = np.zeros(n, dtype=bool)
        self._to_draw: list = []            # units drawn on the CPU side, not yet sent to GL
        # World size of one query pixel per unit of distance (perspective) or
        # absolute (orthographic), the larger of the two axes.
        p = camera.projection
        self.perspective = not camera.is_orthographic
        self.pixel_world = 2.0 / min(abs(p[0, 0]) * renderer.width, abs(p[1, 1]) * renderer.height)
        # A renderer that reduces display-resolution depth to the query resolution is
        # conservative only with boxes grown by one query pixel (core/gl notes).
        self.reduce_guard_px = 1.0 if getattr(renderer, "reduces", False) else 0.0
        # Eye-space depth of one depth-buffer step: times d^2 (perspective) or absolute.
        steps = 2.0 ** tol.depth_bits
        self.depth_step = 2.0 / ((abs(p[2, 3]) if self.perspective else abs(p[2, 2])) * steps)

    def boxes(self, nodes):
        """Camera-relative boxes of ``nodes``, ``(k, 2, 3) float64``."""
        return self.tree.bounds[nodes] - self.eye

    # --- reaching nodes --------------------------------------------------------
    def reach(self, nodes, masks=None, geometry=True):
        """Classify ``nodes`` against the frustum (planes in ``masks``, default all)
        and return those inside; fills their node arrays (see the class doc)."""
        nodes = np.asarray(nodes, dtype=np.int64)
        if not len(nodes):
            return nodes
        t = time.perf_counter()
        self.stats.nodes_visited += len(nodes)
        b = self.boxes(nodes)
        if masks is not None and not masks.any():      # inside every plane already (plane masking)
            outside, remaining = np.zeros(len(nodes), dtype=bool), masks
        else:
            outside, remaining = classify(self.planes, b, masks)
        keep = nodes[~outside]
        self.reached[nodes] = True
        self.in_frustum[keep] = True
        self.mask[keep] = remaining[~outside]
        # leaves inside the frustum start VISIBLE; strategies demote to OCCLUDED
        leaves = keep[self.is_leaf[keep]]
        self.state[self.tree.leaf_unit[leaves]] = Visibility.VISIBLE
        if geometry and len(keep):
            self._geometry(keep, b[~outside])
        self.t_reach += time.perf_counter() - t
        return keep

    def _geometry(self, nodes, b):
        self.has_geometry[nodes] = True
        self.rects[nodes], self.crosses[nodes] = project_rects(b, self.clip, self.renderer.width, self.renderer.height,
                                                               self.planes[4])
        self.tiles[nodes] = self.om.tile_rects(self.rects[nodes])
        # Front-to-back key: distance from the eye (the origin here) to the box's
        # nearest point, 0 when the eye is inside.
        nearest = np.maximum(np.maximum(b[:, MIN], -b[:, MAX]), 0.0)
        self.dist[nodes] = np.sqrt((nearest * nearest).sum(axis=1))

    def root(self):
        """The root, reached: ``(1,)`` when it is inside the frustum, else ``(0,)``."""
        return self.reach(np.zeros(1, dtype=np.int64))

    def children_in_frustum(self, nodes, geometry=True):
        """Reach the children of ``nodes`` (reached nodes) with their parents' plane
        masks; returns those inside the frustum."""
        nodes = np.asarray(nodes, dtype=np.int64)
        kids = self.tree.children(nodes)
        masks = np.repeat(self.mask[nodes], self.tree.child_count[nodes])
        return self.reach(kids, masks, geometry)

    def frustum_leaves(self, geometry=False):
        """Hierarchical view-frustum culling of the whole tree with plane masking,
        one level at a time; returns the leaves inside (for strategies that draw
        or look at every one of them)."""
        front = self.reach(np.zeros(1, dtype=np.int64), geometry=geometry)
        out = []
        while len(front):
            leaf = self.is_leaf[front]
            out.append(front[leaf])
            front = self.children_in_frustum(front[~leaf], geometry)
        return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)

    def ensure_distance(self, nodes):
        """Front-to-back distances of reached ``nodes`` (no rectangles)."""
        b = self.boxes(nodes)
        nearest = np.maximum(np.maximum(b[:, MIN], -b[:, MAX]), 0.0)
        self.dist[nodes] = np.sqrt((nearest * nearest).sum(axis=1))

    def ensure_geometry(self, nodes):
        """Rectangles and distances of reached ``nodes`` that were reached without them."""
        t = time.perf_counter()
        self._geometry(nodes, self.boxes(nodes))
        self.t_reach += time.perf_counter() - t

    # --- helpers the strategies share -------------------------------------------
    def sort_near(self, nodes):
        """``nodes`` ordered front to back."""
        return nodes[np.argsort(self.dist[nodes], kind="stable")]

    def draw_leaves(self, leaves):
        """Draw leaf nodes and mark their rectangles in the occupancy map.  The GL
        draw waits for :meth:`flush` (before the next query, or the pass's end), so
        the leaves proven visible between two queries go out in one draw call."""
        if not len(leaves):
            return
        units = self.tree.leaf_unit[leaves]
        self._to_draw.append(units)
        self.stats.units_drawn += len(units)
        self.state[units] = Visibility.VISIBLE
        self.om.set_tiles(self.tiles[leaves[self.has_geometry[leaves]]])

    def flush(self):
        """Issue the draws :meth:`draw_leaves` collected, in their order (one call)."""
        if not self._to_draw:
            return
        units = self._to_draw[0] if len(self._to_draw) == 1 else np.concatenate(self._to_draw)
        self._to_draw = []
        t = time.perf_counter()
        self.stats.triangles_drawn += self.renderer.draw(units)
        self.t_draw += time.perf_counter() - t

    def guard(self, b):
        """How far each camera-relative box ``(k, 2, 3)`` grows before its query,
        per axis, ``(k, 3)``.

        Conservative: the sum of (1) a relative guard before float32 rounding,
        (2) at least ``tol.query_guard_px`` query pixels (more with the
        ``pixel_guard`` option) measured at the box's farthest eye-space depth
        (where a world unit covers the fewest pixels), so the answer does not
        hang on one renderer's sample rounding, and (3)
        ``tol.depth_guard_steps`` depth-buffer steps at that depth, along the
        rays through the box (towards the eye, not across), so ties with the
        occluders' depths count as visible.

        The pixel guard widens the box across the rays through it, not along
        them: axis i grows by ``r * sqrt(1 - v_i^2)`` with ``v_i`` the smallest
        component along i of a ray direction through the box (for every screen
        direction u across a ray v, ``|u_i| <= sqrt(1 - v_i^2)``, so the grown
        box's outline grows by at least r on screen everywhere), and a box seen
        along an axis does not grow towards the eye by a pixel's width.
        """
        k = len(b)
        mag = np.abs(b).reshape(k, 6).max(axis=1)
        base = (tol.box_grow_rel * (mag + (b[:, MAX] - b[:, MIN]).max(axis=1))
                + tol.box_grow_scene * self.scene_size)
        pixels = max(self.options.pixel_guard, tol.query_guard_px, self.reduce_guard_px)
        if self.perspective:
            # farthest and nearest eye-space depth: w of the corners farthest and
            # nearest along the w row
            wrow = self.clip[3, :3]
            pos = wrow >= 0.0
            far_w = np.maximum(np.where(pos, b[:, MAX], b[:, MIN]) @ wrow + self.clip[3, 3], 0.0)
            near_w = np.where(pos, b[:, MIN], b[:, MAX]) @ wrow + self.clip[3, 3]
            lateral = pixels * self.pixel_world * far_w
            # ray directions v through the box: |v_i| between near_abs_i / far_norm
            # and far_abs_i / near_norm
            near_abs = np.where((b[:, MIN] <= 0.0) & (b[:, MAX] >= 0.0), 0.0,
                                np.minimum(np.abs(b[:, MIN]), np.abs(b[:, MAX])))
            far_abs = np.maximum(np.abs(b[:, MIN]), np.abs(b[:, MAX]))
            far_norm = np.sqrt((far_abs * far_abs).sum(axis=1))
            near_norm = np.sqrt((near_abs * near_abs).sum(axis=1))
            v_min = near_abs / np.maximum(far_norm, tol.guard_tiny)[:, None]
            v_max = np.minimum(far_abs / np.maximum(near_norm, tol.guard_tiny)[:, None], 1.0)
            # moving a point by s along its ray lowers its eye depth by s * w / |p| >= s * near_w / far_norm
            tie = (tol.depth_guard_steps * self.depth_step * far_w ** 2
                   * far_norm / np.maximum(near_w, tol.guard_tiny + tol.guard_near_w_rel * far_norm))
        else:
            lateral = np.full(k, pixels * self.pixel_world)
            v_min = v_max = np.broadcast_to(np.abs(self.camera.direction), (k, 3))
            tie = np.full(k, tol.depth_guard_steps * self.depth_step)
        across = np.sqrt(np.maximum(1.0 - v_min * v_min, 0.0))
        # the box grown by s * |v_i| on axis i holds every point moved by s towards the eye
        return base[:, None] + lateral[:, None] * across + tie[:, None] * v_max

    def query(self, nodes):
        """One multiple query over ``nodes``; returns ``(k,) bool`` visible.

        Boxes grow by :meth:`guard` before float32, and a node counts as
        visible when more than ``threshold`` samples pass (0: any sample, ties
        included, is visible).
        """
        if not len(nodes):
            return np.zeros(0, dtype=bool)
        b = self.boxes(nodes)
        grow = self.guard(b)
        grown = b + np.array([-1.0, 1.0])[None, :, None] * grow[:, None, :]
        # Conservative: a grown box that reaches the near plane would be clipped
        # there (its front faces cut away, nothing left to pass): visible, no query.
        near = self.planes[4]
        lowest = np.where(near[:3] >= 0.0, grown[:, MIN], grown[:, MAX]) @ near[:3] + near[3]
        scale = np.abs(grown).reshape(len(b), 6).max(axis=1)
        clipped = lowest <= tol.near_guard_rel * scale
        visible = clipped.copy()
        asked = ~clipped
        self.stats.near_visible += int(clipped.sum())
        if asked.any():
            self.flush()                    # the occluders before the boxes tested against them
            t = time.perf_counter()
            # Sample counts only where a threshold needs them: a flag per box is a plain
            # store, a count an atomic add per fragment (8-15x slower on an NVIDIA H200)
            samples = self.renderer.query(grown[asked], counts=self.threshold > 0)
            self.t_query += time.perf_counter() - t
            r = self.rects[nodes[asked]]
            self.stats.queries += len(r)
            self.stats.multiple_queries += 1
            self.stats.samples_passed += int(samples.sum())     # threshold 0: boxes with any sample
            area = (r[:, 2] - r[:, 0] + 1) * (r[:, 3] - r[:, 1] + 1)
            measured = self.has_geometry[nodes[asked]]
            if self.query_pixels or not measured.all():
                outline = self.outline_pixels(grown[asked])
                # nodes reached without rectangles (the two-pass strategy): their outlines
                area = np.where(measured, area, np.ceil(outline))
                if self.query_pixels:
                    self.stats.query_raster_pixels += int(np.minimum(outline, area).sum())
            self.stats.query_rect_pixels += int(area.sum())
            visible[asked] = samples > self.threshold
        return visible

    def outline_pixels(self, b):
        """Pixels a query box rasterises (the 2003 paper's count), ``(k,) float``:
        the area of its projected outline, the sum of its front faces' projected
        areas.  ``b`` are camera-relative boxes entirely in front of the near plane."""
        c = corners(b)
        hom = c @ self.clip[[0, 1, 3], :3].T + self.clip[[0, 1, 3], 3]          # x, y, w
        sx = hom[..., 0] / hom[..., 2] * (0.5 * self.renderer.width)
        sy = hom[..., 1] / hom[..., 2] * (0.5 * self.renderer.height)
        x, y = sx[:, BOX_FACES], sy[:, BOX_FACES]                               # (k, 6, 4)
        signed = 0.5 * (x * np.roll(y, -1, axis=2) - np.roll(x, -1, axis=2) * y).sum(axis=2)
        return np.abs(signed).sum(axis=1) * 0.5     # front and back faces cover the outline once each

    def occlude(self, nodes):
        """Mark every unit below ``nodes`` OCCLUDED (those inside the frustum;
        leaves not reached yet are classified here, so the others stay VIEW_CULLED)."""
        leaves = self.tree.leaves_below(nodes)
        if not len(leaves):
            return
        todo = leaves[~self.reached[leaves]]
        if len(todo):
            t = time.perf_counter()
            outside, _ = classify(self.planes, self.boxes(todo))
            self.in_frustum[todo[~outside]] = True
            self.reached[todo] = True
            self.t_reach += time.perf_counter() - t
        leaves = leaves[self.in_frustum[leaves]]
        units = self.tree.leaf_unit[leaves]
        self.state[units] = Visibility.OCCLUDED
        self.stats.triangles_occluded += int(self.renderer.tri_counts[units].sum())

    def object_state(self):
        """Per object: the most visible state of its units, ``(n,) uint8``."""
        uo = self.unit_object
        if len(uo) == self.n_objects:             # one unit per object, unit i = object i
            return self.state.copy()
        out = np.full(self.n_objects, Visibility.VIEW_CULLED, dtype=np.uint8)
        if not len(uo):
            return out
        # units are stored object by object: reduce each object's run
        starts = np.flatnonzero(np.r_[True, uo[1:] != uo[:-1]])
        out[uo[starts]] = np.minimum.reduceat(self.state, starts)
        return out

    def finish_gl(self):
        """Send what is collected and wait for the GPU (timed as drawing)."""
        self.flush()
        t = time.perf_counter()
        self.renderer.finish()
        self.t_draw += time.perf_counter() - t

    def finish(self):
        self.finish_gl()
        total = time.perf_counter() - self.t0
        s = self.stats
        s.frustum_ms = 1e3 * self.t_reach
        s.query_ms = 1e3 * self.t_query
        s.draw_ms = 1e3 * self.t_draw
        s.total_ms = 1e3 * total
        s.traversal_ms = max(0.0, s.total_ms - s.query_ms - s.draw_ms)
        # CPU time of the pass outside GL calls (what a faster GPU cannot shorten)
        s.gl_ms = s.query_ms + s.draw_ms + 1e3 * self.t_begin
        s.cpu_ms = max(0.0, s.total_ms - s.gl_ms)
        counters = getattr(self.renderer, "counters", None)
        if counters is not None:              # renderers that count their GL calls
            s.gl_calls = int(counters.get("gl_calls", 0))
            s.blocking_reads = int(counters.get("blocking_reads", 0))
        else:
            s.gl_calls = s.blocking_reads = -1
        return s
