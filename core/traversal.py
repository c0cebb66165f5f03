"""Per-frame state shared by the strategies: camera-relative boxes, frustum flags,
screen rectangles, front-to-back distances, the occupancy map and the counters.

Results are three states per object (as in Masked Occlusion Culling):
VISIBLE, OCCLUDED (a query proved it hidden) and VIEW_CULLED (outside the frustum).
"""

import time
from enum import IntEnum

import numpy as np

from .bounds import MAX, MIN
from .frustum import ALL_PLANES, classify, planes_from_matrix
from .occupancy import OccupancyMap, project_rects
from .tolerance import tol


class Visibility(IntEnum):
    VISIBLE = 0
    OCCLUDED = 1
    VIEW_CULLED = 2


STAT_KEYS = ("queries", "queries_skipped", "near_visible", "multiple_queries", "samples_passed",
             "query_rect_pixels", "triangles_drawn", "units_drawn", "nodes_visited",
             "frustum_ms", "traversal_ms", "query_ms", "draw_ms", "total_ms")


class Frame:
    """One culling pass: everything a strategy reads and the counters it fills.

    Node arrays are indexed by hierarchy node; rectangles and distances are
    computed once per frame, for the nodes inside the frustum only.
    """

    def __init__(self, hierarchy, renderer, camera, options, scene_size):
        self.h = hierarchy
        self.r = renderer
        self.camera = camera
        self.options = options
        self.threshold = int(options.visible_threshold)
        self.stats = dict.fromkeys(STAT_KEYS, 0)
        self.t_query = self.t_draw = 0.0
        self.t0 = time.perf_counter()
        self.unit_object = renderer.units.object
        self.n_objects = renderer.n
        # per draw unit; reduced to objects (the most visible of their units) at the end
        self.state = np.full(len(self.unit_object), Visibility.VIEW_CULLED, dtype=np.uint8)
        self.om = OccupancyMap(renderer.width, renderer.height, options.tiles)
        renderer.begin_frame(camera)
        self.clip = renderer.clip
        eye = renderer.eye
        self.boxes = hierarchy.bounds - eye                 # camera-relative, float64
        self.scene_size = scene_size
        t = time.perf_counter()
        self.in_frustum = self._frustum_cull(planes_from_matrix(self.clip))
        self.stats["frustum_ms"] = 1e3 * (time.perf_counter() - t)
        live = np.flatnonzero(self.in_frustum)
        self.rects = np.zeros((len(hierarchy), 4), dtype=np.int64)
        self.crosses = np.zeros(len(hierarchy), dtype=bool)
        self.rects[live], self.crosses[live] = project_rects(
            self.boxes[live], self.clip, renderer.width, renderer.height)
        self.tiles = self.om.tile_rects(self.rects)          # the same in occupancy tiles
        # Set by coherent strategies: nodes opened or drawn without a query, and
        # leaves drawn before the traversal started.
        self.free = np.zeros(len(hierarchy), dtype=bool)
        self.predrawn = np.zeros(len(hierarchy), dtype=bool)
        # Front-to-back key: distance from the eye (the origin here) to the box's
        # nearest point, 0 when the eye is inside.
        b = self.boxes
        nearest = np.maximum(np.maximum(b[:, MIN], -b[:, MAX]), 0.0)
        self.dist = np.linalg.norm(nearest, axis=1)
        # World size of one query pixel per unit of distance (perspective) or
        # absolute (orthographic), the larger of the two axes.
        p = camera.projection
        px = 2.0 / min(abs(p[0, 0]) * renderer.width, abs(p[1, 1]) * renderer.height)
        self.pixel_world = (px, not camera.is_orthographic)

    def _frustum_cull(self, planes):
        """Hierarchical view-frustum culling with plane masking, one level at a time."""
        h = self.h
        inside = np.zeros(len(h), dtype=bool)
        front = np.zeros(1, dtype=np.int64)
        masks = np.full(1, ALL_PLANES, dtype=np.uint8)
        while len(front):
            self.stats["nodes_visited"] += len(front)
            outside, remaining = classify(planes, self.boxes[front], masks)
            keep, masks = front[~outside], remaining[~outside]
            inside[keep] = True
            inner = ~h.is_leaf[keep]
            front = h.children(keep[inner])
            masks = np.repeat(masks[inner], h.child_count[keep[inner]])
        leaves = np.flatnonzero(inside & h.is_leaf)
        # objects inside the frustum start VISIBLE; strategies demote to OCCLUDED
        self.state[h.leaf_unit[leaves]] = Visibility.VISIBLE
        return inside

    # --- helpers the strategies share -------------------------------------------
    def sort_near(self, nodes):
        """``nodes`` ordered front to back."""
        return nodes[np.argsort(self.dist[nodes], kind="stable")]

    def children_in_frustum(self, nodes):
        kids = self.h.children(nodes)
        return kids[self.in_frustum[kids]]

    def draw_leaves(self, leaves):
        """Draw leaf nodes and mark their rectangles in the occupancy map."""
        if not len(leaves):
            return
        units = self.h.leaf_unit[leaves]
        t = time.perf_counter()
        self.stats["triangles_drawn"] += self.r.draw(units)
        self.t_draw += time.perf_counter() - t
        self.stats["units_drawn"] += len(units)
        self.om.set_tiles(self.tiles[leaves])

    def query(self, nodes):
        """One multiple query over ``nodes``; returns ``(k,) bool`` visible.

        Boxes grow by a relative guard before float32 (see tolerance), and a
        node counts as visible when more than ``threshold`` samples pass
        (0: any sample, ties included, is visible).
        """
        if not len(nodes):
            return np.zeros(0, dtype=bool)
        b = self.boxes[nodes]
        far = np.abs(b).reshape(len(b), 6).max(axis=1)
        grow = (tol.box_grow_rel * (far + (b[:, MAX] - b[:, MIN]).max(axis=1))
                + tol.box_grow_scene * self.scene_size)
        if self.options.pixel_guard > 0.0:
            # Conservative: one query pixel measured at the box's farthest point
            # (sqrt(3) * max |coordinate| bounds the farthest corner's distance).
            px, perspective = self.pixel_world
            grow = grow + self.options.pixel_guard * px * (np.sqrt(3.0) * far if perspective else 1.0)
        grown = b + np.array([-1.0, 1.0])[None, :, None] * grow[:, None, None]
        t = time.perf_counter()
        samples = self.r.query(grown)
        self.t_query += time.perf_counter() - t
        r = self.rects[nodes]
        self.stats["queries"] += len(nodes)
        self.stats["multiple_queries"] += 1
        self.stats["samples_passed"] += int(samples.sum())
        self.stats["query_rect_pixels"] += int(((r[:, 2] - r[:, 0] + 1) * (r[:, 3] - r[:, 1] + 1)).sum())
        return samples > self.threshold

    def occlude(self, nodes):
        """Mark every unit below ``nodes`` OCCLUDED (those inside the frustum)."""
        leaves = self.h.leaves_below(nodes)
        leaves = leaves[self.in_frustum[leaves]]
        self.state[self.h.leaf_unit[leaves]] = Visibility.OCCLUDED

    def object_state(self):
        """Per object: the most visible state of its units, ``(n,) uint8``."""
        out = np.full(self.n_objects, Visibility.VIEW_CULLED, dtype=np.uint8)
        np.minimum.at(out, self.unit_object, self.state)
        return out

    def finish(self):
        t = time.perf_counter()
        self.r.finish()
        self.t_draw += time.perf_counter() - t
        total = time.perf_counter() - self.t0
        s = self.stats
        s["query_ms"] = 1e3 * self.t_query
        s["draw_ms"] = 1e3 * self.t_draw
        s["total_ms"] = 1e3 * total
        s["traversal_ms"] = max(0.0, s["total_ms"] - s["query_ms"] - s["draw_ms"])
        return s
