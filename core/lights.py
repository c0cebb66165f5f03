"""Shadow volumes: how a hidden object can still show, through its shadow.

In a mode lit by scene lights an object also shows through its shadow.  Its shadow
falls only inside its *shadow volume* (the points behind its box as seen from some
point of the light's emitter), and shows only where that volume holds a point that
is seen.  :func:`shadow_boxes` bounds each volume by a box, clipped to the scene's
box (nothing stands outside it for a shadow to fall on); the engine then tests that
box exactly as it tests an object's box (:func:`core.envelope.envelope_pass`): an
object stays while one of its shadow boxes may be seen.  That is shadow-caster
culling from the view's side (Bittner et al. 2011 test the same volumes against the
view): a caster outside the view whose shadow falls in it stays, and one behind a
wall whose shadow falls only behind that wall goes.

A light reaches no farther than ``reach`` (Blender's custom distance): a box beyond
it casts nothing from that light.  A light from every direction (a world that
extracts a sun from an image) shadows the whole scene box from every object.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from .bounds import MAX, MIN, corners

KINDS = ("sun", "point", "spot", "area", "everywhere")


@dataclass(frozen=True)
class Light:
    """One light: ``kind`` of :data:`KINDS`; ``position`` ``(3,)`` world (point, spot,
    area); ``direction`` ``(3,)`` the way its light travels (sun); ``radius`` of the
    emitter (point, spot, area: half its diagonal); ``angle`` the sun's angular
    diameter (radians); ``reach``: farthest lit distance (``inf``: no limit);
    ``in_view``: the sun's direction is given in view space (x right, y up, z towards
    the viewer) and turns with the view, as Workbench's studio light does."""

    kind: str
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -1.0]))
    radius: float = 0.0
    angle: float = 0.0
    reach: float = math.inf
    in_view: bool = False

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"light kind must be one of {KINDS}, got {self.kind!r}")
        object.__setattr__(self, "position", np.asarray(self.position, dtype=np.float64).reshape(3))
        d = np.asarray(self.direction, dtype=np.float64).reshape(3)
        norm = np.linalg.norm(d)
        object.__setattr__(self, "direction", d / norm if norm > 0 else np.array([0.0, 0.0, -1.0]))


def in_world(lights, camera, turn_deg=0.0):
    """``lights`` with view-space suns (``in_view``) turned into world space for
    ``camera``, their disc widened by ``2 turn_deg`` (a view that turns that far turns
    them with it)."""
    rot = np.asarray(camera.view, dtype=np.float64)[:3, :3]
    out = []
    for light in lights:
        if light.kind == "sun" and light.in_view:
            light = Light("sun", direction=rot.T @ light.direction,
                          angle=light.angle + 2.0 * math.radians(turn_deg), reach=light.reach)
        out.append(light)
    return out


# Margins: a plane test rejects only beyond this fraction of the magnitudes involved.
REL = 1e-9


def _exit(c, direction, lo, hi):
    """How far each corner ``c`` ``(n, 8, 3)`` goes along ``direction`` (``(3,)`` or
    ``(n, 8, 3)``, unit) before it leaves the box ``lo, hi``, ``(n, 8)``, at least 0:
    past that no shadow falls on anything."""
    d = np.broadcast_to(direction, c.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_hi = np.where(d > 0, (hi - c) / d, np.inf)
        t_lo = np.where(d < 0, (lo - c) / d, np.inf)
    t = np.minimum(t_hi, t_lo).min(axis=2)
    return np.maximum(t, 0.0) * (1.0 + 1e-6) + 1e-9


def shadow_boxes(boxes, lights, scene_box):
    """Boxes that hold each box's shadow volume from each light, clipped to
    ``scene_box`` ``(2, 3)`` (where anything a shadow can fall on stands): returns
    ``(m, 2, 3)`` boxes and ``(m,)`` the index of the box each belongs to.

    Sun: the box swept along the light's direction until it leaves the scene box,
    grown sideways by the sweep's length times the sine of half the sun's disc.
    Point, spot, area (an emitter of radius ``r`` at ``L``): every corner ``c`` swept
    from ``c`` along ``c - L`` as far, grown by the spread of rays from the emitter's
    other points, ``T r / (d - r)`` (``d``: the box's distance from ``L``); a box the
    emitter touches shadows the whole scene box.  A box beyond a light's reach casts
    nothing from it.  Every shadow volume lies in its box: conservative."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    sb = np.asarray(scene_box, dtype=np.float64)
    n = len(b)
    out, owner = [], []
    if not n or not lights:
        return np.zeros((0, 2, 3)), np.zeros(0, dtype=np.int64)
    lo = np.minimum(sb[MIN], b[:, MIN].min(axis=0))
    hi = np.maximum(sb[MAX], b[:, MAX].max(axis=0))
    # per box, the farthest any of its points is from any point of the scene box:
    # a sweep that long leaves the scene box whatever the direction
    reach_out = np.maximum(np.abs(hi - b[:, MIN]), np.abs(b[:, MAX] - lo))
    sweep_all = np.linalg.norm(reach_out, axis=1) * (1.0 + 1e-6) + 1e-9
    c = corners(b)                                                  # (n, 8, 3)
    idx = np.arange(n)
    for light in lights:
        if light.kind == "everywhere":
            box = np.repeat(np.array([lo, hi])[None], n, axis=0)
            out.append(box)
            owner.append(idx)
            continue
        if light.kind == "sun":
            # the sun's disc turns the sweep by up to half its angle: a little longer at most
            t = np.minimum(_exit(c, light.direction, lo, hi) / max(math.cos(0.5 * light.angle), 1e-3),
                           sweep_all[:, None])
            far = c + t[..., None] * light.direction
            sweep = t.max(axis=1)
            # the sun's disc: directions within half its angle, a sideways spread
            grow = (sweep * math.sin(0.5 * light.angle) + REL * sweep)[:, None]
            ends = np.concatenate([c, far], axis=1)
            box = np.stack([ends.min(axis=1) - grow, ends.max(axis=1) + grow], axis=1)
            keep = idx
        else:
            gap = np.maximum(np.maximum(b[:, MIN] - light.position, light.position - b[:, MAX]), 0.0)
            dist = np.linalg.norm(gap, axis=1)
            keep = np.flatnonzero(dist <= light.reach + light.radius)
            if not len(keep):
                continue
            cc = c[keep]
            ray = cc - light.position
            length = np.linalg.norm(ray, axis=2, keepdims=True)
            with np.errstate(divide="ignore", invalid="ignore"):
                unit = np.where(length > 0.0, ray / length, 0.0)
            t = np.minimum(_exit(cc, unit, lo, hi), sweep_all[keep][:, None])
            ends = np.concatenate([cc, cc + t[..., None] * unit], axis=1)
            d = dist[keep]
            sw = t.max(axis=1)
            # rays from the emitter's other points turn by up to asin(r / d): that far sideways
            with np.errstate(divide="ignore"):
                spread = np.where(d > light.radius, sw * light.radius / np.maximum(d - light.radius, 1e-300),
                                  np.inf)
            grow = spread + REL * sw
            box = np.stack([ends.min(axis=1) - grow[:, None], ends.max(axis=1) + grow[:, None]], axis=1)
            touching = ~np.isfinite(spread)
            box[touching] = np.array([lo, hi])
        box = np.stack([np.maximum(box[:, MIN], lo), np.minimum(box[:, MAX], hi)], axis=1)
        out.append(box)
        owner.append(keep)
    if not out:
        return np.zeros((0, 2, 3)), np.zeros(0, dtype=np.int64)
    return np.concatenate(out), np.concatenate(owner)
