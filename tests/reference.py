"""Reference implementations the tests hold the engine's fast ones against: written
for clarity, not speed, and never shipped."""

import numpy as np

from core.bounds import MAX, MIN, check_boxes, corners, surface_area
from core.frustum import ALL_PLANES
from core.hierarchy import SAH_BINS
from core.occupancy import X0, X1, Y0, Y1
from core.tolerance import tol


def classify_gathered(planes, boxes, masks=None):
    """:func:`core.frustum.classify` as first written: gathered p- and n-vertices.

    planes: ``(6, 4)``; boxes: ``(n, 2, 3)`` in the planes' space; masks: ``(n,)
    uint8`` of planes still to test (default all).  Returns ``(outside (n,) bool,
    remaining (n,) uint8)``: ``remaining`` drops the planes a box is fully inside,
    so its children need not test them again (plane masking).
    """
    b = check_boxes(boxes)
    n = len(b)
    if masks is None:
        masks = np.full(n, ALL_PLANES, dtype=np.uint8)
    normal = planes[:, :3]
    positive = normal >= 0.0                                    # (6, 3)
    # p-vertex: per plane, MAX where the normal is positive, else MIN.
    p = np.where(positive[None], b[:, None, MAX], b[:, None, MIN])    # (n, 6, 3)
    q = np.where(positive[None], b[:, None, MIN], b[:, None, MAX])    # n-vertex
    dp = np.einsum("npk,pk->np", p, normal) + planes[:, 3]
    dn = np.einsum("npk,pk->np", q, normal) + planes[:, 3]
    scale = np.abs(b).reshape(n, 6).max(axis=1, initial=0.0)[:, None] + np.abs(planes[:, 3])
    bits = (np.uint8(1) << np.arange(6, dtype=np.uint8))[None]
    active = (masks[:, None] & bits) != 0
    outside = np.any(active & (dp < -tol.plane_rel * scale), axis=1)
    inside_bits = np.bitwise_or.reduce(np.where(active & (dn >= 0.0), bits, 0), axis=1)
    return outside, (masks & ~inside_bits.astype(np.uint8)).astype(np.uint8)


def corners_outside_brute(planes, boxes):
    """Reference test: a box is outside when all 8 corners are outside one plane."""
    c = corners(boxes)                                          # (n, 8, 3)
    d = np.einsum("nck,pk->ncp", c, planes[:, :3]) + planes[:, 3]
    return np.any(np.all(d < 0.0, axis=1), axis=1)


def non_overlapping_first(tile_rects):
    """The stricter arrangement this project used first: in order, take a rectangle
    when it overlaps no rectangle taken before it.  Kept for comparison; the test
    lists use :func:`free_tile_first`, the papers' rule.  Returns ``(k,) bool``.
    """
    t = np.asarray(tile_rects)
    k = len(t)
    if k == 0:
        return np.zeros(0, dtype=bool)
    ov = ((t[:, None, X0] <= t[None, :, X1]) & (t[None, :, X0] <= t[:, None, X1])
          & (t[:, None, Y0] <= t[None, :, Y1]) & (t[None, :, Y0] <= t[:, None, Y1]))
    ov &= np.tri(k, k, -1, dtype=bool)       # ov[i, j]: j comes before i and overlaps it
    taken = np.zeros(k, dtype=bool)
    dropped = np.zeros(k, dtype=bool)
    while True:
        undecided = ~(taken | dropped)
        if not undecided.any():
            return taken
        # taken: every earlier overlapping rectangle is dropped
        new_taken = undecided & ~np.any(ov & ~dropped[None], axis=1)
        new_dropped = undecided & np.any(ov & (taken | new_taken)[None], axis=1) & ~new_taken
        taken |= new_taken
        dropped |= new_dropped


def sah_split(boxes):
    """Best binned-SAH partition of items with boxes ``(k, 2, 3)``, k >= 2.

    Returns a ``(k,) bool`` mask of the left side, never all-True or all-False.
    The rule for one group, written plainly; the builder's vectorised
    :func:`core.hierarchy._split_segments` must choose the same.
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
