"""The motion envelope: a hidden set that holds while the view moves a little.

``envelope_pass(culler, camera, Envelope(D, A))`` hides an object only when it is
hidden from EVERY view whose eye lies within ``D`` scene units of the camera's eye
and whose direction lies within ``A`` degrees of its direction, with any roll and
the same lens: what live mode needs between passes, when the view moves before the
next pass lands.

The method is Durand et al.'s *extended projections* (2000) on an image from the
centre eye ``p``, in directions (a projection plane at infinity):

- **Occludees grow.**  Every direction from an eye ``p'`` (``|p' - p| <= D``) to a
  point ``x`` of a box is a direction from ``p`` to ``x + (p - p')``, a point of the
  box grown by ``D``; so the grown box's projection from ``p`` holds every ray that
  can reach the box from the envelope.
- **Occluders shrink.**  A ray from ``p'`` in direction ``w``, at distance ``r`` from
  ``p``, is seen from ``p`` within ``asin(D / r)`` of ``w``.  Where the first-hit
  surface from ``p`` is continuous over a window of directions around ``w`` that
  holds that whole angle for every ``r`` past the window's nearest surface, the ray
  starts in front of that surface (``p'`` is nearer than it) and ends behind it (the
  occludee is farther than the window's farthest surface), so it crosses it: the ray
  is blocked.  Continuity ends at an object's outline (object-ID change), at a depth
  jump larger than a continuous surface makes between two pixels at that depth (see
  ``_jumps``), at empty pixels and at the image border; a window holding any of these
  covers nothing.  Fusion is free: every window is one surface, so occluders of many
  objects hide together only where they meet with no gap the eye could look through.
- **Frustum.**  A point seen from ``p'`` with a direction within ``A`` of ``d``, any
  roll, lies within ``theta + A`` of ``d`` seen from ``p'`` (``theta``: the angle of the
  lens's corner ray), hence in the cone of that half-angle from ``p`` once its box is
  grown by ``D``.  The image from ``p`` is a square frustum around that cone; a grown
  box outside it is VIEW_CULLED.

Per window size (half-sizes 1, 3, 7, ... pixels) the image is reduced to: any break in
the window, the nearest and the farthest depth; a pixel takes the farthest depth of
the smallest window that holds its parallax, or stays open (nothing hides behind it).
A grown box is OCCLUDED when its nearest depth is beyond the farthest such depth over
its pixel rectangle (rounded outward).  Limits, stated as the point pass states its
own: the surface is sampled at pixel centres, so a slit inside one object narrower
than a pixel of this image, or a depth jump small enough to pass for a slope, is not
seen; orthographic views hide no occluded object under an envelope (only what the
grown frustum leaves out, and only with ``A = 0``); a lens wider than ``MAX_HALF_DEG``
with the turn hides nothing.
"""

import math
import time
from dataclasses import dataclass

import numpy as np

from .bounds import MAX, MIN, corners, transform_boxes
from .camera import Camera, perspective
from .errors import OccError
from .frustum import classify, planes_from_matrix
from .tolerance import tol
from .traversal import STAT_KEYS, Visibility
from . import umbra
from .umbra import hidden_by_polygons

MAX_HALF_DEG = 80.0        # widest half-angle of the envelope's square image (tan 80 = 5.7)
MAX_SIDE = 2048            # largest side of the envelope's image, pixels
MIN_SIDE = 64
HALF_SIZES = (1, 3, 7, 15, 31, 63, 127, 255)   # window half-sizes: each 2h + 1 of the one before
RECT_TEXELS = 8            # a box's rectangle is read at the pyramid level where it spans this many


