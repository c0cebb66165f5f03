"""View-frustum planes and the p/n-vertex box test, vectorised over all boxes.

Planes come from the clip matrix by Gribb & Hartmann (2001): with rows
``r0..r3`` of ``M``, a point ``x`` is inside when ``(r3 ± ri) . [x, 1] >= 0``.
Plane order: left, right, bottom, top, near, far (bit ``k`` of a mask = plane ``k``).

Conservative rule: a box is rejected only when its p-vertex (the corner farthest
along the plane normal) is outside one plane by more than a relative tolerance;
a box exactly on a plane is kept.
"""

import numpy as np

from .bounds import MAX, MIN
from .tolerance import tol

ALL_PLANES = np.uint8(0b111111)


def planes_from_matrix(m):
    """Six normalised planes ``(6, 4) float64`` ``(a, b, c, d)`` of clip matrix ``m``."""
    m = np.asarray(m, dtype=np.float64)
    r = m
    planes = np.array([r[3] + r[0], r[3] - r[0], r[3] + r[1], r[3] - r[1], r[3] + r[2], r[3] - r[2]])
    norms = np.linalg.norm(planes[:, :3], axis=1)
    # A zero normal only arises from a degenerate matrix; leave that plane
    # unable to reject anything (normal 0, d = +1).
    ok = norms > 0.0
    planes[ok] /= norms[ok, None]
    planes[~ok] = (0.0, 0.0, 0.0, 1.0)
    return planes


PLANE_BITS = (np.uint8(1) << np.arange(6, dtype=np.uint8))[None]


def classify(planes, boxes, masks=None):
    """Test boxes against the planes selected by ``masks``.

    planes: ``(6, 4)``; boxes: ``(n, 2, 3)`` in the planes' space; masks: ``(n,)
    uint8`` of planes still to test (default all).  Returns ``(outside (n,) bool,
    remaining (n,) uint8)``: ``remaining`` drops the planes a box is fully inside,
    so its children need not test them again (plane masking).  The p- and n-vertex
    distances are two small matrix products (``max(n, 0) . MAX + min(n, 0) . MIN``)
    instead of gathered corners: the thousands of nodes a pass reaches cost little.
    """
    b = boxes
    n = len(b)
    normal = planes[:, :3]
    pos, neg = np.maximum(normal, 0.0).T, np.minimum(normal, 0.0).T          # (3, 6)
    lo, hi = b[:, MIN], b[:, MAX]
    dp = hi @ pos + lo @ neg + planes[:, 3]                                   # p-vertex distances
    dn = lo @ pos + hi @ neg + planes[:, 3]                                   # n-vertex distances
    scale = np.abs(b).reshape(n, 6).max(axis=1, initial=0.0)[:, None] + np.abs(planes[:, 3])
    if masks is None:
        masks = np.full(n, ALL_PLANES, dtype=np.uint8)
    active = (masks[:, None] & PLANE_BITS) != 0
    outside = np.any(active & (dp < -tol.plane_rel * scale), axis=1)
    inside_bits = np.bitwise_or.reduce(np.where(active & (dn >= 0.0), PLANE_BITS, 0), axis=1)
    return outside, (masks & ~inside_bits.astype(np.uint8)).astype(np.uint8)
