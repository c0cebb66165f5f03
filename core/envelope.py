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
  is blocked.  Continuity ends at a depth jump that no plane or crease makes between
  two pixels (see ``_jumps``), at empty pixels and at the image border; a window
  holding any of these covers nothing.  Fusion is free: occluders of many objects
  hide together where their pixels meet with no such jump (flush walls, a facade of
  many objects), since a ray cannot pass between two surfaces that meet.
- **Frustum.**  A point seen from ``p'`` with a direction within ``A`` of ``d``, any
  roll, lies within ``theta + A`` of ``d`` seen from ``p'`` (``theta``: the angle of the
  lens's corner ray), hence in the cone of that half-angle from ``p`` once its box is
  grown by ``D``.  The image from ``p`` is a square frustum around that cone; a grown
  box outside it is VIEW_CULLED.

Near occluders move too far across the screen for any window; big convex polygons of
them are tested in object space instead (:mod:`core.umbra`), and an object is hidden
when either proof hides it.  Shadows under scene lights are boxes tested the same way
(:mod:`core.lights`).

Per window size (half-sizes 1, 3, 7, ... pixels) the image is reduced to: any break in
the window, the nearest and the farthest depth; a pixel takes the farthest depth of
the smallest window that holds its parallax, or stays open (nothing hides behind it).
A grown box is OCCLUDED when its nearest depth is beyond the farthest such depth over
its pixel rectangle (rounded outward).  Limits, stated as the point pass states its
own: the surface is sampled at pixel centres, so a slit narrower than a pixel of this
image between two pixels that lie on one slope (inside one object, or between two
surfaces in one plane) is not seen; a lens wider than ``MAX_HALF_DEG`` with the turn
hides nothing.

Orthographic views have a proof of their own (:class:`_ParallelProof`): their rays do not
depend on the eye, so only the turn moves them, and a point is hidden while it lies behind
a continuous surface by no more than the surface's width over the turn's tangent allows.
"""

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from . import umbra
from .bounds import MAX, MIN, corners
from .camera import Camera, perspective, view_change
from .cull import PassStats, Visibility
from .errors import OccError
from .frustum import classify, planes_from_matrix
from .lights import in_world, shadow_boxes
from .tolerance import tol
from .umbra import hidden_by_polygons

MAX_HALF_DEG = 80.0        # widest half-angle of the envelope's square image (tan 80 = 5.7)
MAX_SIDE = 2048            # largest side of the envelope's image, pixels
MIN_SIDE = 64
MARGIN_PX = 4              # the render square reaches this many pixels past the cull square ...
MARGIN_REL = 0.05          # ... or this share of its side, the larger
HALF_SIZES = (1, 3, 7, 15, 31, 63, 127, 255)   # window half-sizes: each 2h + 1 of the one before
RECT_TEXELS = 8            # a box's rectangle is read at the pyramid level where it spans this many
SPLITS = 2                 # a box that starts before the covered depth and ends behind it: cut this often


@dataclass(frozen=True)
class Envelope:
    """Eye within ``distance`` scene units, direction within ``angle_deg`` degrees (any
    roll); with ``any_roll=False``, the camera's whole frame turned by at most
    ``angle_deg`` (roll included: what live mode measures), a narrower view to test.

    ``also``: cameras whose envelopes (the same distance and angle) the hidden set must
    hold for too.  ``floor``: ``(nx, ny, nz, c)``, the eye also stays on the side ``n . eye >= c`` of a
    plane (world space, ``n`` a unit vector), or None.  ``above_floor``: the pass may set
    ``floor`` itself (:func:`floor_cut`: a little short of the nearest face the ball
    reaches through, a ground or a wall) and returns the envelope it used
    (:attr:`core.cull.CullResult.envelope`); only for a caller that checks every view
    against the returned envelope before drawing (live mode: a view that leaves it,
    through the floor too, is drawn with everything shown).  Eyes under a floor see
    what stands on it from below, past its lower edges: left out, the same walls hide
    far more (on the city, eyes 1.7 above the ground, ``2,10``: 97 % of what no sampled
    view sees against 85 %, ``tools/bench/envelope_ceiling.py``)."""

    distance: float
    angle_deg: float
    any_roll: bool = True
    above_floor: bool = False
    floor: tuple | None = None
    # other cameras (:class:`core.camera.Camera`) the hidden set must hold for too, each with
    # this distance and angle around it (no floor): the perspective view Blender turns an
    # orthographic one into, before a redraw the caller could act in
    also: tuple = ()

    def __post_init__(self):
        d, a = float(self.distance), float(self.angle_deg)
        if not (math.isfinite(d) and d >= 0.0):
            raise OccError(f"envelope distance must be a number >= 0, got {self.distance}")
        if not (math.isfinite(a) and 0.0 <= a < 90.0):
            raise OccError(f"envelope angle must be between 0 and 90 degrees, got {self.angle_deg}")
        object.__setattr__(self, "distance", d)
        object.__setattr__(self, "angle_deg", a)
        if self.floor is not None:
            floor = tuple(float(x) for x in self.floor)
            if len(floor) != 4 or not all(math.isfinite(x) for x in floor) \
                    or abs(math.hypot(*floor[:3]) - 1.0) > 1e-6:
                raise OccError(f"an envelope's floor is (nx, ny, nz, c) with a unit normal, got {self.floor}")
            object.__setattr__(self, "floor", floor)

    def height(self, eye) -> float:
        """How far ``eye`` (world) stands above the floor's plane (inf: no floor)."""
        if self.floor is None:
            return math.inf
        nx, ny, nz, c = self.floor
        return float(nx * eye[0] + ny * eye[1] + nz * eye[2] - c)

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
        move, turn = view_change(camera, view, frame=not self.any_roll)
        return move <= self.distance and turn <= self.angle_deg and self.height(view.eye) >= 0.0


# an envelope wider than this proves little, and the envelope allows less than 90 degrees
MAX_COVER_TURN_DEG = 60.0


def covering(camera, views, widen: float = 0.0):
    """The envelope around ``camera`` that holds every view of ``views`` (Cameras): the
    largest eye distance and whole-frame turn (roll included) from ``camera`` to any of
    them, each grown by ``widen`` times itself (the slack for a path sampled between
    the views) and a hair for float rounding.  None: every view is ``camera``'s own
    (nothing moves); ``False``: no envelope holds (a view has another lens, or turns
    more than :data:`MAX_COVER_TURN_DEG`): nothing may be hidden for them."""
    move = turn = 0.0
    for v in views:
        if not np.array_equal(v.projection, camera.projection):
            return False
        m, t = view_change(camera, v)
        move, turn = max(move, m), max(turn, t)
    turn *= 1.0 + widen
    if turn > MAX_COVER_TURN_DEG:
        return False
    if move == 0.0 and turn == 0.0:
        return None
    return Envelope(move * (1.0 + widen) * (1.0 + 1e-9) + 1e-12, min(turn * (1.0 + 1e-9) + 1e-9, 89.0),
                    any_roll=False)


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


@dataclass(frozen=True)
class EnvelopeView:
    """The views of an envelope.  ``cull``: the frustum that holds every view of the
    envelope (a grown box outside it is VIEW_CULLED); ``render``: the same widened by a
    margin of pixels, so that windows at its edge find surface beyond it (``size =
    (width, height)`` pixels, square in tangent units; the cull frustum is pixels
    ``lo[0] .. hi[0]`` across and ``lo[1] .. hi[1]`` up)."""

    cull: Camera
    render: Camera
    size: tuple
    lo: tuple
    hi: tuple
    far: float = math.inf      # the lens's own far plane ...
    turn: float = 0.0          # ... and how far (radians) a view's axis turns