@dataclass(frozen=True)
class Envelope:
    """Eye within ``distance`` scene units, direction within ``angle_deg`` degrees."""

    distance: float
    angle_deg: float

    def __post_init__(self):
        d, a = float(self.distance), float(self.angle_deg)
        if not (math.isfinite(d) and d >= 0.0):
            raise OccError(f"envelope distance must be a number >= 0, got {self.distance}")
        if not (math.isfinite(a) and 0.0 <= a < 90.0):
            raise OccError(f"envelope angle must be between 0 and 90 degrees, got {self.angle_deg}")
        object.__setattr__(self, "distance", d)
        object.__setattr__(self, "angle_deg", a)

    @classmethod
    def parse(cls, text):
        """``"D,A"`` -> Envelope, with one clear error."""
        try:
            d, a = (float(x) for x in str(text).split(","))
        except ValueError:
            raise OccError(f"envelope must look like 2,10 (distance in scene units, angle in degrees), "
                           f"got '{text}'") from None
        return cls(d, a)

    def holds(self, camera, view):
        """Whether ``view`` (a Camera with the same lens) lies inside this envelope
        around ``camera``."""
        move = float(np.linalg.norm(view.eye - camera.eye))
        cos = float(np.clip(view.direction @ camera.direction, -1.0, 1.0))
        return move <= self.distance and math.degrees(math.acos(cos)) <= self.angle_deg


def corner_half_angle(camera):
    """Largest angle between the view direction and a ray through a corner of the
    image, radians (lens shift included)."""
    inv = np.linalg.inv(camera.projection)
    ndc = np.array([(x, y, -1.0, 1.0) for x in (-1, 1) for y in (-1, 1)])
    p = ndc @ inv.T
    p = p[:, :3] / p[:, 3:]
    cos = -p[:, 2] / np.linalg.norm(p, axis=1)        # the camera looks down -z
    return float(np.arccos(np.clip(cos.min(), -1.0, 1.0)))


def _lens(camera):
    """Near and far distances and the pixel-to-tangent scale of a perspective lens."""
    p = camera.projection
    near = p[2, 3] / (p[2, 2] - 1.0)
    far = p[2, 3] / (p[2, 2] + 1.0)
    return float(near), float(far), 1.0 / float(p[1, 1])


def envelope_camera(camera, envelope, query_height):
    """The square view from the camera's eye that holds every view of the envelope,
    and its side in pixels (the query's angular pixel size at the centre), or
    ``(None, 0)`` when the turn makes it wider than :data:`MAX_HALF_DEG`."""
    half = corner_half_angle(camera) + math.radians(envelope.angle_deg)
    if half >= math.radians(MAX_HALF_DEG):
        return None, 0
    near, far, tan_y = _lens(camera)
    side = int(np.clip(math.ceil(query_height * math.tan(half) / tan_y), MIN_SIDE, MAX_SIDE))
    proj = perspective(math.degrees(2.0 * half), 1.0, near, far + envelope.distance)
    return Camera(camera.view, proj), side


def _shift_max(a, h, axis, fill):
    """``max`` over a window of half-size ``h`` built from one of half-size ``(h - 1) / 2``:
    the array and its two copies shifted by ``(h + 1) / 2``, ``fill`` past the border."""
    k = (h + 1) // 2
    out = a.copy()
    n = a.shape[axis]
    if k >= n:
        out[...] = np.maximum(out, fill)
        return out
    lo = [slice(None)] * a.ndim
    hi = [slice(None)] * a.ndim
    lo[axis], hi[axis] = slice(k, None), slice(None, n - k)
    np.maximum(out[tuple(lo)], a[tuple(hi)], out=out[tuple(lo)])
    np.maximum(out[tuple(hi)], a[tuple(lo)], out=out[tuple(hi)])
    edge = [slice(None)] * a.ndim
    edge[axis] = slice(0, k)
    np.maximum(out[tuple(edge)], fill, out=out[tuple(edge)])
    edge[axis] = slice(n - k, None)
    np.maximum(out[tuple(edge)], fill, out=out[tuple(edge)])
    return out


