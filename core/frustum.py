"""View-frustum planes and the p/n-vertex box test, vectorised over all boxes.

Planes come from the clip matrix by Gribb & Hartmann (2001): with rows
``r0..r3`` of ``M``, a point ``x`` is inside when ``(r3 ± ri) . [x, 1] >= 0``.
Plane order: left, right, bottom, top, near, far (bit ``k`` of a mask = plane ``k``).

Conservative rule: a box is rejected only when its p-vertex (the corner farthest
along the plane normal) is outside one plane by more than a relative tolerance;
a box exactly on a plane is kept.
"""

import numpy as np

from .bounds import MAX, MIN, check_boxes
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


def classify(planes, boxes, masks=None):
    """Test boxes against the planes selected by ``masks``.

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
    from .bounds import corners
    c = corners(boxes)                                          # (n, 8, 3)
    d = np.einsum("nck,pk->ncp", c, planes[:, :3]) + planes[:, 3]
    return np.any(np.all(d < 0.0, axis=1), axis=1)