def _half_angles(camera, envelope):
    """Half-angles ``(x, y)`` in radians of a symmetric frustum around the view axis
    that holds every view of the envelope.

    Any roll: the cone of the lens's corner ray plus the turn, in a square.  A frame
    turned by at most ``A``: every corner ray stays within ``A`` of where it was, in a
    cap whose horizontal angle spans ``asin(sin A / cos b)`` either side of the
    corner's (``b``: the corner's angle out of the horizontal plane), the same upward;
    the turned frustum is the cone over its turned corners, so a frustum holding the
    four caps holds it."""
    a = math.radians(envelope.angle_deg)
    if envelope.any_roll:
        half = corner_half_angle(camera) + a
        return half, half
    inv = np.linalg.inv(camera.projection)
    ndc = np.array([(x, y, -1.0, 1.0) for x in (-1, 1) for y in (-1, 1)])
    p = ndc @ inv.T
    p = p[:, :3] / p[:, 3:]
    u = p / np.linalg.norm(p, axis=1, keepdims=True)
    out = []
    for axis, other in ((0, 1), (1, 0)):
        angle = np.abs(np.arctan2(u[:, axis], -u[:, 2]))                # the corner's angle along this axis
        lat = np.arcsin(np.clip(np.abs(u[:, other]), 0.0, 1.0))       # out of that plane
        room = np.cos(lat) - math.sin(a)
        if (room <= 0.0).any():
            return math.pi / 2, math.pi / 2                            # the cap reaches the pole: too wide
        out.append(float((angle + np.arcsin(np.clip(math.sin(a) / np.cos(lat), 0.0, 1.0))).max()))
    return out[0], out[1]


def envelope_camera(camera, envelope, query_height):
    """The :class:`EnvelopeView` from the camera's eye that holds every view of the
    envelope (at the query's angular pixel size at the centre), or None when the
    turn makes it wider than :data:`MAX_HALF_DEG`."""
    hx, hy = _half_angles(camera, envelope)
    if max(hx, hy) >= math.radians(MAX_HALF_DEG):
        return None
    near, far, tan_y = _lens(camera)
    tx, ty = math.tan(hx), math.tan(hy)
    scale = min(1.0, MAX_SIDE / (query_height * max(tx, ty) / tan_y))   # pixels: at most MAX_SIDE a side
    inner_y = max(MIN_SIDE, math.ceil(query_height * ty / tan_y * scale))
    inner_x = max(MIN_SIDE, math.ceil(inner_y * tx / ty))
    margin = max(MARGIN_PX, math.ceil(MARGIN_REL * max(inner_x, inner_y)))
    w, h = inner_x + 2 * margin, inner_y + 2 * margin
    # square pixels in tangent units: the render frustum reaches margin pixels past the cull one
    rx, ry = tx * w / inner_x, ty * h / inner_y
    # the far plane is a plane: a turned view draws a point out to far / cos(c) from its eye
    # (c: the lens's corner angle), so out to that plus D from this one (a point beyond the
    # far plane here, off the axis, can lie before a turned view's)
    reach = far / math.cos(corner_half_angle(camera)) + envelope.distance
    clip = (near, reach * (1.0 + tol.near_guard_rel))
    cull = Camera(camera.view, perspective(math.degrees(2.0 * hy), tx / ty, *clip))
    render = Camera(camera.view, perspective(math.degrees(2.0 * math.atan(ry)), rx / ry, *clip))
    return EnvelopeView(cull, render, (w, h), (margin, margin), (margin + inner_x - 1, margin + inner_y - 1),
                        far, math.radians(envelope.angle_deg))


