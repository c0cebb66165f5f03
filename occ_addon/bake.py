"""Baked shots: per frame of the scene camera's animation, what a pass from that camera
hides, computed once (Bake Shot) and applied as the frame changes (Use Baked Shot).

**The bake.**  Every frame of the range is culled as a new engine's first pass from the
scene camera at the render resolution, by the pass's own rule (:mod:`.policy`: dynamic
objects, "never cull" and the exclusion collection are never hidden; under the render
engine's lights a shadow caster of what is seen stays; under ray tracing nothing is
hidden unless the user opted in), with the envelope (:mod:`..core.envelope`) of every
view the camera takes within the frame: the camera sampled every quarter frame from
the frame to the next one, and back over the motion-blur shutter where the render
blurs, the envelope widened by a quarter of itself for the path between samples.  A
lens that changes within the frame, or a turn too wide, keeps everything.  Only an
object that is occluded and lies wholly inside the frame, at every sample, is
recorded: a camera view also draws past the frame (the passepartout), where nothing
was tested.

**Storage** (``scene.occ_bake``, saved with the file; an undo step): per frame a bitset
over stable object numbers (``Object.occ_bake_id``, written by the bake in bulk, kept by
renames, saves and undo).  An object without a number (added after the bake) or one
that shares its number (a duplicate made after the bake: which one is the original
cannot be told) is never hidden.  XOR of consecutive frames, zlib, base64.

**Staleness.**  A bake holds for the scene it was made from: the fingerprint of what it
read (every object that took part: its number, its geometry, its transform where it
does not move by itself; the lights; the settings and the render size) and the camera
of every frame.  An edit of a transform or a geometry makes it stale at once; any
other change, an undo or a file load makes it unknown until checked again (the next
frame change, or a timer right after the change).  The camera is compared at every
frame it is applied.  A stale bake hides nothing, and what it hid is shown at once.

**Playback.**  The frame's set is applied from the frame-change handler (before the
frame draws) through the add-on's own channels (:mod:`.visibility`): in a window, in
the 3D view that looks through the scene camera (its local-view bits); headless,
everywhere (``hide_viewport``) unless "Hide In" is This View.  Never during a render
(the frame-change handler runs on the render thread there), never with live mode on.
A view that stops looking through the camera shows everything before it redraws, and
so does one whose shading changes (checked again at the next frame: a view whose own
shading draws shadows or lights the render does not hides nothing baked).
"""

import base64
import hashlib
import math
import time
import zlib
from collections.abc import Generator
from dataclasses import dataclass

import bpy
import numpy as np
from bpy.app.handlers import persistent
from bpy.props import BoolProperty, IntProperty, PointerProperty, StringProperty

from ..core import OccError, Visibility, repeatable
from ..core.bounds import transform_boxes
from ..core.camera import Camera, view_change
from ..core.envelope import covering
from ..core.frustum import classify, planes_from_matrix
from ..core.playback import PlaybackCost
from . import analysis, identity, localview, policy, visibility
from .cameras import scene_camera, shading_look, through_scene_camera
from .drawn import hidden_by_own_keys, rendered_by_collections
from .fingerprints import _mesh_fingerprint
from .identity import ident
from .kinds import is_dynamic, render_geometry
from .materials import see_through
from .props import settings_key
from .session import SESSION, rendering
from .shading import key as shading_key
from .shading import rule as rule_of
from .shading import view_rule
from .worker import Progress

BAKE_ID = "occ_bake_id"
STEP = 0.25          # the camera is sampled this often within a frame (in frames) ...
WIDEN = 0.25         # ... and the envelope of the samples widened by this share of itself
# the stored camera against the frame's: float32 transforms evaluated twice agree to this
CAMERA_TOLERANCE = 1e-6


class OccBake(bpy.types.PropertyGroup):
    # no update callbacks (see props.OccSettings): the operators apply what changes
    use: BoolProperty(name="Use Baked Shot", default=False,
                      description="Apply the baked frame's hiding as the frame changes (the camera view)")
    frame_start: IntProperty(default=0, options={"HIDDEN"})
    frame_end: IntProperty(default=-1, options={"HIDDEN"})
    width: IntProperty(default=0, options={"HIDDEN"})
    hidden: StringProperty(default="", options={"HIDDEN"})
    cameras: StringProperty(default="", options={"HIDDEN"})
    envelopes: StringProperty(default="", options={"HIDDEN"})
    held: StringProperty(default="", options={"HIDDEN"})
    fingerprint: StringProperty(default="", options={"HIDDEN"})
    summary: StringProperty(default="", options={"HIDDEN"})
    camera_digest: StringProperty(default="", options={"HIDDEN"})   # the camera's path when baked
    render_keys: StringProperty(default="", options={"HIDDEN"})     # Apply to Render wrote keys for this
    render_note: StringProperty(default="", options={"HIDDEN"})     # why they were removed
    shares: StringProperty(default="", options={"HIDDEN"})          # per frame, the share of triangles hidden


# --- storage -------------------------------------------------------------------------

def _pack(data: bytes) -> str:
    return base64.b64encode(zlib.compress(data, 6)).decode("ascii")


def _unpack(text: str) -> bytes:
    return zlib.decompress(base64.b64decode(text.encode("ascii")))


