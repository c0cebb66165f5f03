"""Big planar occluders tested in object space against a ball of eyes.

A convex polygon ``F`` hides a point ``x`` from every eye of the ball ``B(p, D)``
exactly when (1) the ball lies wholly on one side of ``F``'s plane and ``x``
strictly on the other, and (2) for every edge ``e`` of ``F``, the ball lies on the
polygon's side of the plane through ``x`` and ``e``, at least ``D`` from it.  (A
segment from an eye ``b`` to ``x`` crosses ``F``'s plane at a point on the same side
of that plane as ``b``, since ``x`` lies on it; inside ``F`` means on the polygon's
side of every edge.)  Condition (2) is a half-space per edge: the planes through an
edge form a pencil, and the one through ``x`` leaves the ball on the polygon's side,
at least ``D`` away, exactly when ``x`` lies on the ball's side of the pencil's plane
tangent to the ball that has the polygon on that side too.  So the points hidden from
the ball form a convex set, the polygon's plane and one tangent plane per edge
(:func:`umbra_planes`), and a box is hidden when its corner nearest each of those
planes is inside it: one dot product per box and plane.

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

from .bounds import MAX, MIN
from .tolerance import tol

PER_MESH = 16          # polygons kept per mesh (its largest)
OBJECTS = 512          # objects whose polygons are tried per pass (highest scores: occluder_polygons)
POLYGONS = 512         # polygons tried per pass (heaviest: polygon_weights)
BOX_CHUNK = 256        # boxes per matrix product (x 5 planes x POLYGONS doubles)
GROUP = 64             # near boxes whose bounding box is tested first (hidden_by_polygons)
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


def width_factor(width, distance):
    """How much of a polygon's solid angle its umbra keeps from a ball of radius
    ``distance``: ``min(1, width / 2 distance)^2``.  A polygon narrower than the ball
    hides a point only within a short reach behind it (its umbra closes at about
    ``r width / (2 distance - width)``, ``r`` its distance), a wider one along every ray
    beyond it."""
    w = np.asarray(width, dtype=np.float64)
    if distance <= 0.0:
        return np.ones_like(w)
    return np.minimum(w / (2.0 * distance), 1.0) ** 2


def polygon_weights(polys, distance):
    """How much each convex polygon ``(k, 4, 3)`` (camera-relative) may hide from the ball
    of radius ``distance`` around the origin, to pick the few a pass tries: its solid
    angle (area times the cosine of its normal to the eye, over the squared distance)
    times :func:`width_factor` of its narrow width (the longer of each pair of opposite
    sides, the shorter of the two).  On the city at 8 units, from two of its path's frames,
    the 512 heaviest by this hide 3.6x and 1.5x the boxes that the 512 largest by area
    over squared distance hide (grazing faces and small near faces hide little)."""
    p = np.asarray(polys, dtype=np.float64)
    centre = p.mean(axis=1)
    r2 = np.maximum(np.einsum("kj,kj->k", centre, centre), tol.tiny)
    d02, d13 = p[:, 2] - p[:, 0], p[:, 3] - p[:, 1]
    n = np.stack([d02[:, 1] * d13[:, 2] - d02[:, 2] * d13[:, 1],
                  d02[:, 2] * d13[:, 0] - d02[:, 0] * d13[:, 2],
                  d02[:, 0] * d13[:, 1] - d02[:, 1] * d13[:, 0]], axis=1)   # twice the area, normal
    projected = 0.5 * np.abs(np.einsum("kj,kj->k", n, centre)) / (r2 * np.sqrt(r2))
    side = np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2)                # edges 01, 12, 23, 30
    width = np.minimum(np.maximum(side[:, 0], side[:, 2]), np.maximum(side[:, 1], side[:, 3]))
    return projected * width_factor(width, distance)


def cap_support(d, radius, cut):
    """``(m,)`` the support function ``max x . d`` of the eyes ``E = B(0, radius) ∩ {f . x
    >= s}`` (``cut = (f, s)``, ``f`` a unit vector) for unit rows ``d`` ``(m, 3)``: the
    ball's ``radius`` where its own farthest point ``radius d`` is an eye of ``E``, else the
    farthest point of the rim circle where the cut plane meets the sphere (the linear
    maximum over a convex set lies on its boundary, and on the sphere's part of it only
    at ``radius d`` or on the rim)."""
    f, s = cut
    fd = d @ f
    rim = s * fd + np.sqrt(np.maximum(radius * radius - s * s, 0.0)) * np.sqrt(np.maximum(1.0 - fd * fd, 0.0))
    return np.where(radius * fd >= s, radius, rim)


def facing_planes(polys):
    """The planes of convex polygons ``(k, 4, 3)`` (camera-relative, a triangle repeating
    its last corner): ``(normals, distances, good)``, unit normals pointing away from the
    eye at the origin, the plane at ``normals . x = distances >= 0``; ``good``: the
    polygon has an area (the larger of its two corner triangles' normals is taken)."""
    n = np.cross(polys[:, 1] - polys[:, 0], polys[:, 2] - polys[:, 0])
    n2 = np.cross(polys[:, 2] - polys[:, 0], polys[:, 3] - polys[:, 0])
    n = np.where((np.linalg.norm(n, axis=1) >= np.linalg.norm(n2, axis=1))[:, None], n, n2)
    nn = np.linalg.norm(n, axis=1)
    good = nn > 0.0
    n = n / np.where(good, nn, 1.0)[:, None]
    h = np.einsum("kj,kj->k", n, polys[:, 0])
    n = np.where((h < 0.0)[:, None], -n, n)                   # the normal points away from the eye
    return n, np.abs(h), good


def umbra_planes(polys, radius, near_eff=0.0, cut=None):
    """The umbra of each convex polygon ``(k, 4, 3)`` (camera-relative, a triangle
    repeating its last corner) from the ball ``B(0, radius)``, as five half-spaces
    ``normals @ x >= offsets`` (``(k, 5, 3)``, ``(k, 5)``): the polygon's plane (row 0:
    ``x`` beyond it) and, per edge, the plane through the edge tangent to the ball with the
    ball and the polygon on its positive side.  A point is hidden from every eye of the
    ball exactly when it lies in all five (module doc: the plane through ``x`` and an edge
    leaves the ball on the polygon's side exactly when ``x`` lies on the ball's side of that
    edge's tangent plane, given ``x`` beyond the polygon).  A repeated corner's edge is
    always true (a zero row, offset ``-inf``); a polygon that cannot hide (degenerate, its
    plane within ``radius`` of the eye or nearer than ``near_eff``) is never true (offset
    ``+inf`` in row 0).  ``radius`` is ``(k,)`` or a number.

    ``cut = (f, s)``: the eyes are only the ball's points with ``f . x >= s`` (a unit
    ``f``; an envelope kept above a floor, :attr:`core.envelope.Envelope.floor`).  Each
    edge's plane then turns from the ball's tangent towards the plane through the eye and
    the edge, as far as the cut eyes stay on its positive side (:func:`cap_support`,
    bisected; the plane kept is always one they are on the positive side of, so the
    umbra is the cut eyes' own or a little smaller).  The polygon's own plane keeps the
    whole ball's test."""
    k = len(polys)
    radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (k,))
    if cut is not None and k:
        f, level = np.asarray(cut[0], dtype=np.float64), float(cut[1])
        level -= tol.near_guard_rel * float(radius.max())          # (rounding: a few more eyes)
        # a cut that misses the ball, or leaves out the centre eye, changes nothing
        cut = (f, level) if -float(radius.max()) < level < 0.0 else None
    n, h, good = facing_planes(polys)
    guard = tol.box_grow_rel * np.abs(polys).max(axis=(1, 2))
    good &= (h > radius) & (h > near_eff)                     # the whole ball on the near side
    normals = np.zeros((k, 5, 3))
    offsets = np.full((k, 5), -np.inf)
    normals[:, 0] = n
    offsets[:, 0] = h + guard
    # the four edges at once, (k, 4, ...)
    a0, a1 = polys, np.roll(polys, -1, axis=1)
    ed = a1 - a0
    length = np.linalg.norm(ed, axis=2)
    edge = length > 0.0
    u = ed / np.where(edge, length, 1.0)[..., None]
    m0 = np.cross(u, a0)                                      # along the plane through the eye and the edge
    rho = np.linalg.norm(m0, axis=2)                          # the edge's line from the eye (>= h > radius)
    r4 = radius[:, None]
    edge &= rho > r4
    v = m0 / np.where(edge, rho, 1.0)[..., None]
    w = np.cross(v, u)                                        # from the eye's foot on the line, outwards
    alpha = -r4 / np.where(edge, rho, 1.0)
    beta = np.sqrt(np.maximum(1.0 - alpha * alpha, 0.0))
    inward = polys.mean(axis=1)[:, None] - a0
    gv = np.einsum("kej,kej->ke", v, inward)
    side = np.where(gv >= 0.0, 1.0, -1.0)[..., None] * v     # towards the polygon, in the eye's plane
    g = alpha[..., None] * w + beta[..., None] * side
    offset = np.broadcast_to(-r4, edge.shape).copy()
    if cut is not None:
        # only where the ball's tangent touches it below the cut (its point -radius g) does
        # the plane turn: elsewhere that point is an eye of the cut ball, the same tangent
        need = edge & (np.einsum("kej,j->ke", -g, cut[0]) * r4 < cut[1])
        if need.any():
            at = np.nonzero(need)
            g[at], offset[at] = _cut_edge_planes(w[at], side[at], rho[at], np.arctan2(beta[at], alpha[at]),
                                                 np.broadcast_to(r4, edge.shape)[at], cut)
    # the tangent plane keeps the polygon on the eyes' side (one of the two does)
    edge &= np.einsum("kej,kej->ke", g, inward) > 0.0
    good &= (edge | (length == 0.0)).all(axis=1)
    normals[:, 1:] = np.where(edge[..., None], g, 0.0)
    offsets[:, 1:] = np.where(edge, offset + guard[:, None], -np.inf)
    offsets[~good, 0] = np.inf
    return normals, offsets


