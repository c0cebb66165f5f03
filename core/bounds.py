"""Axis-aligned boxes as arrays: ``(n, 2, 3) float64``, row ``MIN`` then row ``MAX``.

Every function works on all boxes at once; none loops over boxes in Python.
"""

import numpy as np

from .errors import OccError
from .sah import corner_area

MIN, MAX = 0, 1

# The 8 corners of a box as (corner, axis) choices of MIN/MAX, in bit order
# x = bit 0, y = bit 1, z = bit 2.
CORNER_SELECT = np.array([[(c >> a) & 1 for a in range(3)] for c in range(8)], dtype=np.intp)

# The 12 edges of a box as pairs of corner indices (in that bit order).
BOX_EDGES = np.array([(c, c | b) for c in range(8) for b in (1, 2, 4) if not c & b], dtype=np.intp)

# The 6 faces of a box as corner quads, counter-clockwise seen from outside: the
# projected outline's area is the sum of the front faces'.
BOX_FACES = np.array([[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]])


def check_boxes(boxes, name="bounds"):
    """Return ``boxes`` as ``(n, 2, 3) float64``; raise :class:`OccError` otherwise."""
    b = np.asarray(boxes, dtype=np.float64)
    if b.ndim != 3 or b.shape[1:] != (2, 3):
        raise OccError(f"{name} must be (n, 2, 3), got {b.shape}")
    return b


def corners(boxes):
    """The 8 corners of every box: ``(n, 2, 3)`` -> ``(n, 8, 3) float64``."""
    b = check_boxes(boxes)
    axes = np.arange(3)
    return b[:, CORNER_SELECT, axes]


def transform_boxes(boxes, matrices):
    """World boxes of local boxes moved by ``matrices``.

    boxes: ``(n, 2, 3)`` local boxes; matrices: ``(n, 4, 4)`` (column vectors,
    ``world = M @ [x, y, z, 1]``).  Exact for affine matrices (Arvo's method:
    each output extent is the sum of ``|M_ij|`` times input half extents).
    """
    b = check_boxes(boxes)
    m = np.asarray(matrices, dtype=np.float64)
    if m.shape != (len(b), 4, 4):
        raise OccError(f"matrices must be ({len(b)}, 4, 4), got {m.shape}")
    centre = 0.5 * (b[:, MIN] + b[:, MAX])
    half = 0.5 * (b[:, MAX] - b[:, MIN])
    rot = m[:, :3, :3]
    c = np.einsum("nij,nj->ni", rot, centre) + m[:, :3, 3]
    h = np.einsum("nij,nj->ni", np.abs(rot), half)
    return np.stack([c - h, c + h], axis=1)


def union(boxes):
    """One box around all ``(n, 2, 3)`` boxes -> ``(2, 3)``; n must be > 0."""
    b = check_boxes(boxes)
    if len(b) == 0:
        raise OccError("union of no boxes is undefined")
    return np.stack([b[:, MIN].min(axis=0), b[:, MAX].max(axis=0)])


def segment_union(boxes, starts, counts):
    """Union of consecutive runs of boxes: run i is ``boxes[starts[i]:starts[i]+counts[i]]``.

    Every count must be > 0.  Returns ``(k, 2, 3)``.
    """
    b = check_boxes(boxes)
    starts = np.asarray(starts, dtype=np.intp)
    counts = np.asarray(counts, dtype=np.intp)
    if not len(starts):
        return np.zeros((0, 2, 3))
    # reduceat over [start, end) pairs; a dummy last row keeps every end in range
    padded = np.concatenate([b, b[:1]])
    edges = np.column_stack([starts, starts + counts]).ravel()
    lo = np.minimum.reduceat(padded[:, MIN], edges, axis=0)[::2]
    hi = np.maximum.reduceat(padded[:, MAX], edges, axis=0)[::2]
    return np.stack([lo, hi], axis=1)


def surface_area(boxes):
    """Surface area of each box, ``(n, 2, 3)`` -> ``(n,)``; empty (inverted) boxes give 0."""
    b = check_boxes(boxes)
    return corner_area(b[:, MIN], b[:, MAX])


def contains(outer, inner, atol=0.0):
    """Whether each box of ``inner`` lies inside the matching box of ``outer`` -> ``(n,) bool``."""
    o = check_boxes(outer)
    i = check_boxes(inner)
    return np.all(o[:, MIN] <= i[:, MIN] + atol, axis=1) & np.all(i[:, MAX] <= o[:, MAX] + atol, axis=1)