def encode_frames(hidden: np.ndarray) -> str:
    """``(frames, width) bool`` -> text: each row XOR the one before, bit-packed."""
    rows = np.asarray(hidden, dtype=bool)
    delta = rows.copy()
    delta[1:] ^= rows[:-1]
    return _pack(np.packbits(delta, axis=1).tobytes())


def decode_frames(text: str, frames: int, width: int) -> np.ndarray:
    if frames <= 0 or width <= 0:
        return np.zeros((max(frames, 0), max(width, 0)), dtype=bool)
    packed = np.frombuffer(_unpack(text), dtype=np.uint8).reshape(frames, -1)
    delta = np.unpackbits(packed, axis=1, count=width).astype(bool)
    return np.logical_xor.accumulate(delta, axis=0)


def decode_cameras(text: str, frames: int) -> np.ndarray:
    """``(frames, 2, 4, 4)``: each frame's view and projection."""
    return np.frombuffer(_unpack(text), dtype="<f8").reshape(frames, 2, 4, 4)


@dataclass
class Baked:
    """A bake decoded: frames ``start .. end``, per frame the numbers it hides, the
    cameras, the numbers that took part."""

    start: int
    end: int
    hidden: np.ndarray          # (frames, width) bool
    cameras: np.ndarray         # (frames, 2, 4, 4)
    held: np.ndarray            # (width,) bool
    envelopes: np.ndarray       # (frames, 2): each frame's envelope (move, turn); -1: none holds
    shares: np.ndarray | None = None   # (frames,): the share of triangles each frame hides (older bakes: None)

    def frame(self, f: int) -> np.ndarray | None:
        return self.hidden[f - self.start] if self.start <= f <= self.end else None


_decoded: dict = {"key": None, "baked": None}


def stored(scene) -> Baked | None:
    """The scene's bake, decoded (once per bake), or None."""
    b = scene.occ_bake
    if not b.hidden or b.frame_end < b.frame_start:
        return None
    key = (ident(scene), b.fingerprint, len(b.hidden), b.frame_start, b.frame_end)
    if _decoded["key"] != key:
        n = b.frame_end - b.frame_start + 1
        try:
            held = np.unpackbits(np.frombuffer(_unpack(b.held), np.uint8), count=b.width).astype(bool)
            baked = Baked(b.frame_start, b.frame_end, decode_frames(b.hidden, n, b.width),
                          decode_cameras(b.cameras, n), held,
                          np.frombuffer(_unpack(b.envelopes), dtype="<f8").reshape(n, 2),
                          np.frombuffer(_unpack(b.shares), dtype="<f4").reshape(n) if b.shares else None)
        except (ValueError, zlib.error):      # damaged by hand or by a script: no bake
            baked = None
        _decoded.update(key=key, baked=baked)
    return _decoded["baked"]


# --- object numbers ------------------------------------------------------------------

def numbers() -> np.ndarray:
    """``(n,) int64`` every object's bake number (0: none)."""
    objs = bpy.data.objects
    out = np.zeros(len(objs), dtype=np.int32)
    objs.foreach_get(BAKE_ID, out)
    return out.astype(np.int64)


def frame_mask(row: np.ndarray | None, ids: np.ndarray) -> np.ndarray:
    """``(n,) bool`` over ``bpy.data.objects`` (their numbers ``ids``): what a frame's
    bitset ``row`` hides (None: nothing); an object without a number of its own never."""
    out = np.zeros(len(ids), dtype=bool)
    if row is not None:
        ok = usable(ids) & (ids < len(row))
        out[ok] = row[ids[ok]]
    return out


def usable(ids: np.ndarray) -> np.ndarray:
    """``(n,) bool``: numbers an object owns alone (none, or shared: never hidden)."""
    ok = ids > 0
    values, counts = np.unique(ids[ok], return_counts=True)
    ok[ok] = np.isin(ids[ok], values[counts == 1])
    return ok


def number_objects() -> np.ndarray:
    """Give every object without a number of its own one (the first of a shared number
    keeps it), in one bulk write that tags nothing; returns the numbers."""
    ids = numbers()
    fresh = ids <= 0
    _, first = np.unique(ids, return_index=True)
    repeated = np.ones(len(ids), dtype=bool)
    repeated[first] = False
    fresh |= repeated
    if fresh.any():
        ids[fresh] = ids.max(initial=0) + 1 + np.arange(int(fresh.sum()))
        objs = bpy.data.objects
        try:
            objs.foreach_set(BAKE_ID, ids.astype(np.int32))
        except (TypeError, AttributeError, RuntimeError):   # a linked object is read-only: skip those
            items = objs.values()
            for i in np.flatnonzero(fresh).tolist():
                if items[i].library is None:
                    setattr(items[i], BAKE_ID, int(ids[i]))
            ids = numbers()
    return ids


# --- the fingerprint -------------------------------------------------------------------

def _persistent(v):
    """A value of a setting that means the same after a reload (datablocks by name)."""
    if isinstance(v, bpy.types.ID):
        return ("id", v.name_full)
    if isinstance(v, (bool, int, str)) or v is None:
        return v
    if isinstance(v, float):
        return round(v, 9)
    try:
        return tuple(_persistent(x) for x in v)
    except TypeError:
        return type(v).__name__


