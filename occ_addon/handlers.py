"""Blender's application handlers.

The handlers are registered explicitly (:func:`register`, in the order of
:data:`HANDLERS`; :func:`unregister` in reverse).  Every change not our own (an
edit, a new frame, another view layer) is announced on the change bus
(:mod:`.bus`), where live mode listens; this module knows nothing of live mode.
Undo, redo and file loads drop the session's caches; no file is saved with the
add-on's hiding in it.
"""

import bpy
from bpy.app.handlers import persistent

from . import bus, localview, visibility
from .identity import ident
from .passes import UNKNOWN
from .session import SESSION, render_thread, rendering


def on_window_change() -> None:
    """The window shows another scene or view layer than the last pass's: what the
    add-on hid everywhere is shown again, and live mode makes a fresh pass
    (:meth:`.session.Session.left_layer`)."""
    context = bpy.context
    if context.scene is not None and context.view_layer is not None and SESSION.left_layer(context):
        bus.notify()


@persistent          # kept across file loads, like the add-on itself
def on_depsgraph_update(scene, depsgraph):
    """Mark what changed: geometry -> re-extract those objects (and instances of
    collections holding them); transforms are read in bulk every pass anyway.
    An object the user showed leaves the add-on's record here (every show is
    evaluated, so reported), before the user can hide it again."""
    if SESSION.applying or render_thread():
        return                        # (our own hiding; a render's own evaluation, from its thread)
    SESSION.edited_elsewhere(scene, depsgraph)
    visibility.reconcile()
    if depsgraph.id_type_updated("SCENE") or depsgraph.id_type_updated("COLLECTION") \
            or localview.layer_switched():
        localview.adopt()           # what joined the view layer is drawn in the add-on's local view
    _mark(depsgraph)
    updates = depsgraph.updates
    if len(updates) or not rendering():        # (a render job's start reports an update naming nothing)
        bus.emit("edited", scene, not len(updates) or _beside_scene(updates))
    bus.emit("camera", scene)       # the scene camera moved by an edit: as for a new frame
    bus.notify()


@persistent
def on_frame_change(scene, depsgraph):
    """Animation moved things: the same marks as an edit (the frame's depsgraph reports them).
    Animation changes values, not what objects are; but it can change hide flags
    (keyframed collection visibility): the user-shown answers are asked again.  A render
    job's frames, which Blender announces from the render's own thread, are the render's:
    nothing is read or written there."""
    if render_thread():
        return
    SESSION.extractor.visibility_changed()
    if depsgraph is not None:
        _mark(depsgraph, edits=False)
    # what the frame moved (nothing reported: nothing animated, the scene's frame only)
    bus.emit("edited", scene, depsgraph is None or _beside_scene(depsgraph.updates))
    bus.emit("camera", scene)
    bus.notify()


VIEW_ONLY = (bpy.types.Scene, bpy.types.Camera)


def _beside_scene(updates) -> bool:
    """Whether the depsgraph's updates name a datablock beside the scene and its cameras
    (a camera draws nothing: where one moves, the view through it moves, which the
    listeners check as a view)."""
    return any(not isinstance(u.id, VIEW_ONLY) and not (isinstance(u.id, bpy.types.Object) and u.id.type == "CAMERA")
               for u in updates)


def _mark(depsgraph, edits=True):
    geometry, moved = [], []
    extractor = SESSION.extractor
    for update in depsgraph.updates:
        if edits:
            extractor.saw(update)
        if isinstance(update.id, bpy.types.Object):
            if update.is_updated_geometry:
                geometry.append(ident(update.id.original))
            else:
                # moved, or any other change (display, in front, ...): what instances it
                # (a collection, a particle system, a vertex parent) may draw it otherwise
                moved.append(ident(update.id.original))
    if geometry or moved:
        extractor.mark(geometry, moved)


@persistent
def on_load(*_args):
    """A file opens with everything the add-on hid shown again (files saved by
    older versions, or by a crash), and live mode off: nothing runs by itself."""
    SESSION.reset()
    visibility.after_load()
    bus.emit("loaded")


@persistent
def on_undo(*_args):
    """Undo and redo replace Blender's data: caches and references are dropped,
    the live timer follows the restored state; the add-on's own local view follows
    the restored record."""
    SESSION.reset()
    SESSION.applying = True
    try:
        visibility.after_undo()
    finally:
        SESSION.applying = False
    if visibility.culled().any():       # hidden for a view nobody recorded: it holds for none
        SESSION.shown = UNKNOWN
    bus.emit("undone")


@persistent
def before_save(*_args):
    visibility.lift()           # no file carries the add-on's hiding


@persistent
def after_save(*_args):
    SESSION.applying = True
    try:
        visibility.reapply()
    finally:
        SESSION.applying = False


HANDLERS = (("depsgraph_update_post", on_depsgraph_update), ("frame_change_post", on_frame_change),
            ("load_post", on_load), ("undo_post", on_undo), ("redo_post", on_undo),
            ("save_pre", before_save), ("save_post", after_save))


def register() -> None:
    for name, f in HANDLERS:
        getattr(bpy.app.handlers, name).append(f)
    bus.subscribe("window", on_window_change)


def unregister() -> None:
    bus.unsubscribe("window", on_window_change)
    for name, f in reversed(HANDLERS):
        h = getattr(bpy.app.handlers, name)
        if f in h:
            h.remove(f)
