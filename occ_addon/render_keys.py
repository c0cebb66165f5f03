"""Apply to Render: a baked shot written as keys of ``hide_render``, where any final render
reads it, the window's F12 or Render Animation, ``blender -b file.blend -a`` and a farm's
chunk alike, with or without the add-on there.

**What is written.**  Each object that some baked frame hides gets an action of its own
(marked :data:`.kinds.RENDER_KEYS`) with one F-curve, ``hide_render``, keyed only where
its state changes: shown before the first baked frame and after the last, constant
between keys.  A sub-frame (motion blur) takes the frame below it, whose set holds up to
the next frame (the bake samples the camera that far).  An object with animation,
drivers or NLA of its own, one the user hides from the render, one without a number of
its own, and one linked into another scene (whose camera the bake never saw) gets none.
An object carrying only these keys is not animated for the add-on (:func:`.kinds.is_dynamic`).

**When it is refused.**  The bake must hold (:func:`.bake.check`), the camera must move by
its own keys alone (no constraints, drivers, NLA, moving parent or markers switching
cameras) and still be the baked one: the digest of its keys, its still channels, its
lens and the scene's time mapping (:func:`shot_digest`) equals the bake's, so every
sub-frame is the baked path.  The scene must render one view layer, the one baked.

**When it is removed.**  The keys hold only as long as the bake does, and as long as the
render draws everything the bake culled against (:func:`.bake.render_reason`: no occluder
hidden from the render, out of camera rays, or in a collection the render leaves out):
after any edit, undo, redo or file load the add-on checks the bake and the digest again (a
timer right after the edit in a window; at once headless and on load) and removes every
key of a bake that no longer holds; the panel says why.  What changes without an edit
Blender reports (the add-on's scene settings, which carry no update callbacks; the
scene's view layers and their render switches; the window's view layer; markers that
switch cameras) is polled in a window (:func:`poll`, every :data:`POLL_S`) and checked
again before every render in background mode and before every save; an object's "never
cull" (a callback) is checked at once.  So neither a render nor a saved file
takes keys that no longer hold.  A new bake, Clear Bake and Remove from
Render remove them too.  What the add-on cannot see, an edit made where it is not
enabled, it cannot guard: open and save the file with the add-on before it goes to a
farm (a load checks it).
"""

import contextlib
import hashlib
from dataclasses import dataclass

import bpy
import numpy as np
from bpy.app.handlers import persistent

from ..core import OccError
from . import bake, bus, identity
from .keyed_camera import CHANNELS, _fcurves
from .kinds import RENDER_KEYS, action_curves, is_dynamic, render_keys_only
from .props import settings_key
from .session import rendering

CURVE = "hide_render"
POLL_S = 0.25           # a window's poll of what changes the keys' hold without an update


@dataclass
class Written:
    objects: int            # objects given keys
    keys: int               # keys written
    skipped: int            # objects a frame hides that could not take keys (their own animation, ...)


# --- the camera's digest --------------------------------------------------------------------

def _curves_digest(curves) -> list:
    out = []
    for fc in sorted(curves, key=lambda c: (c.data_path, c.array_index)):
        kp = fc.keyframe_points
        n = len(kp)
        arr = np.zeros(6 * n, dtype=np.float64)
        if n:
            for i, prop in enumerate(("co", "handle_left", "handle_right")):
                part = np.zeros(2 * n, dtype=np.float32)
                kp.foreach_get(prop, part)
                arr[2 * i * n:2 * (i + 1) * n] = part
        out.append((fc.data_path, fc.array_index, fc.mute, fc.extrapolation, len(fc.modifiers),
                    hashlib.sha1(arr.tobytes()).hexdigest(),
                    tuple((k.interpolation, k.easing, round(k.back, 6), round(k.amplitude, 6),
                           round(k.period, 6)) for k in kp)))
    return out