def _struct(s) -> tuple:
    """Every plain setting of an RNA struct (a modifier, a light)."""
    out = [s.bl_rna.identifier]
    for p in s.bl_rna.properties:
        if p.identifier in ("rna_type", "name", "is_active", "show_expanded", "persistent_uid",
                            "animation_data", "session_uid", "is_evaluated", "original", "users") \
                or p.type in ("COLLECTION", "POINTER") and p.identifier != "object":
            continue
        out.append((p.identifier, _persistent(getattr(s, p.identifier, None))))
    return tuple(out)


def _geometry(obj, memo: dict) -> tuple:
    """What ``obj``'s shape is read from, as a value that survives a reload."""
    base = (obj.type, obj.display_type, obj.show_in_front, obj.instance_type)
    if obj.type == "MESH":
        mods = tuple(_struct(m) for m in obj.modifiers) if len(obj.modifiers) else ()
        return base + (_mesh_fingerprint(obj.data, memo), mods)
    if obj.instance_type == "COLLECTION" and obj.instance_collection is not None:
        return base + tuple((m.name_full, _geometry(m, memo), tuple(map(tuple, m.matrix_world)))
                            for m in obj.instance_collection.all_objects)
    return base + (tuple(map(tuple, obj.bound_box)),)


def fingerprint(context, held: np.ndarray, passes: bool = True) -> str:
    """The fingerprint of what a bake read (``held``: ``(width,) bool`` over numbers):
    each such object's number and, where it does not change by itself (animation,
    drivers, constraints: :func:`.kinds.is_dynamic`), its shape and transform; every
    light of the view layer, the settings and the render size.  ``passes``: with the
    pass's accuracy (strategy, resolution), which change how a bake is made, not whether a
    made one holds (the render keys leave them out)."""
    h = hashlib.sha1()
    ids = numbers()
    own = usable(ids)
    at = np.flatnonzero(own & (ids < len(held)))
    at = at[held[ids[at]]]
    at = at[np.argsort(ids[at], kind="stable")]
    if len(at) != int(held.sum()):
        return "missing"                           # an object that took part is gone or shares its number
    objs = bpy.data.objects
    items = objs.values()
    mats = np.zeros(len(objs) * 16, dtype=np.float32)
    objs.foreach_get("matrix_world", mats)
    mats = mats.reshape(-1, 16)
    memo = {}
    dynamic = {}
    for i in at.tolist():
        o = items[i]
        if is_dynamic(o, dynamic):            # never hidden; what animation changes is baked per frame
            h.update(repr((int(ids[i]), "dynamic")).encode())
            continue
        h.update(repr((int(ids[i]), _geometry(o, memo))).encode())
        h.update(mats[i].tobytes())
    h.update(settings_digest(context, passes).encode())
    return h.hexdigest()


def settings_digest(context, passes: bool = True) -> str:
    """The part of :func:`fingerprint` that no object's own edit changes: every light of the
    view layer, the settings, the render size and rule, the objects kept from culling
    (an update of the scene alone is checked against this, cheaply)."""
    h = hashlib.sha1()
    ids = numbers()
    own = usable(ids)
    dynamic = {}
    for o in context.view_layer.objects:
        if o.type == "LIGHT":
            moves = is_dynamic(o, dynamic)
            h.update(repr((o.name_full, o.visible_get(), moves, None if moves else _struct(o.data))).encode())
            if not moves:
                h.update(np.array(o.matrix_world, dtype=np.float32).tobytes())
    scene = context.scene
    r = scene.render
    key = settings_key(scene.occ)
    accuracy = (scene.occ.strategy, scene.occ.max_resolution) if passes else ()
    h.update(repr((key[0], key[1], key[3], accuracy, r.engine,
                   r.resolution_x, r.resolution_y, r.resolution_percentage,
                   scene.camera.name_full if scene.camera else None,
                   # what the render shows beyond depth (ray tracing, X-ray, lights), and the
                   # time a frame spans (motion blur, time remapping)
                   rule_of(context, "CAMERA").why, getattr(r, "use_motion_blur", False),
                   round(float(getattr(r, "motion_blur_shutter", 0.0)), 6), r.frame_map_old, r.frame_map_new)).encode())
    never = identity.flags("occ_never_cull")
    h.update(np.sort(ids[never & own]).tobytes())
    return h.hexdigest()


def _candidate_numbers(context) -> np.ndarray:
    """The numbers of the objects that take part in a pass now (drawn, and culled
    against): each of a bake's must still."""
    cand = SESSION.extractor.candidates(context)
    ids, uids = numbers(), identity.uids()
    order = np.argsort(uids, kind="stable")
    return ids[order[np.searchsorted(uids, cand.uids, sorter=order)]]


def check(context, baked: Baked, want: str | None = None) -> str | None:
    """Why the scene's bake no longer holds, or None: it does.  ``want``: the fingerprint
    to hold to, made without the pass's accuracy (the render keys'), else the bake's own;
    with it, what the viewport hides is not asked (the render draws it: an object deleted
    or copied since still shows in the fingerprint, one the render leaves out in
    :func:`render_reason`)."""
    b = context.scene.occ_bake
    if want is None:            # (the render keys ask what the render draws: render_reason)
        present = _candidate_numbers(context)
        missing = baked.held.copy()
        missing[present[present < len(missing)]] = False
        if missing.any():
            return "an object it culled against is hidden, deleted or duplicated since"
    if (fingerprint(context, baked.held) != b.fingerprint) if want is None \
            else (fingerprint(context, baked.held, passes=False) != want):
        return "the scene changed since the bake (geometry, transforms, lights or settings)"
    return None