def _grow(a, h, fill):
    """Window max of half-size ``h`` from the one of half-size ``(h - 1) / 2``, both axes."""
    return _shift_max(_shift_max(a, h, 0, fill), h, 1, fill)


def _jumps(z, ok, tan_px, distance, w_tol):
    """Pixels beside a depth jump that no continuous surface makes.

    Two neighbouring pixels lie on one continuous surface when the step between them
    in ``1 / z`` (linear across the screen on a plane) lies between the steps on
    either side of them: one plane, or two planes meeting at a crease between the
    two centres.  A silhouette, where the near surface ends and another one shows
    behind it, steps outside that range.  A step small enough passes too: a ray from
    an eye ``D`` away that slips between two surfaces ``dz`` apart at distance ``r``
    drifts ``D dz / r^2`` radians across them, under half a pixel here (both rules
    judge from pixel centres: the module doc's sampling limit)."""
    w = np.where(ok, 1.0 / np.where(ok, z, 1.0), np.nan)
    zz = np.where(ok, z, np.inf)
    out = np.zeros(z.shape, dtype=bool)
    for axis in (0, 1):
        a = np.moveaxis(w, axis, 0)
        zn = np.moveaxis(zz, axis, 0)
        px = np.moveaxis(tan_px, axis, 0)
        step = a[1:] - a[:-1]                                   # between pixel k and k + 1
        before = np.full(step.shape, np.nan)
        after = np.full(step.shape, np.nan)
        before[1:] = step[:-1]                                  # the step from k - 1 to k
        after[:-1] = step[1:]                                   # the step from k + 1 to k + 2
        lo = np.fmin(before, after)
        hi = np.fmax(before, after)
        with np.errstate(invalid="ignore"):
            sloped = (step >= lo - w_tol) & (step <= hi + w_tol)
            near = np.minimum(zn[1:], zn[:-1])
            ang = np.minimum(px[1:], px[:-1])
            small = np.abs(zn[1:] - zn[:-1]) <= 0.5 * ang * near * near / max(distance, 1e-300)
        jump = ~(sloped | small)
        o = np.moveaxis(out, axis, 0)
        o[1:] |= jump
        o[:-1] |= jump
    return out


def extended_depth(ids, depth, camera, envelope):
    """Per pixel, the farthest depth behind which every ray from the envelope is
    blocked, ``(s, s) float64`` view-space distance along the axis (``inf``: open).

    ids, depth: the ID and window-depth images from :meth:`GLRenderer.ids_and_depth`
    of ``camera`` (the envelope's square view)."""
    near, far, tan_half = _lens(camera)
    s = ids.shape[0]
    d = depth.astype(np.float64)                       # float64 here: 1/z steps are compared below
    ok = (ids >= 0) & (d < 1.0)
    ndc = 2.0 * d - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(ok, 2.0 * near * far / (far + near - ndc * (far - near)), np.inf)
    # tangent-plane coordinates of pixel centres; one pixel = dt of tangent
    dt = 2.0 * tan_half / s
    c = (np.arange(s) + 0.5) * dt - tan_half
    t = np.hypot(c[None, :], c[:, None])
    tan_px = dt / (1.0 + t * t)                        # angle of one pixel there, radians (at most)
    brk = ~ok
    if envelope.distance > 0.0:
        # 1/z is known to a few steps of the 24-bit depth grid: (far - near) / (near far 2^24) each
        w_tol = tol.depth_guard_steps * (far - near) / (near * far * 2.0 ** tol.depth_bits)
        brk = brk | _jumps(z, ok, tan_px, envelope.distance, w_tol)
    guard = 1.0 + tol.near_guard_rel
    ext = np.full(z.shape, np.inf)
    b = brk.astype(np.uint8)
    zlo = np.where(ok, -z, -np.inf)                     # max of -z: the nearest depth
    zhi = np.where(ok, z, np.inf)
    open_ = np.ones(z.shape, dtype=bool)
    for h in HALF_SIZES:                               # each window from the one before
        if h >= s:
            break
        b = _grow(b, h, np.uint8(1))                   # past the border: unknown, a break
        zlo = _grow(zlo, h, np.inf)
        zhi = _grow(zhi, h, np.inf)
        cand = np.flatnonzero((open_ & (b == 0) & (-zlo > envelope.distance * guard)).ravel())
        if not len(cand):
            continue
        nearest = -zlo.ravel()[cand]
        alpha = np.arcsin(np.clip(envelope.distance / nearest, 0.0, 1.0))
        # the window's angle in pixels where it is widest on screen: at its outer
        # corner, where a tangent step per radian is 1 + tan^2
        reach = np.arctan(t.ravel()[cand] + h * dt * math.sqrt(2.0)) + alpha
        fits = reach < 0.5 * math.pi - 1e-6
        need = alpha * (1.0 + np.tan(np.where(fits, reach, 0.0)) ** 2) / dt + 1.0   # + the pixel's own footprint
        good = cand[fits & (need <= h)]
        ext.ravel()[good] = zhi.ravel()[good]
        open_.ravel()[good] = False
        if not open_.any():
            break
    return ext


