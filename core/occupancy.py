"""Screen rectangles of boxes and the occupancy map of Staneker et al. (2003).

The occupancy map is a small bitfield over the screen -- by default 512 words
of 32 bits, i.e. 16,384 tiles, laid out to the viewport's aspect -- holding
which tiles something was already drawn over.  A node whose rectangle still
has an empty tile would almost surely answer "visible" to a query, so the
query is skipped.  The map only ever decides whether to *ask*; no object is
culled on its word, so it cannot make the culling wrong, only slower.

Pixel convention: pixel ``(i, j)`` has its centre at ``(i + 0.5, j + 0.5)`` in
window coordinates, row 0 at the bottom.  Rectangles are inclusive index ranges
``(x0, y0, x1, y1)`` rounded outward: every pixel centre the box's projection
could cover is inside.
"""

import math

import numpy as np

from .bounds import BOX_EDGES, corners
from .frustum import planes_from_matrix
from .tolerance import tol

X0, Y0, X1, Y1 = range(4)
DEFAULT_TILES = 512 * 32
SMALL_SET = 24         # rectangles set one by one below this count (measured: ~1 us each vs ~60 us a grid pass)


def project_rects(boxes, clip_matrix, width, height, near=None):
    """Pixel rectangles of boxes, rounded outward.

    boxes: ``(n, 2, 3)`` in the space ``clip_matrix`` maps to clip space
    (camera-relative for the engine).  Returns ``(rects (n, 4) int64,
    crosses_near (n,) bool)``.  A box within the near guard of the near plane
    (or containing the eye) has ``crosses_near = True``: it is visible without a
    query (conservative rule).  Its rectangle is that of the box clipped at the
    near plane (the corners in front of it and the points where its edges cross
    it), as the rasteriser clips it, not the whole screen.  near: the near plane
    ``(4,)`` of ``clip_matrix`` when the caller has it (see frustum.planes_from_matrix).
    """
    c = corners(boxes)                                               # (n, 8, 3)
    n = len(c)
    near = planes_from_matrix(clip_matrix)[4] if near is None else near
    scale = np.abs(c).reshape(n, 24).max(axis=1, initial=0.0) + tol.tiny
    dist = c @ near[:3] + near[3]                                    # (n, 8)
    # Conservative: a corner at or in front of the near plane (within a guard
    # relative to the box's magnitude) means the box reaches the eye's side.
    crosses = np.any(dist <= tol.near_guard_rel * scale[:, None], axis=1)
    pts, keep = c, np.ones((n, 8), dtype=bool)
    if crosses.any():
        # Clip the crossing boxes at the near plane: corners in front, plus the
        # crossing point of every edge whose ends lie on both sides.
        k = np.flatnonzero(crosses)
        ck, dk = c[k], dist[k]
        da, db = dk[:, BOX_EDGES[:, 0]], dk[:, BOX_EDGES[:, 1]]          # (m, 12)
        cut = (da > 0.0) != (db > 0.0)
        t = np.where(cut, da / np.where(cut, da - db, 1.0), 0.0)
        on_plane = ck[:, BOX_EDGES[:, 0]] + t[..., None] * (ck[:, BOX_EDGES[:, 1]] - ck[:, BOX_EDGES[:, 0]])
        pts = np.concatenate([c, np.zeros((n, 12, 3))], axis=1)
        keep = np.concatenate([np.ones((n, 8), dtype=bool), np.zeros((n, 12), dtype=bool)], axis=1)
        pts[k, 8:] = on_plane
        keep[k, :8] = dk > 0.0
        keep[k, 8:] = cut
    clip = pts @ clip_matrix[:3, :3].T + clip_matrix[:3, 3]          # x, y, z
    w = pts @ clip_matrix[3, :3] + clip_matrix[3, 3]
    # Points kept lie on or in front of the near plane, where w >= near > 0 (or
    # w = 1, orthographic); the floor only guards rounding on the plane itself.
    w = np.where(keep, np.maximum(w, tol.tiny), 1.0)
    px = (clip[..., 0] / w + 1.0) * (0.5 * width)
    py = (clip[..., 1] / w + 1.0) * (0.5 * height)
    big = np.float64(4.0 * (width + height) + 16.0)                 # off screen, never overflows int64
    px, py = np.clip(px, -big, big), np.clip(py, -big, big)
    lo_x = np.where(keep, px, np.inf).min(axis=1)
    hi_x = np.where(keep, px, -np.inf).max(axis=1)
    lo_y = np.where(keep, py, np.inf).min(axis=1)
    hi_y = np.where(keep, py, -np.inf).max(axis=1)
    # A box with no point in front of the plane (only within the guard): whole screen.
    none = ~keep.any(axis=1)
    lo_x[none], lo_y[none], hi_x[none], hi_y[none] = -big, -big, big, big
    rects = np.empty((n, 4), dtype=np.int64)
    # Outward: a centre i + 0.5 in [min, max] gives i in [floor(min - .5), ceil(max - .5)].
    rects[:, X0] = np.floor(lo_x - 0.5)
    rects[:, Y0] = np.floor(lo_y - 0.5)
    rects[:, X1] = np.ceil(hi_x - 0.5)
    rects[:, Y1] = np.ceil(hi_y - 0.5)
    rects[:, X0] = np.clip(rects[:, X0], 0, width - 1)
    rects[:, X1] = np.clip(rects[:, X1], 0, width - 1)
    rects[:, Y0] = np.clip(rects[:, Y0], 0, height - 1)
    rects[:, Y1] = np.clip(rects[:, Y1], 0, height - 1)
    return rects, crosses