def render_reason(context, baked: Baked) -> str | None:
    """Why the render would not draw what the bake culled against, or None: every object a
    bake held renders to the camera (its own render hide off and not animated, seen by
    camera rays, in a collection the view layer renders) with the geometry the viewport
    draws (:func:`.kinds.render_geometry`).  The bake reads the viewport;
    an occluder the render leaves out would show what it hid.  In bulk but for the
    objects that carry animation."""
    from .kinds import action_curves
    ids = numbers()
    at = np.flatnonzero(usable(ids) & (ids < len(baked.held)))
    at = at[baked.held[ids[at]]]
    objs = bpy.data.objects
    off = identity.flags("hide_render")
    if "visible_camera" in bpy.types.Object.bl_rna.properties:
        rays = np.zeros(len(objs), dtype=bool)
        objs.foreach_get("visible_camera", rays)
        off |= ~rays
    out = ~np.isin(identity.uids()[at], rendered_by_collections(context.view_layer))
    items = objs.values()
    for i in at[off[at] | out].tolist():          # (hidden by the add-on's own keys: not left out)
        if out[np.searchsorted(at, i)] or not hidden_by_own_keys(items[i]):
            return (f"'{items[i].name}' is culled against in the viewport but left out of the render (its own "
                    "or its collection's render visibility): render it, or hide it in the viewport too, and bake again")
    scene = context.scene
    for i in at.tolist():
        if see_through(items[i]):                  # made see-through since: it hides nothing now
            return f"'{items[i].name}' is see-through now (its materials, or camera rays pass through it)"
        # the bake read the viewport's geometry: an occluder the render draws otherwise
        # (fewer subdivision levels' shrinking silhouette, a modifier off) may uncover what it hid
        why = render_geometry(items[i], scene)
        if why is not None:
            return f"'{items[i].name}' renders other geometry than the viewport draws ({why}; make them the same)"
        ad = items[i].animation_data
        if ad is None or hidden_by_own_keys(items[i]):
            continue
        curves = list(ad.drivers)
        if ad.action is not None:
            curves += action_curves(ad.action, getattr(ad, "action_slot", None)) or []
        if len(ad.nla_tracks) or any(fc.data_path == "hide_render" for fc in curves):
            return f"'{items[i].name}' has its render visibility animated (or NLA tracks)"
    return None


# --- the session's view of the bake ---------------------------------------------------

class State:
    """What this session knows of the scene's bake (never saved: a file load or an
    undo makes it unknown)."""

    def __init__(self):
        self.reset()

    def reset(self):
        self.key = None              # (scene, fingerprint) the status is for
        self.stale: str | None = None
        self.known = False
        self.applied = False         # the add-on hides a baked frame's set now ...
        self.version = -1            # ... unless a pass applied since (SESSION.version)
        self.drawn = None            # what the view layer draws by the user's hides (a digest) ...
        self.drawn_view = None       # ... in this view
        self.camera_off: int | None = None   # a frame whose camera is not the baked one
        self.camera = None           # (view, projection) of the camera the applied set holds for
        self.view = None             # the SpaceView3D pointer it hides in ...
        self.look = None             # ... and that view's shading then (:func:`.cameras.shading_look`)
        self.baking = False
        self.rendering = False       # Render Baked Shot runs: its own hide_render writes
        self.unsure = True           # hidden now may be a baked set nobody recorded (an undo)
        self.pending = False         # a recheck timer is registered
        self.apply_ms = 0.0          # the last frame's apply: the hiding and Blender's update (ms)
        self.changed = 0             # objects whose hiding the last frame's apply changed
        self.playback = PlaybackCost()   # the applies' updates against the drawing they save

    def status(self, context, baked: Baked) -> str | None:
        key = (ident(context.scene), context.scene.occ_bake.fingerprint)
        if self.key != key or not self.known:
            self.key, self.known = key, True
            self.stale = check(context, baked)
        return self.stale

    def owns(self) -> bool:
        """Whether what the add-on hides now is a baked frame's set (no pass since)."""
        return self.applied and self.version == SESSION.version

    def mark(self, reason: str | None) -> None:
        """An edit: stale with ``reason`` where the bake was known to hold (cheap: a drag
        checks nothing), else (or with None) unknown until checked in full."""
        if reason is None or not self.known:
            self.known = False
        elif self.stale is None:
            self.stale = reason


STATE = State()


def camera_area(context):
    """``(window, area)`` of a 3D view showing ``context.scene`` through its camera (not a
    Local Camera of its own), or None.
    A view in Quad View (its other regions draw from other sides), with a clipping region
    (what it cuts hides nothing), or whose own shading draws more than the render the sets
    were made for (:func:`_beyond_the_render`) draws more than the camera's sets hold for:
    none."""
    wm = context.window_manager
    for win in (wm.windows if wm is not None else ()):
        if win.scene != context.scene:
            continue
        for area in win.screen.areas:
            if area.type == "VIEW_3D":
                space = area.spaces.active
                rv3d = space.region_3d
                if rv3d is not None and through_scene_camera(space, context.scene) and not _draws_more(space, rv3d) \
                        and not _beyond_the_render(context, space):
                    return win, area
    return None