def _pyramid(ext):
    """Max pyramid of a square image (level k: 2^k x 2^k blocks); sizes round up."""
    levels = [ext]
    a = ext
    while a.shape[0] > 1 or a.shape[1] > 1:
        h, w = a.shape
        a = np.pad(a, ((0, h % 2), (0, w % 2)), constant_values=-np.inf)
        a = np.maximum(np.maximum(a[0::2, 0::2], a[1::2, 0::2]), np.maximum(a[0::2, 1::2], a[1::2, 1::2]))
        levels.append(a)
    return levels


def _rect_max(levels, rects):
    """Max over each inclusive pixel rectangle ``(k, 4) [x0, y0, x1, y1]``, read at the
    level where it spans at most RECT_TEXELS texels a side (so possibly over a bit more
    than the rectangle: larger, never smaller)."""
    k = len(rects)
    out = np.full(k, -np.inf)
    if not k:
        return out
    span = np.maximum(rects[:, 2] - rects[:, 0], rects[:, 3] - rects[:, 1]) + 1
    lvl = np.clip(np.ceil(np.log2(np.maximum(span / RECT_TEXELS, 1.0))).astype(np.int64), 0, len(levels) - 1)
    for L in np.unique(lvl):
        sel = np.flatnonzero(lvl == L)
        img = levels[L]
        r = rects[sel] >> L
        for dy in range(RECT_TEXELS + 1):
            for dx in range(RECT_TEXELS + 1):
                x = np.minimum(r[:, 0] + dx, r[:, 2])
                y = np.minimum(r[:, 1] + dy, r[:, 3])
                out[sel] = np.maximum(out[sel], img[y, x])
    return out


def grown_boxes(boxes, eye, distance, scene_size):
    """Camera-relative boxes grown by the envelope's distance and the query guard."""
    rel = boxes - eye
    mag = np.abs(rel).max(axis=(1, 2))
    g = distance + tol.box_grow_rel * mag + tol.box_grow_scene * scene_size
    out = rel.copy()
    out[:, MIN] -= g[:, None]
    out[:, MAX] += g[:, None]
    return out


