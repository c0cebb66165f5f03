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


# numpy 1.25+ runs ``ufunc.at`` on a fast path (here 3 ns an item against 130 on 1.24,
# which Debian's Blender 3.4 uses); without it a sort and ``reduceat`` are faster
FAST_AT = tuple(int(x) for x in np.__version__.split(".")[:2]) >= (1, 25)


def bin_unions(key, lo, hi, bmin, bmax):
    """Union the boxes ``lo``, ``hi`` ``(3, m)`` into their bins' ``bmin``, ``bmax``
    ``(3, bins)`` (in place: ``+inf`` / ``-inf`` for a bin not met yet); ``key``
    ``(m,)`` the bin of each box."""
    if FAST_AT:
        for d in range(3):
            np.minimum.at(bmin[d], key, lo[d])
            np.maximum.at(bmax[d], key, hi[d])
        return
    order = np.argsort(key, kind="stable")
    ks = key[order]
    run = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    at = ks[run]
    bmin[:, at] = np.minimum(bmin[:, at], np.minimum.reduceat(lo[:, order], run, axis=1))
    bmax[:, at] = np.maximum(bmax[:, at], np.maximum.reduceat(hi[:, order], run, axis=1))


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