def _beyond_the_render(context, space) -> bool:
    """Whether 3D view ``space`` draws by its own shading more than the render the bake's
    sets were made for (:func:`.shading.rule` for the camera): Solid with shadows over a
    Workbench render without them, Material Preview's lights over another engine's.  A
    view that draws depth alone, or by the render's own rule, shows nothing more."""
    mine = view_rule(context, space)
    return mine.mode != "depth" and shading_key(mine) != shading_key(rule_of(context, "CAMERA"))


def _draws_more(space, rv3d) -> bool:
    """Whether a 3D view draws more than its own camera's picture: Quad View, a clipping region."""
    return bool(len(space.region_quadviews)) or rv3d.use_clip_planes


def _channel(context):
    """Where a baked frame hides: ``(window, area)``, None (everywhere), or False (nowhere)."""
    if bpy.app.background:
        return False if context.scene.occ.hide_in == "VIEW" else None
    return camera_area(context) or False


def release(update: bool = True) -> int:
    """Show what the bake hid (every object the add-on hides: its record is one), where
    no pass has hidden another set since, or where what is hidden came back with an
    undo or a file and may be a baked set (:attr:`State.unsure`).  ``update``: Blender's
    update now (not from a depsgraph handler: the next evaluation takes it)."""
    unsure, STATE.unsure = STATE.unsure, False
    if not (STATE.owns() or (unsure and visibility.culled().any())):
        STATE.applied = False
        return 0
    STATE.applied, STATE.view = False, None
    SESSION.applying = True
    try:
        n = visibility.restore()
        if update:
            bpy.context.view_layer.update()
    finally:
        SESSION.applying = False
    return n


def drawn_digest(context, view: int | None) -> int:
    """A digest of what the view layer draws by the user's hides (eye, monitor,
    collections) in the 3D view ``view`` (a ``SpaceView3D`` pointer; None: no view), the
    add-on's own hiding counted as drawn (so a frame's apply leaves it as it was).  The
    view is named: ``visible_get`` without one reads the context's 3D view, local view
    included, so a handler and an operator would see two sets.  About 50 ms at 50,000
    objects: after an update of the scene alone, and at the first apply after one."""
    found = localview.find(view) if view is not None else None
    space = found[2] if found is not None else None
    layer = context.view_layer.objects
    items = layer.values()
    shown = np.fromiter((o.visible_get(viewport=space) for o in items), dtype=bool, count=len(items))
    uids = identity.idents(items)
    shown |= identity.layer_flags(identity.VIEW_RECORD, uids, layer) | identity.layer_flags("occ_culled", uids, layer)
    return hash(uids.tobytes() + np.packbits(shown).tobytes())


def _camera_holds(baked: Baked, f: int, t: float, camera) -> bool:
    """Whether frame ``f``'s set holds for ``camera`` at time ``t``: at the frame itself the
    camera is the baked one, within the frame (a sub-frame) it lies inside the frame's
    envelope; else that frame hides nothing (the panel names it: the camera's keys were
    edited, or it was moved by hand)."""
    want = baked.cameras[f - baked.start]
    if camera is None:
        return False
    if t == f:
        same = np.allclose(camera.view, want[0], rtol=CAMERA_TOLERANCE, atol=CAMERA_TOLERANCE) \
            and np.allclose(camera.projection, want[1], rtol=CAMERA_TOLERANCE, atol=CAMERA_TOLERANCE)
        STATE.camera_off = None if same else f
        return same
    move, turn = baked.envelopes[f - baked.start]
    if move < 0 or not np.allclose(camera.projection, want[1], rtol=CAMERA_TOLERANCE, atol=CAMERA_TOLERANCE):
        return False
    m, a = view_change(Camera.from_matrices(want[0], want[1]), camera)
    return m <= move and a <= turn


def apply_frame(context, handler: bool = False) -> int:
    """Hide the current frame's baked set (or nothing: no bake, off, stale, another
    camera, no camera view); returns how many are hidden.  ``handler``: called from
    the frame-change handler, where no operator may run: a view that must first enter
    the add-on's local view is left to a timer right after (hiding late only costs
    drawing; showing is never late)."""
    scene = context.scene
    b = scene.occ_bake
    baked = stored(scene) if b.use and not scene.occ.live else None
    row = baked.frame(scene.frame_current) if baked is not None else None
    channel = _channel(context) if row is not None else False
    if row is None or channel is False or STATE.status(context, baked) is not None:
        release()
        STATE.playback.reset()
        return 0
    f = scene.frame_current
    try:
        camera, _ = scene_camera(context)
    except OccError:
        camera = None
    if not _camera_holds(baked, f, scene.frame_current_final, camera):
        release()
        STATE.playback.reset()
        return 0
    hide = frame_mask(row, numbers())
    if handler and channel is not None and channel[1].spaces.active.local_view is None and hide.any():
        _later()
        hide[:] = False
    t0, before = time.perf_counter(), visibility.COUNT["changed"]
    SESSION.applying = True
    try:
        with identity.one_pass():
            if hide.any():               # the selection and the active object: never hidden
                hide &= ~np.isin(identity.uids(), policy.chosen(context.view_layer))
            n = visibility.apply(hide, channel)
        context.view_layer.update()
    finally:
        SESSION.applying = False
    now = time.perf_counter()
    STATE.apply_ms = 1e3 * (now - t0)
    share = None if baked.shares is None else float(baked.shares[f - baked.start]) if hide.any() else 0.0
    STATE.playback.frame(f, now, STATE.apply_ms, share)
    STATE.changed = visibility.COUNT["changed"] - before
    SESSION.shown = None                 # no pass's set: the live guard has nothing to watch
    STATE.applied = bool(n)
    STATE.view = channel[1].spaces.active.as_pointer() if n and channel is not None else None
    STATE.look = shading_look(channel[1].spaces.active) if STATE.view is not None else None
    STATE.version, STATE.unsure = SESSION.version, False
    if STATE.drawn is None or STATE.drawn_view != STATE.view:
        STATE.drawn, STATE.drawn_view = drawn_digest(context, STATE.view), STATE.view
    STATE.camera = (camera.view, camera.projection)
    return n