def classify_boxes(rel, view_camera, side, ext, depth_step_at):
    """States of camera-relative boxes (already grown) from the envelope's view:
    VISIBLE, OCCLUDED or VIEW_CULLED per box."""
    k = len(rel)
    state = np.full(k, Visibility.VISIBLE, dtype=np.uint8)
    if not k:
        return state
    clip = view_camera.relative_view_projection()
    outside, _ = classify(planes_from_matrix(clip), rel)
    state[outside] = Visibility.VIEW_CULLED
    if ext is None:
        return state
    near, _, _ = _lens(view_camera)
    inside = np.flatnonzero(~outside)
    c = corners(rel[inside])                                 # (k, 8, 3) camera-relative
    view_rot = view_camera.view[:3, :3]
    vz = -(c @ view_rot.T)[..., 2]                           # view-space depth of each corner
    zmin = vz.min(axis=1)
    front = zmin > near * (1.0 + tol.near_guard_rel)        # a box at or before the near plane is visible
    idx = inside[front]
    cc = c[front]
    h = np.concatenate([cc, np.ones(cc.shape[:2] + (1,))], axis=2) @ clip.T
    ndc = h[..., :2] / h[..., 3:4]
    lo, hi = ndc.min(axis=1), ndc.max(axis=1)
    # pixel i's footprint is [i, i + 1) of u = (ndc + 1) / 2 * side: every pixel a
    # direction of the box falls in, rounded outward
    u0 = np.floor((lo + 1.0) * 0.5 * side).astype(np.int64)
    u1 = np.floor((hi + 1.0) * 0.5 * side).astype(np.int64)
    rects = np.clip(np.concatenate([u0, u1], axis=1), 0, side - 1)
    levels = _pyramid(ext)
    far_occ = _rect_max(levels, rects)
    zm = zmin[front]
    # ties and the depth buffer's rounding count as visible
    hidden = zm > far_occ + tol.depth_guard_steps * depth_step_at(zm)
    state[idx[hidden]] = Visibility.OCCLUDED
    return state


def occluder_polygons(culler, eye):
    """Camera-relative convex polygons ``(k, 4, 3)`` of the objects largest on screen
    from ``eye`` (:data:`core.umbra.OBJECTS` objects, :data:`core.umbra.POLYGONS`
    polygons); each mesh's polygons are found once and kept on the culler."""
    scene = culler.scene
    valid = np.flatnonzero(~scene.invalid)
    if not len(valid):
        return np.zeros((0, 4, 3))
    box = scene.bounds[valid] - eye
    size = np.linalg.norm(box[:, MAX] - box[:, MIN], axis=1)
    gap = np.linalg.norm(np.maximum(np.maximum(box[:, MIN], -box[:, MAX]), 0.0), axis=1)
    with np.errstate(divide="ignore"):
        score = size / np.maximum(gap, 1e-300)
    objs = valid[np.argsort(-score)[:umbra.OBJECTS]]
    cache = culler.__dict__.setdefault("_polygons", {})
    polys, weight = [], []
    for o in objs:
        mi = int(scene.mesh_of[o])
        v, f = scene.meshes[mi]
        key = (mi, id(v), id(f))
        if key not in cache:
            cache[key] = umbra.convex_polygons(v, f)
        local, area = cache[key]
        if not len(local):
            continue
        m = scene.matrices[o]
        world = local @ m[:3, :3].T + (m[:3, 3] - eye)
        polys.append(world)
        d = np.linalg.norm(world.mean(axis=1), axis=1)
        weight.append(np.linalg.norm(np.cross(world[:, 2] - world[:, 0], world[:, 3] - world[:, 1]), axis=1)
                      / np.maximum(d * d, 1e-300))
    if not polys:
        return np.zeros((0, 4, 3))
    polys = np.concatenate(polys)
    weight = np.concatenate(weight)
    return polys[np.argsort(-weight)[:umbra.POLYGONS]]