def shot_digest(context) -> str:
    """The scene camera's path and lens as a value, and what the render takes beside the
    bake's fingerprint (time mapping, view layers, background sets); ``"complex: ..."``
    where the camera moves by more than its own keys (its path cannot be told from its
    settings)."""
    scene = context.scene
    cam = scene.camera
    if cam is None or cam.type != "CAMERA":
        return "complex: the scene has no camera"
    if any(m.camera is not None for m in scene.timeline_markers):
        return "complex: markers switch cameras"
    if len(cam.constraints):
        return "complex: the camera has constraints"
    curves, data_curves = _fcurves(cam), _fcurves(cam.data)
    if curves is None or data_curves is None:
        return "complex: the camera is driven (drivers or NLA)"
    chain = []
    p = cam.parent
    if p is not None and (cam.parent_type != "OBJECT" or is_dynamic(p)):
        return "complex: the camera's parent moves"
    while p is not None and len(chain) < 64:
        chain.append((p.name_full, tuple(round(v, 7) for row in p.matrix_world for v in row)))
        p = p.parent
    keyed = {(fc.data_path, fc.array_index) for fc in curves}
    still = [(path, i, round(getattr(cam, path)[i], 7)) for path, size in CHANNELS.items()
             for i in range(size) if (path, i) not in keyed]
    data_keyed = {fc.data_path for fc in data_curves}
    lens = [p for p in bake._struct(cam.data) if not (isinstance(p, tuple) and p[0] in data_keyed)]
    r = scene.render
    layers = [v.name for v in scene.view_layers if v.use]
    if r.use_single_layer:
        layers = [context.view_layer.name]
    sets = sorted(s.name_full for s in bpy.data.scenes if s.background_set == scene)
    value = repr((cam.name_full, cam.rotation_mode, cam.parent_type, chain,
                  tuple(round(v, 7) for row in cam.matrix_parent_inverse for v in row),
                  still, _curves_digest(curves), lens, _curves_digest(data_curves),
                  r.frame_map_old, r.frame_map_new, r.pixel_aspect_x, r.pixel_aspect_y,
                  context.view_layer.name, layers, sets))
    return hashlib.sha1(value.encode()).hexdigest()


def _refusal(context, digest: str) -> str | None:
    """Why the render keys cannot hold for the scene as it is, or None."""
    scene = context.scene
    if digest.startswith("complex"):
        return (f"{digest[9:]}: its path cannot be proved frame by frame from its keys; use "
                "Render Baked Shot, which checks every frame")
    if digest != scene.occ_bake.camera_digest:
        return "the camera's animation, its lens or the render's layers changed since the bake: bake again"
    layers = [v.name for v in scene.view_layers if v.use]
    if not scene.render.use_single_layer and layers != [context.view_layer.name]:
        return (f"the scene renders the view layers {', '.join(layers) or '(none)'}; the bake holds for "
                f"'{context.view_layer.name}' alone (Render Single Layer, or turn the others off)")
    if any(s.background_set == scene for s in bpy.data.scenes):
        return "another scene renders this one as its background set, with its own camera"
    return None


# --- writing and removing -------------------------------------------------------------------

def _elsewhere(scene) -> np.ndarray:
    """Sorted identities of the objects linked into any scene but ``scene`` (their keys
    would hide in that scene's render, for a camera the bake never saw)."""
    found = [identity.uids(s.objects) for s in bpy.data.scenes if s != scene]
    return np.unique(np.concatenate(found)) if found else np.zeros(0, dtype=np.int64)


def _new_curve(obj):
    """A fresh action of the add-on's, assigned to ``obj``, and its ``hide_render`` F-curve."""
    action = bpy.data.actions.new(f"OccRender {obj.name}")
    action[RENDER_KEYS] = 1
    ad = obj.animation_data or obj.animation_data_create()
    ad.action = action
    if hasattr(action, "slots"):                      # slotted actions (Blender 4.4+)
        from bpy_extras.anim_utils import action_ensure_channelbag_for_slot
        slot = action.slots.new(id_type="OBJECT", name=obj.name)
        ad.action_slot = slot
        return action_ensure_channelbag_for_slot(action, slot).fcurves.new(CURVE)
    return action.fcurves.new(CURVE)