# --- the bake ----------------------------------------------------------------------------

def sample_offsets(scene) -> list[float]:
    """The sub-frame offsets a frame's set holds for: to the next frame, and back over
    the motion-blur shutter where the render blurs."""
    r = scene.render
    blur = bool(getattr(r, "use_motion_blur", False))
    shutter = float(getattr(r, "motion_blur_shutter", 0.0)) if blur else 0.0
    back = math.ceil(shutter / STEP) * STEP if shutter > 0 else 0.0
    ahead = max(1.0, math.ceil(shutter / STEP) * STEP)
    n_back, n_ahead = round(back / STEP), round(ahead / STEP)
    return [-STEP * k for k in range(n_back, 0, -1)] + [STEP * k for k in range(1, n_ahead + 1)]


def _inside(scene, cameras: list) -> np.ndarray:
    """``(k,) bool`` of the engine's objects: wholly inside every camera's frustum."""
    boxes = transform_boxes(scene.mesh_bounds[scene.mesh_of], scene.matrices)
    out = np.ones(len(boxes), dtype=bool)
    for c in cameras:
        _, remaining = classify(planes_from_matrix(c.projection @ c.view), boxes)
        out &= remaining == 0
    return out


@dataclass
class BakeResult:
    frames: list
    hidden_mean: float
    objects: int
    share: list                 # per frame, the share of the triangles it hides


def bake_steps(context, start: int, end: int) -> Generator[object, None, BakeResult]:
    """Bake frames ``start .. end`` into ``scene.occ_bake`` (a generator, see
    :func:`.worker.drive`).  Stopped early (Esc), the scene goes back to its frame and
    nothing is stored."""
    scene = context.scene
    previous = scene.frame_current
    frames = list(range(start, end + 1))
    offsets = sample_offsets(scene)
    from . import render_keys  # (it builds on this module)
    render_keys.remove("removed: the shot is baked again; apply again")
    STATE.baking = True
    release()
    try:
        samples = {}
        for k, f in enumerate(frames):               # the camera at every sample first
            for t in [float(f)] + [f + o for o in offsets]:
                whole = math.floor(t)
                key = (whole, t - whole)
                if key not in samples:
                    scene.frame_set(whole, subframe=key[1])
                    samples[key] = scene_camera(context)[0]
            yield Progress(f"camera {k + 1}/{len(frames)}", 0.2 * (k + 1) / len(frames))
        ids = number_objects()
        uids = identity.uids()
        order = np.argsort(uids, kind="stable")
        width = int(ids.max(initial=0)) + 1
        hidden = np.zeros((len(frames), width), dtype=bool)
        held = np.zeros(width, dtype=bool)
        cams, envelopes, share = [], np.zeros((len(frames), 2)), np.zeros(len(frames))
        for k, f in enumerate(frames):
            analysis.evaluate(context, f)
            camera, display = scene_camera(context)
            cams.append(camera)
            views = [samples[(math.floor(f + o), f + o - math.floor(f + o))] for o in offsets]
            envelope = covering(camera, views, widen=WIDEN)
            envelopes[k] = (-1.0, -1.0) if envelope is False else \
                (0.0, 0.0) if envelope is None else (envelope.distance, envelope.angle_deg)
            if envelope is not False:
                view_rule = rule_of(context, "CAMERA")
                result, objects = yield from SESSION.compute_steps(
                    context, camera, display, restart=True, envelope=envelope, lights=view_rule.lights or None,
                    strategy=repeatable(scene.occ.strategy))
                h = SESSION.held
                at = np.searchsorted(uids, h.uids, sorter=order).clip(0, len(uids) - 1)
                if not np.array_equal(uids[order[at]], h.uids):
                    raise OccError("the scene changed during the bake (an object was added): bake again")
                took = ids[order[at]]
                held[took] = True
                state = result.state
                occluded = state == Visibility.OCCLUDED
                keep = policy.never_hidden(context, objects, h.uids, h.collection, occluded, SESSION.extractor)
                keep |= policy.drawn_beyond_depth(view_rule, state, scene.occ.cull_raytraced)
                hide = occluded & ~keep
                if hide.any():
                    hide &= _inside(SESSION.culler.scene, [camera] + views)
                hidden[k, took[hide]] = True
                tris = SESSION.culler.scene.triangle_counts
                share[k] = float(tris[hide].sum()) / max(float(tris.sum()), 1.0)
            yield Progress(f"frame {k + 1}/{len(frames)}", 0.2 + 0.8 * (k + 1) / len(frames))
    finally:
        scene.frame_set(previous)
        STATE.baking = False
    cameras = np.stack([np.stack([c.view, c.projection]) for c in cams]) if cams else np.zeros((0, 2, 4, 4))
    return store(context, start, end, hidden, cameras, envelopes, held, share)