def envelope_pass(culler, camera, envelope, display=None):
    """States ``(n,) uint8`` and stats of the objects of ``culler``'s scene for every
    view of ``envelope`` around ``camera`` (see the module doc)."""
    t0 = time.perf_counter()
    scene = culler.scene
    n = len(scene)
    stats = dict.fromkeys(STAT_KEYS, 0)
    ub = culler.unit_bounds()
    valid_units = ~scene.invalid[culler.units.object]
    eye = camera.eye
    rel = grown_boxes(ub, eye, envelope.distance, culler.scene_size)
    unit_state = np.full(len(ub), Visibility.VISIBLE, dtype=np.uint8)
    height = (display or culler.display or culler.resolution)[1]
    if camera.is_orthographic:
        if envelope.angle_deg == 0.0:
            # a parallel view moved by D sees the frustum moved by D: grown boxes test it
            outside, _ = classify(planes_from_matrix(camera.relative_view_projection()), rel)
            unit_state[outside] = Visibility.VIEW_CULLED
        ext = None
        view_camera = None
    else:
        view_camera, side = envelope_camera(camera, envelope, height)
        ext = None
        if view_camera is not None:
            # only what can show in the square view: the same picture, less to draw
            out_units, _ = classify(planes_from_matrix(view_camera.relative_view_projection()), rel)
            shown = np.zeros(n, dtype=bool)
            shown[culler.units.object[~out_units]] = True
            objects = np.flatnonzero(shown & ~scene.invalid)
            ids, depth = culler.renderer.ids_and_depth(view_camera, (side, side), objects)
            stats["gl_calls"] = culler.renderer.counters["gl_calls"]
            stats["blocking_reads"] = culler.renderer.counters["blocking_reads"]
            ext = extended_depth(ids, depth, view_camera, envelope)
            near, far, _ = _lens(view_camera)

            def step(zd):
                return zd * zd * (far - near) / (near * far * 2.0 ** tol.depth_bits)

            unit_state = classify_boxes(rel, view_camera, side, ext, step)
            stats["query_rect_pixels"] = int(side * side)
            if envelope.distance > 0.0:
                test = np.flatnonzero((unit_state == Visibility.VISIBLE) & valid_units)
                hidden = hidden_by_polygons(ub[test] - eye, occluder_polygons(culler, eye), envelope.distance,
                                            camera.view[:3, :3])
                unit_state[test[hidden]] = Visibility.OCCLUDED
                stats["queries"] = int(len(test))
    unit_state[~valid_units] = Visibility.VISIBLE
    state = np.full(n, Visibility.VIEW_CULLED, dtype=np.uint8)
    np.minimum.at(state, culler.units.object, unit_state)     # an object: the most visible of its units
    state[scene.invalid] = Visibility.VISIBLE
    stats["total_ms"] = stats["cpu_ms"] = 1e3 * (time.perf_counter() - t0)
    stats["invalid_objects"] = int(scene.invalid.sum())
    stats["envelope_distance"] = envelope.distance
    stats["envelope_angle_deg"] = envelope.angle_deg
    return state, stats


def sample_views(camera, envelope, count, rng):
    """``count`` random views of the envelope around a look-at ``camera``: eyes
    uniform in the ball, directions uniform in the cone, any roll; the same projection (for tests and the motion benchmark)."""
    eye, d = camera.eye, camera.direction
    r = camera.view[:3, :3]
    out = []
    for _ in range(count):
        v = rng.normal(size=3)
        v *= envelope.distance * rng.random() ** (1.0 / 3.0) / max(np.linalg.norm(v), 1e-300)
        a = math.radians(envelope.angle_deg) * math.sqrt(rng.random())
        axis = np.cross(d, rng.normal(size=3))
        axis /= max(np.linalg.norm(axis), 1e-300)
        rot = _rotation(axis, a)
        roll = _rotation(d, math.pi * (2.0 * rng.random() - 1.0))
        world = rot @ roll @ r.T                         # camera axes in world space, turned
        view = np.eye(4)
        view[:3, :3] = world.T
        view[:3, 3] = -world.T @ (eye + v)
        out.append(Camera(view, camera.projection))
    return out


def _rotation(axis, angle):
    """Rotation matrix about a unit ``axis`` by ``angle`` radians (Rodrigues)."""
    x, y, z = axis
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


__all__ = ["Envelope", "envelope_pass", "envelope_camera", "extended_depth", "sample_views",
           "corner_half_angle", "transform_boxes"]
