"""Big planar occluders tested in object space against a ball of eyes.

A convex polygon ``F`` hides a point ``x`` from every eye of the ball ``B(p, D)``
exactly when (1) the ball lies wholly on one side of ``F``'s plane and ``x``
strictly on the other, and (2) for every edge ``e`` of ``F``, the ball lies on the
polygon's side of the plane through ``x`` and ``e``, at least ``D`` from it.  (A
segment from an eye ``b`` to ``x`` crosses ``F``'s plane at a point on the same side
of that plane as ``b``, since ``x`` lies on it; inside ``F`` means on the polygon's
side of every edge.)  The points hidden from a convex ball by a convex polygon form
a convex set (an intersection of shadow cones), so a box is hidden when its eight
corners are.

This is what near occluders need: in image space (:mod:`core.envelope`) a wall a few
metres from the eye moves so far across the screen as the eye moves that no window of
its pixels holds the motion, though every eye of the ball sees the wall in front of
what stands behind it.  Each polygon proves on its own (no fusion); the envelope pass
hides what either proof hides.

Polygons come from the meshes (local space, once per mesh): coplanar triangle pairs
that form a convex quad (the faces of boxes, walls, slabs) and single triangles,
the largest :data:`PER_MESH` of each mesh.
"""

import numpy as np

from .bounds import MAX, MIN, corners
from .tolerance import tol

PER_MESH = 16          # polygons kept per mesh (its largest)
OBJECTS = 256          # objects whose polygons are tried per pass (largest on screen)
POLYGONS = 512         # polygons tried per pass (largest on screen)
PAIR_CHUNK = 20000     # box-polygon pairs per vectorised step
COPLANAR_COS = 1.0 - 1e-9   # two triangles' normals this close are one plane ...
COPLANAR_REL = 1e-9         # ... when the other's far vertex is this close to it (x mesh size)