def store(context, start: int, end: int, hidden: np.ndarray, cameras: np.ndarray, envelopes: np.ndarray,
          held: np.ndarray, share: np.ndarray) -> BakeResult:
    """Write a bake of frames ``start .. end`` into ``scene.occ_bake`` (per frame: the
    numbers hidden, the camera's view and projection, the envelope, the share of
    triangles hidden; the numbers that took part), fingerprinted against the scene now."""
    from . import render_keys
    scene = context.scene
    b = scene.occ_bake
    b.frame_start, b.frame_end, b.width = start, end, hidden.shape[1]
    b.hidden = encode_frames(hidden)
    b.cameras = _pack(np.asarray(cameras, dtype="<f8").tobytes())
    b.envelopes = _pack(np.asarray(envelopes, dtype="<f8").tobytes())
    b.held = _pack(np.packbits(held).tobytes())
    b.shares = _pack(np.asarray(share, dtype="<f4").tobytes())
    b.fingerprint = fingerprint(context, held)
    b.camera_digest = render_keys.shot_digest(context)
    mean = float(hidden.sum(axis=1).mean()) if len(hidden) else 0.0
    share = np.asarray(share, dtype=np.float64)
    b.summary = (f"frames {start}-{end}: {mean:,.0f} of {int(held.sum()):,} objects, "
                 f"{100 * float(share.mean() if len(share) else 0.0):.0f} % of triangles hidden a frame (mean)")
    STATE.key, STATE.known, STATE.stale = (ident(scene), b.fingerprint), True, None
    return BakeResult(list(range(start, end + 1)), mean, int(held.sum()), [float(x) for x in share])


# --- the render ---------------------------------------------------------------------------

@dataclass
class Rendered:
    frames: list
    hidden: list                # per frame, objects hidden from its render
    paths: list


def render_shot(context, start: int, end: int) -> Rendered:
    """Render frames ``start .. end`` to ``scene.render.filepath`` (numbered as
    ``blender -a`` numbers them), each with its baked set hidden from the render: the
    frame is evaluated (``frame_set``), checked (the bake holds, the camera is the baked
    one: else it is rendered whole), the set's objects get ``hide_render`` (only those
    whose own is off), the frame is rendered on this thread (``render.render``, which
    blocks: no render job, no handler on a render thread) and exactly those flags are
    cleared again, whatever happens.  A stale bake renders nothing: an OccError."""
    scene = context.scene
    baked = stored(scene)
    if baked is None:
        raise OccError("no baked shot in this scene: bake one first (Bake Shot)")
    if start < baked.start or end > baked.end:
        raise OccError(f"frames {start}-{end} are not all baked (the bake holds frames {baked.start}-{baked.end})")
    previous = scene.frame_current
    out = Rendered([], [], [])
    STATE.rendering = True
    try:
        release()                                 # the viewport's hiding is not the render's
        why = STATE.status(context, baked) or render_reason(context, baked)
        if why is not None:
            raise OccError(f"the baked shot is stale ({why}): bake it again, or render without it")
        for f in range(start, end + 1):
            scene.frame_set(f)
            try:
                camera, _ = scene_camera(context)
            except OccError:
                camera = None
            row = baked.frame(f) if _camera_holds(baked, f, float(f), camera) else None
            take = frame_mask(row, numbers()) & ~identity.flags("hide_render")
            items = bpy.data.objects.values()
            hidden = [items[i] for i in np.flatnonzero(take).tolist()]
            path = scene.render.frame_path(frame=f)
            SESSION.applying = True
            try:
                for o in hidden:
                    o.hide_render = True
                # a still goes to the output path as it is: the frame's own name, as -a writes it
                scene.render.filepath, kept = path, scene.render.filepath
                try:
                    bpy.ops.render.render(write_still=True)
                finally:
                    scene.render.filepath = kept
            finally:
                for o in hidden:
                    o.hide_render = False
                SESSION.applying = False
            out.frames.append(f)
            out.hidden.append(len(hidden))
            out.paths.append(path)
            if bpy.app.background:
                print(f"occlusion render: frame {f} ({len(hidden)} objects hidden) -> {path}", flush=True)
    finally:
        STATE.rendering = False
        scene.frame_set(previous)
    return out


def clear(scene) -> None:
    from . import render_keys
    release()
    render_keys.remove()
    b = scene.occ_bake
    b.hidden = b.cameras = b.envelopes = b.held = b.fingerprint = b.summary = b.camera_digest = b.render_note = ""
    b.shares = ""
    b.frame_start, b.frame_end, b.width, b.use = 0, -1, 0, False


# --- handlers --------------------------------------------------------------------------

