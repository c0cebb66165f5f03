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

from .bounds import MAX, MIN

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


def _sun_bounds(direction, half_angle):
    """Largest and smallest component of a unit vector within ``half_angle`` of
    ``direction`` along each axis: ``(3,)`` each."""
    theta_pos = np.arccos(np.clip(direction, -1.0, 1.0))      # angle to +axis
    theta_neg = np.pi - theta_pos                               # angle to -axis
    up = np.cos(np.maximum(theta_pos - half_angle, 0.0))
    down = -np.cos(np.maximum(theta_neg - half_angle, 0.0))
    return up, down


def _emitter_bounds(boxes, position, radius):
    """For rays from any point of the ball ``B(position, radius)`` through any point of
    each box: bounds on each component of their unit direction, ``(n, 3)`` largest
    and smallest, and whether the ball touches the box (no bound then)."""
    near = np.maximum(np.maximum(boxes[:, MIN] - position, position - boxes[:, MAX]), 0.0)
    dmin = np.linalg.norm(near, axis=1) - radius                 # nearest emitter-box distance
    far = np.maximum(np.abs(boxes[:, MIN] - position), np.abs(boxes[:, MAX] - position))
    dmax = np.linalg.norm(far, axis=1) + radius                  # farthest
    top = boxes[:, MAX] - (position - radius)                    # largest p_i - L'_i
    bottom = boxes[:, MIN] - (position + radius)                 # smallest
    touch = dmin <= 0.0
    safe = np.where(touch, 1.0, dmin)[:, None]
    # a positive numerator is largest over the smallest length, a negative one over the largest
    up = np.where(top > 0, top / safe, top / dmax[:, None])
    down = np.where(bottom < 0, bottom / safe, bottom / dmax[:, None])
    return np.clip(up, -1.0, 1.0), np.clip(down, -1.0, 1.0), touch


def _swept(boxes, up, down, lo, hi, cap):
    """Boxes swept along every direction whose components lie in ``[down, up]``
    (``(n, 3)`` or ``(3,)``) until they leave the box ``lo, hi``: the sweep is no
    longer than the distance to the wall the directions all head for, over their
    slowest speed towards it (at most ``cap``)."""
    up = np.broadcast_to(up, boxes[:, MIN].shape)
    down = np.broadcast_to(down, boxes[:, MIN].shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_pos = np.where(down > 0, (hi - boxes[:, MIN]) / down, np.inf)     # all head for the +wall
        t_neg = np.where(up < 0, (boxes[:, MAX] - lo) / -up, np.inf)       # all head for the -wall
    t = np.minimum(np.minimum(t_pos, t_neg).min(axis=1), cap)
    grow_hi = t[:, None] * np.maximum(up, 0.0)
    grow_lo = t[:, None] * np.minimum(down, 0.0)
    return np.stack([boxes[:, MIN] + grow_lo, boxes[:, MAX] + grow_hi], axis=1)


def shadow_boxes(boxes, lights, scene_box):
    """Boxes that hold each box's shadow volume from each light, clipped to
    ``scene_box`` ``(2, 3)`` (where anything a shadow can fall on stands): returns
    ``(m, 2, 3)`` boxes and ``(m,)`` the index of the box each belongs to.

    Every ray of the light through the box has a unit direction whose components lie
    in bounds (:func:`_sun_bounds`: a sun's disc; :func:`_emitter_bounds`: rays from
    any point of a spherical emitter through any point of the box).  Along an axis
    where they all have one sign, every ray leaves the scene box within the distance
    to that wall over the slowest speed; the shadow lies within the box swept that
    far along the component bounds (:func:`_swept`).  An emitter touching the box
    shadows the whole scene box; a box beyond a light's reach casts nothing from it.
    Conservative by construction: no point of a shadow lies outside its box."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    sb = np.asarray(scene_box, dtype=np.float64)
    n = len(b)
    out, owner = [], []
    if not n or not lights:
        return np.zeros((0, 2, 3)), np.zeros(0, dtype=np.int64)
    lo = np.minimum(sb[MIN], b[:, MIN].min(axis=0))
    hi = np.maximum(sb[MAX], b[:, MAX].max(axis=0))
    cap = float(np.linalg.norm(hi - lo)) * (1.0 + 1e-6) + 1e-9      # no segment in the scene box is longer
    idx = np.arange(n)
    for light in lights:
        if light.kind == "everywhere":
            out.append(np.repeat(np.array([lo, hi])[None], n, axis=0))
            owner.append(idx)
            continue
        if light.kind == "sun":
            up, down = _sun_bounds(light.direction, 0.5 * light.angle)
            box = _swept(b, up, down, lo, hi, cap)
            keep = idx
        else:
            gap = np.maximum(np.maximum(b[:, MIN] - light.position, light.position - b[:, MAX]), 0.0)
            keep = np.flatnonzero(np.linalg.norm(gap, axis=1) <= light.reach + light.radius)
            if not len(keep):
                continue
            up, down, touch = _emitter_bounds(b[keep], light.position, light.radius)
            box = _swept(b[keep], up, down, lo, hi, cap)
            box[touch] = np.array([lo, hi])
        box = np.stack([np.maximum(box[:, MIN], lo), np.minimum(box[:, MAX], hi)], axis=1)
        out.append(box)
        owner.append(keep)
    if not out:
        return np.zeros((0, 2, 3)), np.zeros(0, dtype=np.int64)
    return np.concatenate(out), np.concatenate(owner)
