"""The binned surface-area heuristic (MacDonald & Booth; Wald's binning): one kernel
for every builder.  A builder bins its items' centres, unions each bin's boxes and
counts them; :func:`sweep` gives, for every split between two bins, the surface areas
and item counts of both sides, from which the builder's own cost follows (the
hierarchy above objects: ``S(L)|L| + S(R)|R|``; the subdivision of a mesh adds the
cost of a visit, see :mod:`core.subdivision`)."""

import numpy as np


def corner_area(lo, hi):
    """Surface area of boxes given as corner arrays ``(..., 3)``; inverted boxes give 0."""
    d = np.maximum(hi - lo, 0.0)
    return 2.0 * (d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0])


def _scan(ufunc, a):
    """``ufunc.accumulate(a, axis=0)``; for a short first axis of large slabs (the
    hierarchy's many segments), slab by slab, much faster; for small slabs (one mesh
    node's bins) one ``accumulate`` call, where a Python loop per bin would dominate."""
    if a[:1].size <= 256:
        return ufunc.accumulate(a, axis=0)
    out = a.copy()
    for i in range(1, len(out)):
        ufunc(out[i - 1], out[i], out=out[i])
    return out


def sweep(bmin, bmax, count):
    """Both sides of every split between bins.

    bmin, bmax: ``(B, ..., 3)`` union of each bin's boxes (empty bins: +inf / -inf);
    count: ``(B, ...)`` items per bin; bins on the first axis, anything after it is
    independent (axes, segments).  Split ``s`` (0 .. B-2) puts bins ``<= s`` left.
    Returns ``(left_area, left_count, right_area, right_count)``, each ``(B - 1, ...)``.
    """
    lmin, lmax = _scan(np.minimum, bmin[:-1]), _scan(np.maximum, bmax[:-1])
    rmin, rmax = _scan(np.minimum, bmin[:0:-1])[::-1], _scan(np.maximum, bmax[:0:-1])[::-1]
    left = np.cumsum(count[:-1], axis=0)
    return corner_area(lmin, lmax), left, corner_area(rmin, rmax), count.sum(axis=0) - left