def tile_grid(width, height, tiles=DEFAULT_TILES):
    """Tile columns and rows for a ``width x height`` viewport: about ``tiles`` tiles
    shaped to the aspect, never smaller than a pixel."""
    if width <= 0 or height <= 0:
        raise ValueError(f"viewport must be at least 1x1, got {width}x{height}")
    aspect = width / height
    ty = max(1, min(height, int(math.floor(math.sqrt(tiles / aspect)))))
    tx = max(1, min(width, int(tiles // ty)))
    return tx, ty


class OccupancyMap:
    """A ``rows x cols`` bitfield of screen tiles over a ``width x height`` viewport.

    All operations take ``(n, 4)`` pixel rectangles and work on all of them at
    once (a 2-D difference array to set, a summed-area table to test).
    """

    def __init__(self, width, height, tiles=DEFAULT_TILES):
        self.width, self.height = int(width), int(height)
        self.cols, self.rows = tile_grid(self.width, self.height, tiles)
        self.grid = np.zeros((self.rows, self.cols), dtype=bool)
        self._sat = None

    def tile_rects(self, rects):
        """Pixel rectangles ``(n, 4)`` -> inclusive tile rectangles ``(n, 4)``."""
        r = np.asarray(rects, dtype=np.int64).reshape(-1, 4)
        t = np.empty_like(r)
        t[:, [X0, X1]] = r[:, [X0, X1]] * self.cols // self.width
        t[:, [Y0, Y1]] = r[:, [Y0, Y1]] * self.rows // self.height
        return t

    def clear(self):
        self.grid[:] = False
        self._sat = None

    def set(self, rects):
        """Mark the tiles under every pixel rectangle ``(n, 4)``."""
        self.set_tiles(self.tile_rects(rects))

    def set_tiles(self, t):
        """Mark every inclusive tile rectangle ``(n, 4)``."""
        if not len(t):
            return
        if len(t) <= SMALL_SET:             # a few slice writes beat two passes over the grid
            for x0, y0, x1, y1 in t.tolist():
                self.grid[y0:y1 + 1, x0:x1 + 1] = True
            self._sat = None
            return
        d = np.zeros((self.rows + 1, self.cols + 1), dtype=np.int32)
        np.add.at(d, (t[:, Y0], t[:, X0]), 1)
        np.add.at(d, (t[:, Y0], t[:, X1] + 1), -1)
        np.add.at(d, (t[:, Y1] + 1, t[:, X0]), -1)
        np.add.at(d, (t[:, Y1] + 1, t[:, X1] + 1), 1)
        self.grid |= np.cumsum(np.cumsum(d, axis=0), axis=1)[:-1, :-1] > 0
        self._sat = None

    def _counts(self, rects):
        return self._tile_counts(self.tile_rects(rects))

    def _tile_counts(self, t):
        if self._sat is None:
            s = np.zeros((self.rows + 1, self.cols + 1), dtype=np.int32)
            s[1:, 1:] = np.cumsum(np.cumsum(self.grid, axis=0, dtype=np.int32), axis=1)
            self._sat = s
        s = self._sat
        count = (s[t[:, Y1] + 1, t[:, X1] + 1] - s[t[:, Y0], t[:, X1] + 1]
                 - s[t[:, Y1] + 1, t[:, X0]] + s[t[:, Y0], t[:, X0]])
        area = (t[:, X1] - t[:, X0] + 1) * (t[:, Y1] - t[:, Y0] + 1)
        return count, area

    def any_empty(self, rects):
        """``(n,) bool``: the rectangle has at least one unset tile."""
        return self.any_empty_tiles(self.tile_rects(rects))

    def any_empty_tiles(self, t):
        """``(n,) bool``: the tile rectangle ``(n, 4)`` has at least one unset tile."""
        count, area = self._tile_counts(t)
        return count < area

    def all_covered(self, rects):
        """``(n,) bool``: every tile of the rectangle is set."""
        count, area = self._counts(rects)
        return count == area

    def any_set(self, rects):
        """``(n,) bool``: at least one tile of the rectangle is set."""
        return self._counts(rects)[0] > 0

    def words(self):
        """The bitfield as the paper stores it: ``uint32`` words, row-major, bit 0 first."""
        bits = np.packbits(self.grid.ravel(), bitorder="little")
        pad = (-len(bits)) % 4
        return np.concatenate([bits, np.zeros(pad, np.uint8)]).view("<u4")

    def picture(self, scale=4):
        """A debug image ``(rows * scale, cols * scale) uint8``, top row first, 255 = set."""
        img = np.where(self.grid[::-1], 255, 40).astype(np.uint8)
        return np.kron(img, np.ones((scale, scale), dtype=np.uint8))


def free_tile_first(tile_rects, rows, cols):
    """The papers' arrangement of one multiple query (Staneker et al. 2004): in
    order, a rectangle joins the list when at least one of its tiles is still
    free in the list's own occupancy map (cleared per list), and then sets its
    tiles there.  Returns ``(k,) bool`` of the rectangles taken.

    Exact without a sequential scan: the first rectangle (in order) to cover a
    tile always finds it free, so it is taken; a later one finds each of its
    tiles set by that first coverer.  So rectangle i is taken exactly when it is
    the first to cover some tile.  Painting in reverse order leaves each tile
    with its first coverer.
    """
    t = np.asarray(tile_rects)
    k = len(t)
    if k == 0:
        return np.zeros(0, dtype=bool)
    first = np.full((rows, cols), k, dtype=np.int64)
    for i in range(k - 1, -1, -1):          # k <= a few hundred slice writes, no per-tile loop
        first[t[i, Y0]:t[i, Y1] + 1, t[i, X0]:t[i, X1] + 1] = i
    taken = np.zeros(k + 1, dtype=bool)
    taken[first.ravel()] = True
    return taken[:k]