def _keys(states: np.ndarray, start: int) -> np.ndarray:
    """``(k, 2) float32`` (frame, value) keys of ``states`` (one bool a frame from ``start``):
    shown before and after, and a key at every change."""
    s = states.astype(np.int8)
    change = np.flatnonzero(np.diff(np.concatenate(([0], s))) != 0)
    frames = np.concatenate(([start - 1], start + change, [start + len(s)])).astype(np.float32)
    values = np.concatenate(([0], s[change], [0])).astype(np.float32)
    return np.stack([frames, values], axis=1)


def write(context) -> Written:
    """Write the scene's bake as render keys (earlier ones removed first); an OccError
    where they could not hold, with nothing written."""
    scene = context.scene
    b = scene.occ_bake
    baked = bake.stored(scene)
    if baked is None:
        raise OccError("no baked shot in this scene: bake one first (Bake Shot)")
    why = bake.STATE.status(context, baked) or bake.render_reason(context, baked)
    if why is not None:
        raise OccError(f"the baked shot is stale ({why}): bake it again")
    digest = shot_digest(context)
    why = _refusal(context, digest)
    if why is not None:
        raise OccError(f"Apply to Render: {why}")
    remove()
    ids = bake.numbers()
    frames = range(baked.start, baked.end + 1)
    rows = np.stack([bake.frame_mask(baked.frame(f), ids) for f in frames])
    items = bpy.data.objects.values()
    shared = np.isin(identity.uids(), _elsewhere(scene))
    objects = keys = skipped = 0
    for i in np.flatnonzero(rows.any(axis=0)).tolist():
        o = items[i]
        ad = o.animation_data
        if o.hide_render or (ad is not None and (ad.action is not None or len(ad.drivers) or len(ad.nla_tracks))) \
                or shared[i]:
            skipped += 1
            continue
        pts = _keys(rows[:, i], baked.start)
        fc = _new_curve(o)
        fc.keyframe_points.add(len(pts))
        fc.keyframe_points.foreach_set("co", pts.ravel())
        fc.keyframe_points.foreach_set("interpolation", np.zeros(len(pts), dtype=np.int32))    # CONSTANT
        if fc.keyframe_points[0].interpolation != "CONSTANT":     # (an enum numbered otherwise)
            for k in fc.keyframe_points:
                k.interpolation = "CONSTANT"
        fc.update()
        objects += 1
        keys += len(pts)
    b.render_keys = ":".join((digest, bake.fingerprint(context, baked.held, passes=False),
                              bake.settings_digest(context, passes=False)))
    b.render_note = ""
    return Written(objects, keys, skipped)


def keyed_objects() -> list:
    """Every object carrying the add-on's render keys (any scene)."""
    if not any(a.get(RENDER_KEYS) is not None for a in bpy.data.actions):
        return []
    out = []
    for o in bpy.data.objects:
        ad = o.animation_data
        if ad is not None and ad.action is not None and ad.action.get(RENDER_KEYS) is not None:
            out.append(o)
    return out


def remove(note: str = "") -> int:
    """Remove every render key of the add-on's (every scene), each object's ``hide_render``
    back to shown; keys the user added to such an action stay (only the add-on's curve
    goes).  ``note``: why, for the panel.  Returns the objects it touched."""
    objs = keyed_objects()
    for o in objs:
        ad = o.animation_data
        action = ad.action
        if render_keys_only(ad):
            ad.action = None
            if not len(ad.drivers) and not len(ad.nla_tracks):
                o.animation_data_clear()
        else:                                      # the user keyed more into it: theirs now
            slot = getattr(ad, "action_slot", None)
            curves = action_curves(action, slot) or []
            for fc in curves:
                if fc.data_path == CURVE:
                    _curve_owner(action, slot).remove(fc)
            del action[RENDER_KEYS]
        o.hide_render = False
    for action in [a for a in bpy.data.actions if a.get(RENDER_KEYS) is not None and a.users == 0]:
        bpy.data.actions.remove(action)
    for s in bpy.data.scenes:
        sb = s.occ_bake
        if sb.render_keys:
            sb.render_keys = ""
            sb.render_note = note
    return len(objs)