def convex_polygons(vertices, faces, keep=PER_MESH):
    """The largest convex polygons of a mesh: ``(k, 4, 3) float64`` corners in order
    (a triangle repeats its last corner) and ``(k,)`` areas, largest first."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if not len(f) or not np.isfinite(v).all():
        return np.zeros((0, 4, 3)), np.zeros(0)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(n, axis=1)
    ok = area > 0.0
    unit = np.zeros_like(n)
    unit[ok] = n[ok] / (2.0 * area[ok, None])
    scale = float(np.abs(v).max(initial=0.0)) + float(np.ptp(v, axis=0).max(initial=0.0))
    # every edge with its triangle and the triangle's third corner
    t = len(f)
    idx = np.repeat(np.arange(t), 3)
    a = f[:, [0, 1, 2]].ravel()
    b = f[:, [1, 2, 0]].ravel()
    o = f[:, [2, 0, 1]].ravel()
    key = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    ks = key[order]
    same = np.all(ks[1:] == ks[:-1], axis=1)
    # an edge shared by exactly two triangles
    first = np.flatnonzero(same)
    lone = np.ones(len(first), dtype=bool)
    if len(first):
        lone &= ~np.concatenate([same[1:], [False]])[first]          # not a third triangle after
        lone &= ~np.concatenate([[False], same[:-1]])[first]         # nor one before
    first = first[lone]
    e1, e2 = order[first], order[first + 1]
    t1, t2 = idx[e1], idx[e2]
    cand = (t1 != t2) & ok[t1] & ok[t2]
    e1, e2, t1, t2 = e1[cand], e2[cand], t1[cand], t2[cand]
    coplanar = np.einsum("ij,ij->i", unit[t1], unit[t2]) > COPLANAR_COS
    off = np.abs(np.einsum("ij,ij->i", unit[t1], v[o[e2]] - v[a[e1]])) <= COPLANAR_REL * max(scale, tol.tiny)
    sel = coplanar & off
    e1, e2, t1, t2 = e1[sel], e2[sel], t1[sel], t2[sel]
    # the quad a, o2, b, o1 around the shared diagonal a-b is convex when the other
    # diagonal o1-o2 separates a and b
    qa, qb, q1, q2 = v[a[e1]], v[b[e1]], v[o[e1]], v[o[e2]]
    d = q2 - q1
    sa = np.einsum("ij,ij->i", np.cross(d, qa - q1), unit[t1])
    sb = np.einsum("ij,ij->i", np.cross(d, qb - q1), unit[t1])
    convex = (sa * sb) < 0.0
    e1, e2, t1, t2 = e1[convex], e2[convex], t1[convex], t2[convex]
    quads = np.stack([v[a[e1]], v[o[e2]], v[b[e1]], v[o[e1]]], axis=1)
    quad_area = area[t1] + area[t2]
    # greedy: largest quads first, each triangle in one polygon at most
    polys, areas = [], []
    used = np.zeros(t, dtype=bool)
    for i in np.argsort(-quad_area)[:4 * keep]:
        if used[t1[i]] or used[t2[i]]:
            continue
        used[t1[i]] = used[t2[i]] = True
        polys.append(quads[i])
        areas.append(quad_area[i])
    free = np.flatnonzero(ok & ~used)
    for i in free[np.argsort(-area[free])][:keep]:
        polys.append(tri[i][[0, 1, 2, 2]])
        areas.append(area[i])
    if not polys:
        return np.zeros((0, 4, 3)), np.zeros(0)
    areas = np.asarray(areas)
    best = np.argsort(-areas)[:keep]
    return np.asarray(polys)[best], areas[best]


def _tangent_rects(points, rot):
    """Per point set ``(k, c, 3)`` (camera-relative), the rectangle of ``x/z, y/z`` in
    the view ``rot`` and whether every point lies in front of the eye."""
    v = points @ rot.T
    z = -v[..., 2]
    front = (z > 0.0).all(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = v[..., :2] / np.where(z > 0.0, z, 1.0)[..., None]
    return np.concatenate([t.min(axis=1), t.max(axis=1)], axis=1), front


def hidden_by_polygons(boxes, polys, distance, rot=None, near_eff=0.0):
    """``(m,) bool``: boxes (camera-relative, ``(m, 2, 3)``) hidden from every eye
    within ``distance`` of the origin by at least one of the convex polygons
    ``(k, 4, 3)`` (camera-relative; see the module doc).  ``rot``: the view's rotation,
    to pair a box only with polygons whose picture from the centre eye holds its
    picture (necessary: the centre eye is one of the eyes).  ``near_eff``: a polygon
    whose plane passes nearer the centre eye than this occludes nothing (an eye's near
    plane may cut it)."""
    m, k = len(boxes), len(polys)
    out = np.zeros(m, dtype=bool)
    if not m or not k:
        return out
    e0 = polys
    e1 = np.roll(polys, -1, axis=1)
    n = np.cross(polys[:, 1] - polys[:, 0], polys[:, 2] - polys[:, 0])
    n2 = np.cross(polys[:, 2] - polys[:, 0], polys[:, 3] - polys[:, 0])
    n = np.where((np.linalg.norm(n, axis=1) >= np.linalg.norm(n2, axis=1))[:, None], n, n2)
    nn = np.linalg.norm(n, axis=1)
    good = nn > 0.0
    n = n / np.where(good, nn, 1.0)[:, None]
    h = np.einsum("kj,kj->k", n, polys[:, 0])
    n = np.where((h < 0.0)[:, None], -n, n)                   # the normal points away from the eye
    h = np.abs(h)
    mag = np.abs(polys).max(axis=(1, 2))
    margin = distance * (1.0 + tol.near_guard_rel) + tol.box_grow_rel * mag
    good &= h > margin                                        # the whole ball on the near side
    good &= h > near_eff                                      # and no eye's near plane cuts it
    centre = polys.mean(axis=1)
    # box beyond the plane: its nearest corner along n is farther than the plane
    lo = boxes[:, MIN] @ np.maximum(n, 0.0).T + boxes[:, MAX] @ np.minimum(n, 0.0).T
    beyond = (lo > (h + tol.box_grow_rel * mag)[None]) & good[None]
    cs = corners(boxes)                                        # (m, 8, 3)
    if rot is not None:
        br, bf = _tangent_rects(cs, rot)
        pr, pf = _tangent_rects(polys, rot)
        inside = (br[:, None, 0] >= pr[None, :, 0]) & (br[:, None, 1] >= pr[None, :, 1]) & \
                 (br[:, None, 2] <= pr[None, :, 2]) & (br[:, None, 3] <= pr[None, :, 3])
        beyond &= inside | ~bf[:, None] | ~pf[None, :]
    # polygon-major: the polygons come largest first (convex_polygons), so most boxes are
    # proved hidden by the first ones and their later pairs are skipped (the answer is an
    # OR over pairs: the order changes only the work)
    pi, bi = np.nonzero(beyond.T)
    if not len(bi):
        return out
    s = 0
    while s < len(bi):
        open_ = np.flatnonzero(~out[bi[s:]])[:PAIR_CHUNK] + s     # the next pairs of boxes not yet hidden
        if not len(open_):
            break
        s = int(open_[-1]) + 1
        b, p = bi[open_], pi[open_]
        # per pair: the box's corners x (q, 8, 1) against the polygon's edges a0 -> a1
        # (q, 1, 4), component by component (np.cross's own arithmetic, without its copies)
        xb, a0p, a1p = cs[b], e0[p], e1[p]                    # each gathered once
        x = [xb[:, :, None, j] for j in range(3)]
        a0 = [a0p[:, None, :, j] for j in range(3)]
        ed = [a1p[:, None, :, j] - a0[j] for j in range(3)]
        dx = [x[j] - a0[j] for j in range(3)]
        # the normal of the plane through x and the edge: edge x (x - a0)
        m = [ed[1] * dx[2] - ed[2] * dx[1], ed[2] * dx[0] - ed[0] * dx[2], ed[0] * dx[1] - ed[1] * dx[0]]
        mlen = np.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
        c = centre[p][:, None, None, :]
        side = sum(m[j] * (c[..., j] - a0[j]) for j in range(3))
        eye = -sum(m[j] * a0[j] for j in range(3))            # the eye (origin) against that plane
        degenerate = (ed[0] == 0.0) & (ed[1] == 0.0) & (ed[2] == 0.0)   # a triangle's repeated corner
        with np.errstate(invalid="ignore", divide="ignore"):
            dist = np.where(side > 0.0, eye, -eye) / mlen
        okp = degenerate | ((mlen > 0.0) & (side != 0.0) & (dist >= margin[p][:, None, None]))
        hid = okp.all(axis=(1, 2))
        np.logical_or.at(out, b[hid], True)
    return out