@persistent
def on_frame_change(scene, _depsgraph=None):
    """Apply the new frame's set before it draws."""
    if STATE.baking or STATE.rendering or rendering() or SESSION.busy:
        return
    context = bpy.context
    if context.scene is not scene or not scene.occ_bake.use:
        if STATE.applied and context.scene is scene:
            release()
        return
    try:
        apply_frame(context, handler=True)
    except Exception:  # a handler must not raise: show everything instead
        import traceback
        traceback.print_exc()
        release()


@persistent
def on_depsgraph_update(scene, depsgraph):
    """An edit: a transform or a geometry changed makes the bake stale at once; any other
    change to an object or a collection, or to what the view layer draws, makes it
    unknown until checked; the camera moved is compared with the frame's.  What the
    bake hid is shown here (before the next draw) and applied again from a timer right
    after, checked (headless: at the next frame change)."""
    if SESSION.applying or STATE.baking or STATE.rendering or not scene.occ_bake.hidden:
        return
    reason, touched, cam = None, False, scene.camera
    for u in depsgraph.updates:
        if isinstance(u.id, bpy.types.Object):
            o = u.id.original
            if cam is not None and o == cam:
                # tagged (its animation, a script) or moved: only a camera that left the
                # view the applied set holds for counts (a Play press tags it unmoved)
                touched = touched or _camera_moved(bpy.context)
            elif u.is_updated_transform or u.is_updated_geometry:
                reason = f"'{o.name}' was edited"
                break
            else:
                touched = True
        elif isinstance(u.id, bpy.types.Action):
            anim = cam.animation_data if cam is not None else None
            if anim is not None and anim.action == u.id.original:
                touched = touched or _camera_moved(bpy.context)
            else:                              # keys of what the bake saw move: baked per frame
                reason = f"the animation '{u.id.name}' was edited"
                break
        elif not isinstance(u.id, bpy.types.Scene):
            touched = True
    if reason is None and not touched:         # the scene alone: a selection, or a hide
        if not STATE.owns():                   # nothing of the bake's hidden: checked when it applies
            STATE.mark(None)
            STATE.drawn = None
            return
        try:
            if STATE.drawn == drawn_digest(bpy.context, STATE.view) \
                    and not policy.hides_chosen(bpy.context.view_layer):
                return
        except AttributeError:                 # no view layer in this context: unknown
            pass
        touched, STATE.drawn = True, None
    STATE.mark(reason)
    if STATE.owns():
        release(update=False)
        _later()


def _camera_moved(context) -> bool:
    """Whether the scene camera differs from the one the applied set was made for."""
    if STATE.camera is None or not STATE.owns():
        return True
    try:
        camera, _ = scene_camera(context)
    except (OccError, AttributeError):
        return True
    view, projection = STATE.camera
    return not (np.array_equal(camera.view, view) and np.array_equal(camera.projection, projection))


def _later() -> None:
    """Apply the frame again from a timer, right after this handler or draw."""
    if not STATE.pending:
        STATE.pending = True
        bpy.app.timers.register(_recheck, first_interval=0.0)


def _recheck():
    """After an edit, outside the handler: apply the frame again (or show all)."""
    STATE.pending = False
    try:
        if bpy.context.scene is not None and not STATE.baking and not SESSION.busy:
            apply_frame(bpy.context)
    except Exception:  # a timer must not raise: show everything instead
        import traceback
        traceback.print_exc()
        release()
    return None


@persistent
def on_reset(*_args):
    """A file load or an undo: what is known of the bake is forgotten (the add-on's
    own handlers have shown what it hid on load)."""
    STATE.reset()
    _decoded.update(key=None, baked=None)


def guard():
    """Before a redraw of the view the bake hides in: a view no longer looking through
    the camera, or now in Quad View or with a clipping region, shows everything first (a
    timer: no data changes while drawing)."""
    if not STATE.owns() or STATE.view is None or STATE.pending:
        return
    context = bpy.context
    space = context.space_data
    if space is None or space.as_pointer() != STATE.view:
        return
    rv3d = space.region_3d
    if rv3d is not None and (not through_scene_camera(space, context.scene) or _draws_more(space, rv3d)
                             or shading_look(space) != STATE.look):
        _later()                              # it finds no camera view there, or checks the new shading


HANDLERS = (("frame_change_post", on_frame_change), ("depsgraph_update_post", on_depsgraph_update),
            ("load_post", on_reset), ("undo_post", on_reset), ("redo_post", on_reset))
_guard = []


def register():
    bpy.utils.register_class(OccBake)
    bpy.types.Scene.occ_bake = PointerProperty(type=OccBake)
    bpy.types.Object.occ_bake_id = IntProperty(name="Bake Number", default=0, min=0, options={"HIDDEN"})
    for name, f in HANDLERS:
        getattr(bpy.app.handlers, name).append(f)
    if not bpy.app.background:
        _guard.append(bpy.types.SpaceView3D.draw_handler_add(guard, (), "WINDOW", "PRE_VIEW"))


def unregister():
    while _guard:
        bpy.types.SpaceView3D.draw_handler_remove(_guard.pop(), "WINDOW")
    for name, f in reversed(HANDLERS):
        h = getattr(bpy.app.handlers, name)
        if f in h:
            h.remove(f)
    STATE.reset()
    del bpy.types.Object.occ_bake_id
    del bpy.types.Scene.occ_bake
    bpy.utils.unregister_class(OccBake)