def _curve_owner(action, slot):
    """The F-curve collection of ``action`` that holds ``slot``'s curves."""
    if hasattr(action, "slots"):
        from bpy_extras.anim_utils import action_get_channelbag_for_slot
        return action_get_channelbag_for_slot(action, slot).fcurves
    return action.fcurves


def holds(context, full: bool = True) -> str | None:
    """Why the scene's render keys no longer hold, or None (they do, or there are none).
    ``full``: the bake's whole check (every object it culled against, their shapes); else
    what an update of the scene alone can change (settings, lights, the camera's path, what
    the render leaves out), milliseconds."""
    scene = context.scene
    b = scene.occ_bake
    if not b.render_keys:
        return None
    baked = bake.stored(scene)
    if baked is None:
        return "the bake was cleared"
    # evaluated first: a file just read holds no world matrices yet (Blender 4+ keeps them
    # at run time only), an undo step may hold stale ones
    context.evaluated_depsgraph_get()
    stored_digest, fp, settings = (b.render_keys.split(":") + ["", "", ""])[:3]
    # in full: the keys hide in every render (the pass's accuracy left out: it changes how
    # a bake is made, not whether this one holds)
    why = bake.check(context, baked, want=fp) if full else None
    if why is not None:
        return f"the bake is stale ({why})"
    digest = shot_digest(context)
    if (stored_digest, settings) != (digest, bake.settings_digest(context, passes=False)):
        return _refusal(context, digest) or "the camera, the lights or the render's settings changed"
    why = bake.render_reason(context, baked)
    if why is not None:
        return why
    keyed = keyed_objects()
    if keyed and np.isin(identity.idents(keyed), _elsewhere(scene)).any():
        return "an object with render keys was linked into another scene"
    return None


def recheck(context, full: bool = True) -> str | None:
    """Remove the render keys where they no longer hold (any failure: removed too);
    returns why, or None.  ``full``: see :func:`holds`."""
    try:
        why = holds(context, full)
    except Exception as e:  # cannot tell: the keys go (they would hide without proof)
        why = f"the check failed ({type(e).__name__}: {e})"
    if why is not None:
        remove(f"removed: {why}; apply again after baking")
    return why


# --- handlers ----------------------------------------------------------------------------

_pending = []


def _own(u) -> bool:
    """Whether a depsgraph update is the keys' own (their actions, their objects' flags)."""
    idb = u.id
    if isinstance(idb, bpy.types.Action):
        return idb.original.get(RENDER_KEYS) is not None
    if isinstance(idb, bpy.types.Object) and not (u.is_updated_transform or u.is_updated_geometry):
        ad = idb.original.animation_data
        return ad is not None and render_keys_only(ad)
    return False


def _later(full: bool) -> None:
    if _pending:
        _pending[0] = _pending[0] or full
        return
    _pending.append(full)
    bpy.app.timers.register(_timer, first_interval=0.0)


def _timer():
    full = bool(_pending and _pending[0])
    _pending.clear()
    context = bpy.context
    if context.scene is not None and context.view_layer is not None and not bake.STATE.baking:
        recheck(context, full)
    return None


def _to_check(scene) -> bool:
    """Whether ``scene`` has keys to check now (not while the add-on bakes or renders a
    baked shot: its own writes)."""
    return scene is not None and bool(scene.occ_bake.render_keys) \
        and not (bake.STATE.baking or bake.STATE.rendering)


@persistent
def on_depsgraph_update(scene, depsgraph):
    """An edit: the keys are checked again, right after it in a window (a timer: a drag
    asks once per step), at once headless (no timer runs there before a render)."""
    if not _to_check(scene):
        _edited_elsewhere(scene, depsgraph)
        return
    theirs = [u for u in depsgraph.updates if not _own(u)]
    if not theirs:
        return
    # the scene alone (a selection, a setting, a view layer's collections): no object's
    # shape or place changed, the cheap part is enough
    full = not all(isinstance(u.id, bpy.types.Scene) for u in theirs)
    if bpy.app.background:
        recheck(bpy.context, full)
    else:
        _later(full)