def _shift_max(a, h, axis, fill):
    """``max`` over a window of half-size ``h`` built from one of half-size ``(h - 1) / 2``:
    the array and its two copies shifted by ``(h + 1) / 2``, ``fill`` past the border."""
    return _shift(a, (h + 1) // 2, axis, fill, np.maximum)


def _shift(a, k, axis, fill, reduce):
    """``reduce`` (``np.maximum`` or ``np.minimum``) of ``a`` and its two copies shifted by
    ``k`` along ``axis``, ``fill`` past the border."""
    out = a.copy()
    n = a.shape[axis]
    if k >= n:
        out[...] = reduce(out, fill)
        return out
    lo = [slice(None)] * a.ndim
    hi = [slice(None)] * a.ndim
    lo[axis], hi[axis] = slice(k, None), slice(None, n - k)
    reduce(out[tuple(lo)], a[tuple(hi)], out=out[tuple(lo)])
    reduce(out[tuple(hi)], a[tuple(lo)], out=out[tuple(hi)])
    edge = [slice(None)] * a.ndim
    edge[axis] = slice(0, k)
    reduce(out[tuple(edge)], fill, out=out[tuple(edge)])
    edge[axis] = slice(n - k, None)
    reduce(out[tuple(edge)], fill, out=out[tuple(edge)])
    return out


def _grow(a, h, fill):
    """Window max of half-size ``h`` from the one of half-size ``(h - 1) / 2``, both axes."""
    return _shift_max(_shift_max(a, h, 0, fill), h, 1, fill)


NEAREST_GUARD = 1.0 + tol.near_guard_rel   # a window's nearest depth must pass D this many times


def slope_tolerance(near, far):
    """How far two ``1 / z`` steps may differ and still be one slope: 1/z is known to a few
    steps of the 24-bit depth grid, ``(far - near) / (near far 2^24)`` each (the numpy
    image's rule and the compute passes')."""
    return tol.depth_guard_steps * (far - near) / (near * far * 2.0 ** tol.depth_bits)


def _jumps(z, ok, w_tol, linear=False):
    """Pixels beside a depth jump that no continuous surface makes.

    Two neighbouring pixels lie on one continuous surface when the step between them
    in ``1 / z`` (linear across the screen on a plane) lies between the steps on
    either side of them: one plane, or two planes meeting at a crease between the
    two centres.  A silhouette, where the near surface ends and another one shows
    behind it, steps outside that range, however small the step: a gap between the two
    surfaces narrower than a pixel can lie between the two centres, and a view of the
    envelope whose pixel centres fall elsewhere sees through it (a rule that let steps
    smaller than half a pixel of parallax pass for slopes hid objects that 1-3 pixels of
    such views showed: ``tools/checks/fuzz_truth.py --envelope``, seeds 88, 122, 163, 237).
    ``linear``: a parallel view, where ``z`` itself is linear across the screen on a plane
    (``w_tol`` then in depth units)."""
    with np.errstate(divide="ignore"):
        w = np.where(ok, z if linear else 1.0 / np.where(ok, z, 1.0), np.nan).astype(np.float32)
    out = np.zeros(z.shape, dtype=bool)
    for axis in (0, 1):
        a = np.swapaxes(w, 0, axis)
        okx = np.swapaxes(ok, 0, axis)
        both = okx[1:] & okx[:-1]                  # a pair with an empty (or too near) pixel: a jump
        # between pixel k and k + 1; float32: ~1e-7 relative, far below w_tol
        padded = np.full((a.shape[0] + 1,) + a.shape[1:], np.nan, dtype=np.float32)
        step = padded[1:-1]
        np.subtract(a[1:], a[:-1], out=step)
        before, after = padded[:-2], padded[2:]               # the steps from k - 1 and to k + 2
        with np.errstate(invalid="ignore"):
            sloped = (step >= np.fmin(before, after) - w_tol) & (step <= np.fmax(before, after) + w_tol)
        jump = ~(both & sloped)
        o = np.swapaxes(out, 0, axis)
        o[:-1] |= jump
        o[1:] |= jump
    return out


def extended_depth(depth, camera, envelope, near_eff=0.0):
    """Per pixel, the farthest depth behind which every ray from the envelope is
    blocked, ``(s, s) float64`` view-space distance along the axis (``inf``: open).

    depth: the window-depth image of :meth:`GLRenderer.envelope_depth` from ``camera``
    (the envelope's square view; 1 = nothing drawn).  ``near_eff``: surfaces nearer
    than this cover nothing (an eye of the envelope may clip them with its near plane).
    The reference of :mod:`core.gl.gpuenvelope`, which computes the same in the same
    precision and order.

    Most images cover few pixels or none (every window wide enough for its parallax
    holds an empty pixel or a silhouette): :func:`cover_plan` bounds, on blocks of
    pixels, where and up to which window any pixel may be covered, and the windows are
    computed there only; the result is the same, pixel for pixel."""
    rows, cols = depth.shape
    out = np.full((rows, cols), np.inf)
    plan = cover_plan(depth, camera, envelope.distance, near_eff)
    if plan is None:
        return out
    (y0, y1, x0, x1), last = plan
    m = last + 3                    # a window reaches ``last`` pixels, a break's test 2 more
    ys, xs = slice(max(0, y0 - m), min(rows, y1 + m)), slice(max(0, x0 - m), min(cols, x1 + m))
    sub = _extended_depth(depth[ys, xs], camera, envelope, near_eff, (ys.start, xs.start, rows, cols), last)
    out[y0:y1, x0:x1] = sub[y0 - ys.start:y1 - ys.start, x0 - xs.start:x1 - xs.start]
    return out


BLOCK = 4                   # cover_plan's blocks: BLOCK x BLOCK pixels
PLAN_SLACK = 1e-4           # cover_plan's relative slack over the image's float32 rounding


def _need(nearest, t, h, distance, dt):
    """The window half-size (pixels) that holds the parallax of a window whose nearest
    depth is ``nearest``, at tangent distance ``t`` of its pixel; inf where none does
    (the image's rule in float64, its last factor of slack left out)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = distance / np.sqrt(nearest * nearest - distance ** 2)
        tt = t + h * dt * math.sqrt(2.0)
        denom = 1.0 - tt * ta
        r = (tt + ta) / np.where(denom > 1e-6 * (1.0 - PLAN_SLACK), denom, np.nan)
        need = ta * (1.0 + r * r) / dt + 1.0
    far_enough = nearest > distance * NEAREST_GUARD * (1.0 - PLAN_SLACK)
    return np.where(np.isfinite(need) & far_enough, need, np.inf)


def _blocks(a, reduce):
    """``reduce`` (``np.minimum`` or ``np.maximum``) over BLOCK x BLOCK blocks of ``a``,
    whose sides are multiples of BLOCK: strided rows, then columns (a reduce over the
    axes of a 4-d view is several times slower)."""
    rows = a[0::BLOCK]
    for i in range(1, BLOCK):
        rows = reduce(rows, a[i::BLOCK])
    out = rows[:, 0::BLOCK]
    for i in range(1, BLOCK):
        out = reduce(out, rows[:, i::BLOCK])
    return out


def cover_plan(depth, camera, distance, near_eff=0.0):
    """Where :func:`extended_depth` may cover a pixel of ``depth``: ``((y0, y1, x0, x1),
    last)``, the pixel rectangle outside which none is covered and the largest window
    half-size that may cover one; None when no pixel is covered.  Proven on blocks of
    ``BLOCK x BLOCK`` pixels.

    A pixel is covered at window half-size ``h`` only when its window holds no break and
    holds its parallax at the window's nearest depth.  For ``h >= BLOCK - 1`` the window
    of every pixel of a block holds the whole blocks within ``(h + 1) / BLOCK - 1`` of
    it: a break (an empty or too-near pixel) in one of them opens every pixel of the
    block, and the nearest depth over them is no nearer than the window's, so the
    parallax it needs (at the block's smallest tangent distance) is no more than any of
    its pixels needs.  Smaller windows are bounded by the lens's far depth, at the
    centre (where they may cover, the whole image is planned).  Depth jumps are breaks
    the blocks leave out: fewer breaks, a weaker test, never a wrong one.  The image's
    float32 rounds what its rule computes: the bounds pass with :data:`PLAN_SLACK` to
    spare."""
    near, far, tan_half = _lens(camera)
    rows, cols = depth.shape
    sizes = [h for h in HALF_SIZES if h < min(rows, cols)]
    if not sizes:
        return None
    dt = 2.0 * tan_half / rows

    def z_of(w):                                     # the image's own formula, increasing in w
        ndc = 2.0 * np.asarray(w, dtype=np.float64) - 1.0
        with np.errstate(divide="ignore"):
            return 2.0 * near * far / (far + near - ndc * (far - near))

    small = np.array([h for h in sizes if h < BLOCK - 1])
    if len(small) and (_need(far, 0.0, small, distance, dt) <= small * (1.0 + PLAN_SLACK)).any():
        return (0, rows, 0, cols), sizes[-1]
    br, bc = -(-rows // BLOCK), -(-cols // BLOCK)
    # the block's nearest depth, 0 where it holds a break (0 passes no test); a block the
    # border cuts holds one (a window there reaches past the border)
    nearest = np.zeros((br, bc))
    whole = np.asarray(depth)[:rows - rows % BLOCK, :cols - cols % BLOCK]
    lo, hi = _blocks(whole, np.minimum), _blocks(whole, np.maximum)
    zlo = z_of(lo)
    nearest[:lo.shape[0], :lo.shape[1]] = np.where((hi < 1.0) & (zlo > near_eff), zlo, 0.0)
    # the smallest tangent distance of a block's pixel centres
    ay = np.abs((np.arange(br * BLOCK) + 0.5) * dt - tan_half).reshape(br, BLOCK).min(axis=1)
    ax = np.abs((np.arange(bc * BLOCK) + 0.5) * dt - 0.5 * cols * dt).reshape(bc, BLOCK).min(axis=1)
    t = np.sqrt(ax[None, :] ** 2 + ay[:, None] ** 2)
    k = 0
    may = np.zeros((br, bc), dtype=bool)
    last = None
    for h in sizes:
        if h < BLOCK - 1:
            continue
        reach = (h + 1) // BLOCK - 1                  # whole blocks every pixel's window holds
        while k < reach:                              # the nearest over 2k + 1 blocks, k <= reach
            step = min(k + 1, reach - k)
            nearest = _shift(_shift(nearest, step, 0, 0.0, np.minimum), step, 1, 0.0, np.minimum)
            k += step
        cells = np.flatnonzero(nearest.ravel() > distance * NEAREST_GUARD * (1.0 - PLAN_SLACK))
        if not len(cells):
            break                                     # windows only grow: none is far enough now
        here = cells[_need(nearest.ravel()[cells], t.ravel()[cells], h, distance, dt) <= h * (1.0 + PLAN_SLACK)]
        if len(here):
            may.ravel()[here] = True
            last = h
    if last is None:
        return None
    by, bx = np.flatnonzero(may.any(axis=1)), np.flatnonzero(may.any(axis=0))
    return (int(by[0]) * BLOCK, min(rows, (int(by[-1]) + 1) * BLOCK),
            int(bx[0]) * BLOCK, min(cols, (int(bx[-1]) + 1) * BLOCK)), last


def _extended_depth(depth, camera, envelope, near_eff, window=None, last=None):
    """:func:`extended_depth` with every window computed, of ``depth`` or (``window =
    (y0, x0, rows, cols)``) of the part of a ``rows x cols`` image from pixel ``(y0,
    x0)`` that ``depth`` is, with windows up to half-size ``last``: exact where every
    such window and a break's test (2 pixels) stay within the part."""
    near, far, tan_half = _lens(camera)
    rows, cols = depth.shape
    y0, x0, full_rows, full_cols = window or (0, 0, rows, cols)
    s = min(full_rows, full_cols)
    d = depth.astype(np.float64)                       # float64 here: 1/z steps are compared below
    ok = d < 1.0
    ndc = 2.0 * d - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(ok, 2.0 * near * far / (far + near - ndc * (far - near)), np.inf)
    # a surface an eye of the envelope clips with its near plane is a hole, not a cover
    ok &= z > near_eff
    z = np.where(ok, z, np.inf)
    # tangent-plane coordinates of pixel centres; one pixel = dt of tangent
    dt = 2.0 * tan_half / full_rows                     # square pixels in tangent units
    cy = (np.arange(y0, y0 + rows) + 0.5) * dt - tan_half
    cx = (np.arange(x0, x0 + cols) + 0.5) * dt - 0.5 * full_cols * dt
    t = np.sqrt(cx[None, :] * cx[None, :] + cy[:, None] * cy[:, None]).astype(np.float32)
    brk = ~ok
    if envelope.distance > 0.0:
        brk = brk | _jumps(z, ok, slope_tolerance(near, far))
    guard = NEAREST_GUARD
    ext = np.full(z.shape, np.inf)
    zlo = np.where(ok, -z, -np.inf).astype(np.float32)  # max of -z: the nearest depth
    # the farthest depth, +inf at a break: a window's max is +inf exactly when it holds one
    # (past the border too: unknown there); a pixel is covered only from a window without
    zhi = np.where(brk, np.inf, z).astype(np.float32)
    open_ = np.ones(z.shape, dtype=bool)
    for h in HALF_SIZES:                               # each window from the one before
        if h >= s or (last is not None and h > last):
            break
        zlo = _grow(zlo, h, np.inf)
        zhi = _grow(zhi, h, np.inf)
        free = open_ & (zhi != np.inf)
        if not free.any():
            break                                      # windows only grow: no pixel can be covered now
        # -zlo > D guard, without a negated copy (negation is exact)
        cand = np.flatnonzero((free & (zlo < -np.float32(envelope.distance * guard))).ravel())
        if not len(cand):
            continue
        nearest = -zlo.ravel()[cand]
        # the parallax angle alpha = asin(D / r), bounded by tan(alpha) = D / sqrt(r^2 - D^2)
        # (tan >= the angle: a larger window, conservative); the window's angle in pixels
        # where it is widest on screen, at its outer corner (tangent T), where a tangent
        # step per radian is 1 + tan^2(atan T + alpha): all without trigonometry
        ta = envelope.distance / np.sqrt(nearest * nearest - envelope.distance ** 2)
        tt = t.ravel()[cand] + np.float32(h * dt * math.sqrt(2.0))
        denom = 1.0 - tt * ta
        fits = denom > 1e-6
        r = (tt + ta) / np.where(fits, denom, 1.0)
        need = ta * (1.0 + r * r) * (1.0 + 1e-5) / dt + 1.0      # + the pixel's own footprint; float32 slack
        good = cand[fits & (need <= h)]
        # float32 rounds the farthest depth by 6e-8 of itself: far below the depth guard
        ext.ravel()[good] = zhi.ravel()[good]
        open_.ravel()[good] = False
        if not open_.any():
            break
    return ext


def _pyramid(ext):
    """Max pyramid of an image (level k: 2^k x 2^k blocks); sizes round up."""
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


def _split8(boxes):
    """Each box ``(k, 2, 3)`` cut in half along every axis: ``(8 k, 2, 3)``, box ``i``'s
    eight halves at ``8 i .. 8 i + 7``."""
    mid = 0.5 * (boxes[:, MIN] + boxes[:, MAX])
    out = np.empty((len(boxes), 8, 2, 3))
    for j in range(8):
        bits = np.array([(j >> a) & 1 for a in range(3)], dtype=bool)
        out[:, j, MIN] = np.where(bits, mid, boxes[:, MIN])
        out[:, j, MAX] = np.where(bits, boxes[:, MAX], mid)
    return out.reshape(-1, 2, 3)


def _beyond_every_far_plane(rel, view):
    """Camera-relative boxes (grown by the envelope's distance) beyond the far plane of
    every view whose axis turns at most ``view.turn`` from this one's: a point ``r`` away,
    ``theta`` off the axis, lies at least ``r cos(theta + turn)`` deep in each; over a box,
    its nearest distance and its widest angle (at a corner: the cone within an angle is
    convex) bound that from below."""
    far = view.far * (1.0 + tol.near_guard_rel)
    out = np.zeros(len(rel), dtype=bool)
    nearest = np.linalg.norm(np.maximum(np.maximum(rel[:, MIN], -rel[:, MAX]), 0.0), axis=1)
    cand = np.flatnonzero(nearest > far)                       # only these can be (cos <= 1)
    if not len(cand):
        return out
    axis = -view.render.view[2, :3]
    c = corners(rel[cand])
    dist = np.linalg.norm(c, axis=2)                           # > 0: beyond the far distance
    theta = np.arccos(np.clip(((c @ axis) / dist).min(axis=1), -1.0, 1.0)) + view.turn
    out[cand] = (theta < 0.5 * math.pi) & (nearest[cand] * np.cos(np.minimum(theta, 0.5 * math.pi)) > far)
    return out


def classify_boxes(rel, view, levels, depth_step_at, splits=SPLITS, outside=None):
    """States of camera-relative boxes (already grown) from the envelope's
    :class:`EnvelopeView`: VISIBLE, OCCLUDED or VIEW_CULLED per box; ``levels``: the
    max pyramid of the extended depth image (:func:`_pyramid`), None where the image
    covers no pixel (the frustum's states only).  A box's pixel
    rectangle is clipped to the cull square: no view of the envelope sees past it.

    A box is tested by its nearest depth against the farthest covered depth over its
    rectangle; one that reaches behind that depth but starts before it is cut in
    eight and each half tested so (``splits`` times): a box just behind a wall seen
    at a slant is not kept for the wall's far end.  ``outside``: boxes already known to
    miss a frustum that holds the cull frustum (the render frustum's test); only the
    others are tested against it."""
    k = len(rel)
    state = np.full(k, Visibility.VISIBLE, dtype=np.uint8)
    if not k:
        return state
    outside = np.zeros(k, dtype=bool) if outside is None else outside.copy()
    rest = np.flatnonzero(~outside)
    out_rest, _ = classify(planes_from_matrix(view.cull.relative_view_projection()), rel[rest])
    outside[rest] = out_rest | _beyond_every_far_plane(rel[rest], view)
    state[outside] = Visibility.VIEW_CULLED
    if levels is None:
        return state
    clip = view.render.relative_view_projection()
    size = np.asarray(view.size, dtype=np.float64)
    near, _, _ = _lens(view.render)
    inside = np.flatnonzero(~outside)
    c = corners(rel[inside])                                 # (k, 8, 3) camera-relative
    view_rot = view.render.view[:3, :3]
    vz = -(c @ view_rot.T)[..., 2]                           # view-space depth of each corner
    zmin = vz.min(axis=1)
    front = zmin > near * (1.0 + tol.near_guard_rel)        # a box at or before the near plane is visible
    idx = inside[front]
    cc = c[front]
    h = np.concatenate([cc, np.ones(cc.shape[:2] + (1,))], axis=2) @ clip.T
    ndc = h[..., :2] / h[..., 3:4]
    lo, hi = ndc.min(axis=1), ndc.max(axis=1)
    # pixel i's footprint is [i, i + 1) of u = (ndc + 1) / 2 * size: every pixel a
    # direction of the box falls in, rounded outward
    u0 = np.floor((lo + 1.0) * 0.5 * size).astype(np.int64)
    u1 = np.floor((hi + 1.0) * 0.5 * size).astype(np.int64)
    first, last = np.array(view.lo * 2), np.array(view.hi * 2)
    rects = np.clip(np.concatenate([u0, u1], axis=1), first, last) - first    # the pyramid's pixels
    far_occ = _rect_max(levels, rects)
    zm = zmin[front]
    # ties and the depth buffer's rounding count as visible
    hidden = zm > far_occ + tol.depth_guard_steps * depth_step_at(zm)
    state[idx[hidden]] = Visibility.OCCLUDED
    if splits > 0:
        # open only in front: the far part of the box lies behind every covered depth
        retry = idx[~hidden & np.isfinite(far_occ) & (vz[front].max(axis=1) > far_occ)]
        if len(retry):
            halves = classify_boxes(_split8(rel[retry]), view, levels, depth_step_at, splits - 1)
            gone = (halves != Visibility.VISIBLE).reshape(-1, 8).all(axis=1)
            state[retry[gone]] = Visibility.OCCLUDED
    return state


def occluder_polygons(culler, eye, distance):
    """Camera-relative convex polygons ``(k, 4, 3)`` that may hide most from the ball of
    eyes of radius ``distance`` around ``eye``: of the :data:`core.umbra.OBJECTS` objects
    whose boxes score highest, the :data:`core.umbra.POLYGONS` polygons that weigh most
    (:func:`core.umbra.polygon_weights`).  An object's score bounds its polygons' weights
    from above: its box's solid angle, and its middle side for the polygons' width.
    Each mesh's polygons are found once per scene build and kept on the culler
    (:attr:`core.engine.Culler.mesh_polygons`)."""
    scene = culler.scene
    valid = np.flatnonzero(~scene.invalid)
    if not len(valid):
        return np.zeros((0, 4, 3))
    bounds = scene.bounds if len(valid) == len(scene) else scene.bounds[valid]
    lo, hi = bounds[:, MIN] - eye, bounds[:, MAX] - eye
    side = hi - lo
    gap = np.maximum(np.maximum(lo, -hi), 0.0)
    x, y, z = side.T
    middle = np.maximum(np.minimum(x, y), np.minimum(np.maximum(x, y), z))
    with np.errstate(divide="ignore", invalid="ignore"):
        score = np.einsum("ij,ij->i", side, side) / np.maximum(np.einsum("ij,ij->i", gap, gap), tol.tiny) \
            * umbra.width_factor(middle, distance)
    top = np.arange(len(score))
    if len(score) > umbra.OBJECTS:
        top = np.argpartition(-score, umbra.OBJECTS - 1)[:umbra.OBJECTS]
    objs = valid[top[np.argsort(-score[top], kind="stable")]]
    world = _polygons_of(culler, objs, eye)
    if not len(world):
        return world
    weight = umbra.polygon_weights(world, distance)
    keep = np.arange(len(world))
    if len(world) > umbra.POLYGONS:
        keep = np.argpartition(-weight, umbra.POLYGONS - 1)[:umbra.POLYGONS]
    return world[keep[np.argsort(-weight[keep], kind="stable")]]


def _polygons_of(culler, objs, eye):
    """Camera-relative convex polygons ``(p, 4, 3)`` of objects ``objs`` (their meshes'
    :func:`core.umbra.convex_polygons`, found once per scene build and kept on the culler,
    :attr:`core.engine.Culler.mesh_polygons`)."""
    scene = culler.scene
    cache = culler.mesh_polygons
    meshes = scene.mesh_of[objs]
    for mi in np.unique(meshes):
        if int(mi) not in cache:
            cache[int(mi)] = umbra.convex_polygons(*scene.meshes[int(mi)])[0]
    local = [cache[int(mi)] for mi in meshes]
    counts = np.array([len(p) for p in local], dtype=np.int64)
    if not counts.sum():
        return np.zeros((0, 4, 3))
    local = np.concatenate(local)
    m = scene.matrices[np.repeat(objs, counts)]
    # camera-relative corners: the rows of each rotation, one axis at a time (einsum's
    # general path is several times slower on (p, 4, 3))
    world = (m[:, None, :3, 3] - eye) + local[:, :, 0:1] * m[:, None, :3, 0]
    world += local[:, :, 1:2] * m[:, None, :3, 1]
    world += local[:, :, 2:3] * m[:, None, :3, 2]
    return world


FLOOR_OBJECTS = 64         # the objects nearest the eye whose faces may be the floor (floor_cut)
FLOOR_RISE = 0.25          # the cut stands this share of the eye's distance to the face in front of it


def floor_cut(culler, eye, distance):
    """The plane an envelope's eyes stay above (:attr:`Envelope.floor`), or None: the
    nearest face (its foot inside the face, the face turned towards the eye, any way it
    faces: the ground under a street view, a wall beside an interior view) that the ball of
    ``distance`` reaches through, among the convex faces of the :data:`FLOOR_OBJECTS`
    objects nearest the eye, moved towards the eye by :data:`FLOOR_RISE` of its distance
    (so no eye of the envelope stands in the floor, or within a near plane of it).  Any
    plane would be sound (the eyes beyond it are simply not the envelope's, and the caller
    checks every view against it); this one only keeps out views a user does not take."""
    scene = culler.scene
    valid = np.flatnonzero(~scene.invalid)
    if distance <= 0.0 or not len(valid):
        return None
    bounds = scene.bounds if len(valid) == len(scene) else scene.bounds[valid]
    gap = np.linalg.norm(np.maximum(np.maximum(bounds[:, MIN] - eye, eye - bounds[:, MAX]), 0.0), axis=1)
    near = np.flatnonzero(gap < distance)
    if not len(near):
        return None
    if len(near) > FLOOR_OBJECTS:
        near = near[np.argpartition(gap[near], FLOOR_OBJECTS - 1)[:FLOOR_OBJECTS]]
    polys = _polygons_of(culler, valid[near], eye)
    if not len(polys):
        return None
    away, height, ok = umbra.facing_planes(polys)             # the eye at 0, the face at height
    f = -away                                                 # from the face towards the eye
    ok &= (height > tol.near_guard_rel * distance) & (height < distance)
    foot = -height[:, None] * f
    centre = polys.mean(axis=1)
    for e in range(4):                                        # the eye's foot inside the face
        a0, a1 = polys[:, e], polys[:, (e + 1) % 4]
        edge = np.cross(a1 - a0, f)                           # in the face, across the edge
        skip = np.all(a0 == a1, axis=1)
        ok &= skip | (np.einsum("kj,kj->k", edge, foot - a0) * np.einsum("kj,kj->k", edge, centre - a0) >= 0.0)
    if not ok.any():
        return None
    i = int(np.flatnonzero(ok)[np.argmin(height[ok])])
    up = f[i]
    c = float(up @ eye) - (1.0 - FLOOR_RISE) * float(height[i])
    return (float(up[0]), float(up[1]), float(up[2]), c)


def _image_objects(culler, out_units, occluders):
    """The objects an envelope's image draws: those with a unit in its view (``out_units``:
    the units outside it), of ``occluders`` where given (``(n,) bool``), no invalid one."""
    scene = culler.scene
    shown = np.zeros(len(scene), dtype=bool)
    shown[culler.units.object[~out_units]] = True
    if occluders is not None:
        shown &= occluders
    return np.flatnonzero(shown & ~scene.invalid)


class _Tester:
    """The envelope's proof for any world boxes: the frustum of the square view, the
    extended depth image and the big polygons (built once a pass, asked twice: the
    objects' units, then the shadows of those found hidden)."""

    def __init__(self, culler, camera, envelope, height, stats, occluders=None, image=True):
        self.culler, self.envelope = culler, envelope
        self.eye = camera.eye
        self.stats = stats
        self.view = self.ext = self.levels = None
        self.polygons = self.units = None
        self.orthographic = camera.is_orthographic
        if self.orthographic:
            self.parallel = _ParallelProof(culler, camera, envelope, height, stats, occluders, image)
            return
        # an eye of the envelope clips what its near plane cuts: a point at distance r from
        # the centre eye lies at least (r - D) cos(theta) deep in the view of any eye that
        # sees along it (theta: the lens's corner angle), so nothing nearer than this
        # occludes for every eye
        near, _, _ = _lens(camera)
        self.near_eff = (envelope.distance + near / max(math.cos(corner_half_angle(camera)), 1e-6)) \
            * (1.0 + tol.near_guard_rel)
        self.view = envelope_camera(camera, envelope, height)
        if self.view is None:
            return
        ub = culler.unit_bounds()
        rel = grown_boxes(ub, self.eye, envelope.distance, culler.scene_size)
        # only what can show in the square view: the same picture, less to draw
        out_units, _ = classify(planes_from_matrix(self.view.render.relative_view_projection()), rel)
        self.units = (ub, rel, out_units)                  # the units' states reuse them
        if not image:
            stats.envelope_occluders = 0
            return
        stats.envelope_image_hidden = 0
        objects = _image_objects(culler, out_units, occluders)
        stats.envelope_occluders = int(len(objects))
        w, h = self.view.size
        renderer = culler.renderer
        tex = renderer.envelope_depth(self.view.render, (w, h), objects)
        gpu = renderer.gpu_envelope()
        if gpu is not None:
            self.ext = gpu.extended_depth(tex, _lens(self.view.render), envelope, self.near_eff, HALF_SIZES,
                                          slope_tolerance, NEAREST_GUARD)
        else:
            self.ext = extended_depth(renderer.read_texture_depth(tex), self.view.render, envelope, self.near_eff)
        stats.gl_calls = renderer.counters["gl_calls"]
        stats.blocking_reads = renderer.counters["blocking_reads"]
        (x0, y0), (x1, y1) = self.view.lo, self.view.hi
        inner = self.ext[y0:y1 + 1, x0:x1 + 1]              # the cull frustum's: rectangles read no margin
        self.levels = _pyramid(inner) if inner.min() < np.inf else None
        stats.query_rect_pixels = int(w * h)

    def unit_states(self):
        """:meth:`states` of the culler's units, from the bounds, grown boxes and render
        frustum test the image was drawn with."""
        if self.units is None:
            return self.states(self.culler.unit_bounds())
        return self.states(*self.units)

    def states(self, boxes, rel=None, outside=None):
        """VISIBLE, OCCLUDED or VIEW_CULLED for world boxes ``(k, 2, 3)`` (``rel``: their
        grown camera-relative boxes; ``outside``: those known to miss the render frustum)."""
        env = self.envelope
        if self.orthographic:
            state = self.parallel.states(boxes)
            if self.parallel.levels is not None:
                self.stats.envelope_image_hidden += int((state == Visibility.OCCLUDED).sum())
            return state
        if rel is None:
            rel = grown_boxes(boxes, self.eye, env.distance, self.culler.scene_size)
        state = np.full(len(boxes), Visibility.VISIBLE, dtype=np.uint8)
        if self.view is None:
            return state
        near, far, _ = _lens(self.view.render)

        def step(zd):
            return zd * zd * (far - near) / (near * far * 2.0 ** tol.depth_bits)

        state = classify_boxes(rel, self.view, self.levels, step, outside=outside)
        if self.levels is not None:
            self.stats.envelope_image_hidden += int((state == Visibility.OCCLUDED).sum())
        if env.distance > 0.0:
            test = np.flatnonzero(state == Visibility.VISIBLE)
            if self.polygons is None:
                self.polygons = occluder_polygons(self.culler, self.eye, env.distance)
            rel_test = boxes[test] - self.eye
            # the display's depth buffer rounds: a box just behind a polygon's plane can show
            # through it.  Along any ray of the square view a gap g along the plane's normal
            # is at least g cos(corner angle) deep, so the gap must pass the rounding at the
            # box's farthest depth over that
            reach = np.linalg.norm(np.maximum(np.abs(rel_test[:, MIN]), np.abs(rel_test[:, MAX])), axis=1)
            guard = tol.depth_guard_steps * step(reach + env.distance) / math.cos(corner_half_angle(self.view.cull))
            cut = None
            if env.floor is not None:                           # the eyes kept above a floor
                up = np.array(env.floor[:3])
                cut = (up, env.floor[3] - float(up @ self.eye))
            hidden = hidden_by_polygons(rel_test, self.polygons, env.distance, self.near_eff, guard, cut)
            state[test[hidden]] = Visibility.OCCLUDED
        return state


def ortho_lens(camera):
    """``(near, far, (l, r, b, t))`` of an orthographic projection: the view-space depths of
    its clip planes and its window in view-space units (lens shift included)."""
    p = camera.projection
    near, far = (p[2, 3] + 1.0) / p[2, 2], (p[2, 3] - 1.0) / p[2, 2]
    xs = sorted(((-1.0 - p[0, 3]) / p[0, 0], (1.0 - p[0, 3]) / p[0, 0]))
    ys = sorted(((-1.0 - p[1, 3]) / p[1, 1], (1.0 - p[1, 3]) / p[1, 1]))
    return float(min(near, far)), float(max(near, far)), (float(xs[0]), float(xs[1]), float(ys[0]), float(ys[1]))


def _ortho_matrix(left, r, b, t, near, far):
    """glOrtho of the view-space window ``left .. r`` by ``b .. t``."""
    p = np.eye(4)
    p[0, 0], p[0, 3] = 2.0 / (r - left), -(r + left) / (r - left)
    p[1, 1], p[1, 3] = 2.0 / (t - b), -(t + b) / (t - b)
    p[2, 2], p[2, 3] = -2.0 / (far - near), -(far + near) / (far - near)
    return p


def parallel_near(near, distance, lateral, turn):
    """The view-space depth (in the centre view) that a surface must pass to be drawn by
    every view of a parallel envelope: a view whose eye moved by ``distance`` and whose
    direction turned by ``theta <= turn`` (radians) sees a point at depth ``z`` and
    ``lateral`` from the axis at least ``z cos(theta) - lateral sin(theta) - distance``
    deep, which must pass ``near``: ``z >= (c + lateral sin(theta)) / cos(theta)`` with ``c
    = near + distance``, largest at ``theta = turn`` or, for ``c < 0``, where its slope
    ``lateral + c sin(theta)`` turns (``sin(theta) = lateral / -c``), at ``-sqrt(c^2 - lateral^2)``."""
    c = near + distance
    best = max(c, (c + lateral * math.sin(turn)) / math.cos(turn))
    if c < 0.0 and lateral < -c and lateral / -c < math.sin(turn):
        best = max(best, -math.sqrt(c * c - lateral * lateral))
    return best


class _ParallelProof:
    """The envelope's proof for an orthographic view.  Rays of a parallel view do not
    depend on its eye: a view of the envelope (eye moved by ``D``, direction turned by
    ``theta <= A``) sees a point ``x`` along the ray from ``x`` in a direction within ``A``
    of the centre view's, which drifts across the centre image by ``tan(theta)`` per unit
    of depth.  Where the first-hit surface is continuous (no break, :func:`_jumps`) over a
    window of half-size ``h`` pixels around ``x``'s pixel, the ray from ``x`` stays inside
    the window until it is ``(h - 1/2) px / tan(A)`` nearer than ``x``; a point behind the
    surface (beyond the farthest depth of its pixel's 3 x 3 window) and no farther than
    that beyond the window's nearest depth is blocked: its ray starts behind the surface
    and is in front of it before it leaves the window.  So per pixel the image gives an
    interval of depths a point is hidden in, and a box is hidden when its depth range lies
    inside the interval of every pixel its rectangle touches.  The eye's move changes no
    ray: it moves the frustum and the near plane (:func:`parallel_near`).  A box outside
    every view's frustum (grown by ``D`` and what the turn moves its farthest corner) is
    VIEW_CULLED; one whose rectangle leaves the image is VISIBLE."""

    def __init__(self, culler, camera, envelope, height, stats, occluders=None, image=True):
        self.culler, self.envelope = culler, envelope
        self.eye = camera.eye
        self.rot = camera.view[:3, :3]
        self.levels = None
        near, far, (left, r, b, t) = ortho_lens(camera)
        self.near, self.far = near, far
        turn = math.radians(envelope.angle_deg)
        self.chord = 2.0 * math.sin(0.5 * turn)            # how far a turn moves a point, per unit of its distance
        if envelope.any_roll:                               # rolled about the axis: the window's disc
            reach = max(math.hypot(x, y) for x in (left, r) for y in (b, t))
            self.frame = (-reach, reach, -reach, reach)
        else:
            self.frame = (left, r, b, t)
        self.orthonormal = bool(np.allclose(self.rot @ self.rot.T, np.eye(3), atol=1e-9))
        if not (image and self.orthonormal) or not (far > near) or not (t > b and r > left):
            return
        px = (t - b) / max(int(height), 1)                 # the query's pixel, in view-space units
        margin = px * max(MARGIN_PX, math.ceil(MARGIN_REL * height))
        left, r, b, t = left - margin, r + margin, b - margin, t + margin
        px = max(px, (r - left) / MAX_SIDE, (t - b) / MAX_SIDE)
        w, h = max(1, math.ceil((r - left) / px)), max(1, math.ceil((t - b) / px))
        r, t = left + w * px, b + h * px                    # whole pixels
        self.window, self.px, self.size = (left, r, b, t), px, (w, h)
        lateral = max(math.hypot(x, y) for x in (left, r) for y in (b, t))
        n_eff = parallel_near(near, envelope.distance, lateral, turn)
        self.near_eff = n_eff + tol.near_guard_rel * (abs(n_eff) + (far - near))
        self.step = tol.depth_guard_steps * (far - near) / 2.0 ** tol.depth_bits
        image_cam = Camera(camera.view, _ortho_matrix(left, r, b, t, near, far))
        out_units, _ = classify(planes_from_matrix(image_cam.relative_view_projection()),
                                culler.unit_bounds() - self.eye)
        objects = _image_objects(culler, out_units, occluders)
        stats.envelope_occluders = int(len(objects))
        stats.envelope_image_hidden = 0
        renderer = culler.renderer
        depth = renderer.read_texture_depth(renderer.envelope_depth(image_cam, (w, h), objects))
        stats.gl_calls = renderer.counters["gl_calls"]
        stats.blocking_reads = renderer.counters["blocking_reads"]
        stats.query_rect_pixels = int(w * h)
        lo, hi = self._intervals(depth, turn)
        if (hi > lo).any():
            self.levels = (_pyramid(lo), _pyramid(-hi))

    def _intervals(self, depth, turn):
        """Per pixel ``(lo, hi)``: a point of the pixel deeper than ``lo`` and no deeper
        than ``hi`` is hidden from every view of the envelope (``lo = inf``: none is)."""
        near, far = self.near, self.far
        rows, cols = depth.shape
        d = depth.astype(np.float64)
        ok = d < 1.0
        z = near + d * (far - near)                        # linear in the window depth
        ok &= z > self.near_eff                            # clipped by a near plane of the envelope: a hole
        # a turned ray, or a pixel centre of another grid (a rolled or moved view), may pass
        # between two surfaces that meet at a jump
        brk = ~ok | _jumps(z, ok, self.step, linear=True)
        per_px = self.px / math.tan(turn) if turn > 0.0 else math.inf
        far_ = np.where(brk, np.inf, z).astype(np.float32)   # a window's farthest depth, inf where it breaks
        near_ = np.where(ok, -z, -np.inf).astype(np.float32)  # a window's nearest depth, negated
        lo, hi = None, np.full(z.shape, -np.inf)
        for h in HALF_SIZES:
            if h >= min(rows, cols):
                break
            far_ = _grow(far_, h, np.inf)
            near_ = _grow(near_, h, np.inf)
            if lo is None:
                lo = far_.astype(np.float64)                 # the 3 x 3 window: the surface at the pixel
            free = far_ != np.inf
            if not free.any():
                break
            with np.errstate(invalid="ignore"):
                cover = -near_.astype(np.float64) + (h - 0.5) * per_px
            np.maximum(hi, np.where(free, cover, -np.inf), out=hi)
            if per_px == math.inf:
                break                                      # no turn: any unbroken window covers every depth
        if lo is None:
            lo = np.full(z.shape, np.inf)
        return lo, hi

    def states(self, boxes, splits=SPLITS):
        """VISIBLE, OCCLUDED or VIEW_CULLED for world boxes ``(k, 2, 3)``."""
        k = len(boxes)
        state = np.full(k, Visibility.VISIBLE, dtype=np.uint8)
        if not k or not self.orthonormal:
            return state
        env = self.envelope
        rel = boxes - self.eye
        c = corners(rel) @ self.rot.T                      # view space: x, y across, -z deep
        mag = np.abs(rel).max(axis=(1, 2))
        grow = tol.box_grow_rel * mag + tol.box_grow_scene * self.culler.scene_size
        lo = c.min(axis=1) - grow[:, None]
        hi = c.max(axis=1) + grow[:, None]
        d0, d1 = -hi[:, 2], -lo[:, 2]
        # every view of the envelope: the eye moved by D, the frame turned by A
        g = env.distance + self.chord * (np.linalg.norm(c, axis=2).max(axis=1) + env.distance) + grow
        fl, fr, fb, ft = self.frame
        outside = (hi[:, 0] + g < fl) | (lo[:, 0] - g > fr) | (hi[:, 1] + g < fb) | (lo[:, 1] - g > ft) \
            | (d1 + g < self.near) | (d0 - g > self.far)
        state[outside] = Visibility.VIEW_CULLED
        if self.levels is None:
            return state
        left, _, b, _ = self.window
        w, h = self.size
        u0 = np.floor((lo[:, :2] - (left, b)) / self.px).astype(np.int64)
        u1 = np.floor((hi[:, :2] - (left, b)) / self.px).astype(np.int64)
        inside = ~outside & (u0 >= 0).all(axis=1) & (u1[:, 0] < w) & (u1[:, 1] < h)
        idx = np.flatnonzero(inside)
        rects = np.concatenate([u0[idx], u1[idx]], axis=1)
        behind = _rect_max(self.levels[0], rects)           # the surface's farthest depth over the box
        within = -_rect_max(self.levels[1], rects)          # how deep behind it every pixel still hides
        guard = 2.0 * self.step                             # this image's rounding and the display's
        hidden = (d0[idx] > behind + guard) & (d1[idx] <= within - guard)
        state[idx[hidden]] = Visibility.OCCLUDED
        if splits > 0:
            retry = idx[~hidden & np.isfinite(behind) & (within > -np.inf)]
            if len(retry):
                halves = self.states(_split8(boxes[retry]), splits - 1)
                gone = (halves != Visibility.VISIBLE).reshape(-1, 8).all(axis=1)
                state[retry[gone]] = Visibility.OCCLUDED
        return state


class ImageSchedule:
    """Which envelope passes draw the image.  The image proves what the big polygons do
    not (occluders fused from many objects, non-convex ones) where a surface is
    continuous over a window wider than its parallax; in many views it covers no pixel
    and its draw is most of the pass (the city at 4,30 on llvmpipe: 87 of 120 ms).  A
    pass without it proves less, never more: it is sound.  After a pass whose image hid
    nothing, the next ``wait`` passes go without (1, 2, 4 up to :data:`MAX_WAIT`); one
    that hides something, a fresh pass or a new scene draws it again every pass.  A pass
    that may not probe (during motion, where a pass's time sizes the next envelopes)
    draws it only while the last image hid something, and counts no wait down."""

    MAX_WAIT = 8

    def __init__(self):
        self.wait = self.left = 0

    def draws(self, probe=True):
        """Whether the next pass draws the image (and counts it as asked)."""
        if not probe:
            return self.wait == 0
        if self.left > 0:
            self.left -= 1
            return False
        return True

    def drew(self, hidden):
        """The image of the pass just made proved ``hidden`` units hidden."""
        self.wait = 0 if hidden else min(max(1, 2 * self.wait), self.MAX_WAIT)
        self.left = self.wait

    def reset(self):
        self.wait = self.left = 0


def envelope_pass(culler, camera, envelope, display=None, lights=None, occluders=None, image=True):
    """States ``(n,) uint8`` and stats of the objects of ``culler``'s scene for every
    view of ``envelope`` around ``camera`` (see the module doc).  ``lights``
    (:class:`core.lights.Light`): an object stays VISIBLE while its shadow from one
    of them may fall on something seen (its shadow volume's box is tested as an
    object's box is; :func:`core.lights.shadow_boxes`).

    ``occluders``: ``(n,) bool``, the objects drawn into the envelope's image (default
    every one; the engine passes what its last envelope pass did not prove hidden).
    Any subset is sound: the proofs use only surfaces that were drawn, and every drawn
    surface is real; an object left out only lets what stands behind it show, so the
    pass hides less, never more.  An object proven hidden from every view of the last
    envelope adds no first-hit pixel from a view inside it, so leaving it out costs
    nothing there and saves most of the draw (the city: 0.32 s of 1.1 s).  ``image``:
    False leaves the image out (the frustum and the polygons prove alone;
    :class:`ImageSchedule`)."""
    t0 = time.perf_counter()
    scene = culler.scene
    n = len(scene)
    stats = PassStats()
    height = (display or culler.display or culler.resolution)[1]
    tester = _Tester(culler, camera, envelope, height, stats, occluders, image)
    valid_units = ~scene.invalid[culler.units.object]
    unit_state = tester.unit_states()
    unit_state[~valid_units] = Visibility.VISIBLE
    state = np.full(n, Visibility.VIEW_CULLED, dtype=np.uint8)
    np.minimum.at(state, culler.units.object, unit_state)     # an object: the most visible of its units
    state[scene.invalid] = Visibility.VISIBLE
    stats.queries = int(len(unit_state))
    if lights:
        hidden = np.flatnonzero(state != Visibility.VISIBLE)
        boxes, owner = shadow_boxes(scene.bounds[hidden], in_world(lights, camera, envelope.angle_deg),
                                    culler.scene_bounds())
        shows = tester.states(boxes) == Visibility.VISIBLE
        casters = hidden[np.unique(owner[shows])]
        state[casters] = Visibility.VISIBLE
        stats.shadow_boxes = int(len(boxes))
        stats.shadow_casters_kept = int(len(casters))
    for other in envelope.also:                # hidden only where hidden for each camera
        twin = replace(envelope, also=(), floor=None, above_floor=False)
        state = np.minimum(state, envelope_pass(culler, other, twin, display, lights, occluders, image)[0])
    stats.total_ms = stats.cpu_ms = 1e3 * (time.perf_counter() - t0)
    stats.invalid_objects = int(scene.invalid.sum())
    stats.envelope_distance = envelope.distance
    stats.envelope_angle_deg = envelope.angle_deg
    stats.envelope_any_roll = envelope.any_roll
    return state, stats


def sample_views(camera, envelope, count, rng):
    """``count`` random views of the envelope around a look-at ``camera``: eyes
    uniform in the ball (above its floor, if it has one), directions uniform in the
    cone and any roll (or, with ``any_roll=False``, the frame turned about a random axis
    by up to the angle); the same projection (for tests and the motion benchmark)."""
    eye, d = camera.eye, camera.direction
    r = camera.view[:3, :3]
    out = []
    for _ in range(count):
        for _ in range(64):                          # an eye above the floor (the centre is)
            v = rng.normal(size=3)
            v *= envelope.distance * rng.random() ** (1.0 / 3.0) / max(np.linalg.norm(v), tol.tiny)
            if envelope.height(eye + v) >= 0.0:
                break
        else:
            v = np.zeros(3)
        a = math.radians(envelope.angle_deg) * math.sqrt(rng.random())
        axis = np.cross(d, rng.normal(size=3))
        axis /= max(np.linalg.norm(axis), tol.tiny)
        if envelope.any_roll:
            rot = _rotation(axis, a) @ _rotation(d, math.pi * (2.0 * rng.random() - 1.0))
        else:
            axis = rng.normal(size=3)
            rot = _rotation(axis / max(np.linalg.norm(axis), tol.tiny), math.radians(envelope.angle_deg) * rng.random())
        world = rot @ r.T                                # camera axes in world space, turned
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


__all__ = ["Envelope", "EnvelopeView", "ImageSchedule", "envelope_pass", "envelope_camera", "extended_depth",
           "floor_cut", "sample_views", "corner_half_angle"]