CUT_STEPS = 24             # bisection steps of a cut edge plane's angle (2^-24 of under a right angle)


def _cut_edge_planes(w, side, rho, ball_angle, radius, cut):
    """Per edge (rows), the plane through it that the cut eyes (:func:`cap_support`) are on
    the positive side of, turned from the ball's tangent (angle ``ball_angle``) towards
    the plane through the eye (angle pi/2), in the pencil ``cos(phi) w + sin(phi) side``
    (offset ``rho cos(phi)``, the edge's line at ``rho w``): ``(normals, offsets)``.  The
    eyes are on the positive side over an interval of angles that holds the ball's
    tangent; bisection keeps its upper end inside that interval, so the plane returned
    always has them there."""
    lo = np.full(len(w), 0.5 * np.pi)
    hi = ball_angle.copy()

    def eyes_inside(phi):
        g = np.cos(phi)[:, None] * w + np.sin(phi)[:, None] * side
        return -cap_support(-g, radius, cut) >= rho * np.cos(phi)

    for _ in range(CUT_STEPS):
        mid = 0.5 * (lo + hi)
        ok = eyes_inside(mid)
        hi = np.where(ok, mid, hi)
        lo = np.where(ok, lo, mid)
    hi = np.where(eyes_inside(hi), hi, ball_angle)             # (rounding: the ball's, always sound)
    return np.cos(hi)[:, None] * w + np.sin(hi)[:, None] * side, rho * np.cos(hi)