# scenes with keys whose objects may have been edited from another scene's evaluation (an
# object linked into both): each is checked in full at its next poll or render
_edited_from_others: set = set()


def _edited_elsewhere(scene, depsgraph) -> None:
    """An edit evaluated for ``scene`` (no keys of its own) that names an object or data:
    every other scene with keys may share it, and its own handler call never comes."""
    if bake.STATE.baking or bake.STATE.rendering:
        return
    others = [s for s in bpy.data.scenes if s != scene and s.occ_bake.render_keys]
    if others and any(not isinstance(u.id, bpy.types.Scene) and not _own(u) for u in depsgraph.updates):
        _edited_from_others.update(identity.ident(s) for s in others)


def _unreported(context) -> tuple:
    """What may change whether the keys hold without a depsgraph update: the add-on's
    settings (:func:`.props.settings_key`), the view layers the render takes, the window's
    view layer, the scenes using this one as a background set, markers that switch cameras."""
    scene = context.scene
    return (settings_key(scene.occ), scene.render.use_single_layer,
            tuple((v.name, v.use) for v in scene.view_layers), context.view_layer.name,
            tuple(s.name_full for s in bpy.data.scenes if s.background_set == scene),
            tuple(m.camera.name_full for m in scene.timeline_markers if m.camera is not None))


_seen = {}          # scene identity -> :func:`_unreported` when last checked


def poll() -> None:
    """Where the context's scene has keys and what :func:`_unreported` reads changed since
    the last poll (or was never polled): the keys are checked again (the cheap part).  Not
    while a render runs (its thread reads the keys): the first poll after it."""
    context = bpy.context
    scene = context.scene
    if not _to_check(scene) or context.view_layer is None or rendering():
        return
    key, uid = _unreported(context), identity.ident(scene)
    if _seen.get(uid) != key or uid in _edited_from_others:
        _seen[uid] = key
        full = uid in _edited_from_others
        _edited_from_others.discard(uid)
        recheck(context, full=full)


def _poll_timer():
    try:
        poll()
    except Exception:  # noqa: BLE001 -- cannot tell: the keys go, as recheck's failures do
        with contextlib.suppress(Exception):
            remove("removed: the check failed; apply again after baking")
    return POLL_S


def setting_changed():
    """An add-on property with an update callback changed (:mod:`.bus`'s ``"setting"``: an
    object's "never cull"): checked as an update of the scene is (the cheap part)."""
    scene = bpy.context.scene
    if not _to_check(scene):
        return
    if bpy.app.background:
        recheck(bpy.context, full=False)
    else:
        _later(False)


@persistent
def on_render_init(*_args):
    """A render in background mode (a script's, ``blender -b -a``: on the main thread) checks
    the keys first, in full (a window's render runs beside the interface: its keys were
    polled)."""
    if bpy.app.background and not bake.STATE.rendering:
        on_reset()


@persistent
def on_reset(*_args):
    """A file load, an undo, a redo or a save: checked at once (a farm's render follows
    the load; a saved file carries no keys that no longer hold)."""
    context = bpy.context
    if context.scene is not None and context.view_layer is not None:
        recheck(context)


HANDLERS = (("depsgraph_update_post", on_depsgraph_update), ("load_post", on_reset), ("undo_post", on_reset),
            ("redo_post", on_reset), ("save_pre", on_reset), ("render_init", on_render_init))


def register():
    for name, f in HANDLERS:
        getattr(bpy.app.handlers, name).append(f)
    bus.subscribe("setting", setting_changed)
    if not bpy.app.background:
        bpy.app.timers.register(_poll_timer, first_interval=POLL_S, persistent=True)


def unregister():
    bus.unsubscribe("setting", setting_changed)
    for name, f in reversed(HANDLERS):
        h = getattr(bpy.app.handlers, name)
        if f in h:
            h.remove(f)
    if bpy.app.timers.is_registered(_poll_timer):
        bpy.app.timers.unregister(_poll_timer)
    _pending.clear()
    _seen.clear()