def morton_order(points):
    """Indices that put ``points`` ``(m, 3)`` in Morton (Z-curve) order over their bounds,
    10 bits an axis: near points mostly fall near each other in the order."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) < 2:
        return np.arange(len(p))
    lo = p.min(axis=0)
    span = float(np.ptp(p, axis=0).max())
    if not np.isfinite(span) or span <= 0.0:
        return np.arange(len(p))
    q = np.clip((p - lo) * (1023.0 / span), 0, 1023).astype(np.uint64)
    for shift, mask in ((16, 0x30000FF), (8, 0x300F00F), (4, 0x30C30C3), (2, 0x9249249)):
        q = (q | (q << np.uint64(shift))) & np.uint64(mask)
    code = q[:, 0] | (q[:, 1] << np.uint64(1)) | (q[:, 2] << np.uint64(2))
    return np.argsort(code, kind="stable")


def hidden_by_polygons(boxes, polys, distance, near_eff=0.0, depth_guard=None, cut=None):
    """``(m,) bool``: boxes (camera-relative, ``(m, 2, 3)``) hidden from every eye
    within ``distance`` of the origin by at least one of the convex polygons
    ``(k, 4, 3)`` (camera-relative; see the module doc); ``cut``: only the eyes ``x`` with
    ``f . x >= s`` of them (:func:`umbra_planes`).  ``near_eff``: a polygon
    whose plane passes nearer the centre eye than this occludes nothing (an eye's near
    plane may cut it).  ``depth_guard``: ``(m,)``, how far beyond a polygon's plane each
    box must lie besides (a depth buffer draws a surface closer behind a polygon than its
    rounding in front of it, or through it).

    The umbra is convex, so a box is in it when its corner nearest each bounding plane
    is: per box and plane one dot product.  Boxes go in groups of :data:`GROUP`, near
    boxes together (Morton order of their centres), and each group's bounding box is
    tested first: a group inside an umbra is hidden whole, and a polygon whose umbra
    misses the group's box (its farthest corner short of some plane) can hide none of
    its boxes.  Only the polygons left, the umbras the group's box straddles, are tried
    box by box.  The answer is the flat test's, pair by pair (a box lies in its group's
    box and its guards are at most the group's; exactly so up to rounding, which the
    guards exceed by far): the groups change the work only."""
    m, k = len(boxes), len(polys)
    out = np.zeros(m, dtype=bool)
    if not m or not k:
        return out
    mag = np.abs(polys).max(axis=(1, 2))
    radius = distance * (1.0 + tol.near_guard_rel) + tol.box_grow_rel * mag
    normals, offsets = umbra_planes(polys, radius, near_eff, cut)
    keep = np.isfinite(offsets[:, 0])
    if not keep.any():
        return out
    normals, offsets = normals[keep], offsets[keep]
    # an edge that is none (a triangle's repeated corner) repeats the polygon's plane
    none = ~np.isfinite(offsets)
    normals[none] = np.broadcast_to(normals[:, :1], normals.shape)[none]
    offsets[none] = np.broadcast_to(offsets[:, :1], offsets.shape)[none]
    # [lo, hi, guard, 1] x [max(n, 0); min(n, 0); -1; -offset] is each plane's least value
    # over the box, less the box's rounding guard, less the plane's offset ([hi, lo, 0, 1]:
    # its greatest, less the offset); columns plane-major (one block per plane)
    kk = len(normals)
    planes = normals.transpose(1, 0, 2).reshape(-1, 3)
    weights = np.concatenate([np.maximum(planes, 0.0).T, np.minimum(planes, 0.0).T,
                              -np.ones((1, len(planes))), -offsets.T.reshape(1, -1)])
    rows = np.empty((m, 8))
    rows[:, 0:3], rows[:, 3:6] = boxes[:, MIN], boxes[:, MAX]
    rows[:, 6] = tol.box_grow_rel * np.abs(boxes).max(axis=(1, 2))
    rows[:, 7] = 1.0
    guard = np.zeros(m) if depth_guard is None else np.asarray(depth_guard, dtype=np.float64)
    if m <= GROUP:
        out[:] = _inside_any(rows, guard, weights, kk)
        return out
    order = morton_order(0.5 * (boxes[:, MIN] + boxes[:, MAX]))
    rows, guard = rows[order], guard[order]
    starts = np.arange(0, m, GROUP)
    group = np.empty((len(starts), 8))
    group[:, 0:3] = np.minimum.reduceat(rows[:, 0:3], starts)
    group[:, 3:7] = np.maximum.reduceat(rows[:, 3:7], starts)
    group[:, 7] = 1.0
    group_guard = np.maximum.reduceat(guard, starts)
    whole = _inside_any(group, group_guard, weights, kk)
    far = group[:, [3, 4, 5, 0, 1, 2, 6, 7]]
    far[:, 6] = 0.0
    reach = _least_over_planes(far @ weights, kk) >= 0.0        # (groups, polygons): straddled or inside
    hidden = np.zeros(m, dtype=bool)
    w5 = weights.reshape(8, 5, kk)
    for g in np.flatnonzero(~whole & reach.any(axis=1)):
        cand = np.flatnonzero(reach[g])
        s = slice(g * GROUP, min((g + 1) * GROUP, m))
        hidden[s] = _inside_any(rows[s], guard[s], w5[:, :, cand].reshape(8, -1), len(cand))
    hidden |= np.repeat(whole, GROUP)[:m]
    out[order] = hidden
    return out


def _least_over_planes(values, kk):
    """``(n, 5 kk)`` plane-major values to ``(n, kk)``: the least of each polygon's five."""
    least = values[:, :kk].copy()
    for e in range(1, 5):
        np.minimum(least, values[:, e * kk:(e + 1) * kk], out=least)
    return least


def _inside_any(rows, guard, weights, kk):
    """``(n,) bool``: rows ``[lo, hi, guard, 1]`` inside at least one of ``kk`` umbras
    (plane-major weights), each row a further ``guard`` beyond the polygon's plane;
    :data:`BOX_CHUNK` rows a matrix product."""
    out = np.zeros(len(rows), dtype=bool)
    for s in range(0, len(rows), BOX_CHUNK):
        low = rows[s:s + BOX_CHUNK] @ weights
        low[:, :kk] -= guard[s:s + BOX_CHUNK, None]
        out[s:s + BOX_CHUNK] = (_least_over_planes(low, kk) >= 0.0).any(axis=1)
    return out
