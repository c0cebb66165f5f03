"""Blender glue: settings, operators, panel, live mode, handlers.  Registers in
order and unregisters in reverse; no GPU or timer work happens here."""

import bpy
from bpy.app.handlers import persistent

from . import live, operators, panel, props, visibility
from .session import SESSION, on_depsgraph_update, on_frame_change

CLASSES = operators.CLASSES + panel.CLASSES


@persistent
def _on_load(*_args):
    """A file opens with everything the add-on hid shown again (files saved by
    older versions, or by a crash), and live mode off: nothing runs by itself."""
    SESSION.reset()
    visibility.restore()
    live.after_load()


@persistent
def _on_undo(*_args):
    """Undo and redo replace Blender's data: caches and references are dropped,
    the live timer follows the restored state."""
    SESSION.reset()
    live.resync()


@persistent
def _before_save(*_args):
    visibility.lift()           # no file carries the add-on's hiding


@persistent
def _after_save(*_args):
    SESSION.applying = True
    try:
        visibility.reapply()
    finally:
        SESSION.applying = False


HANDLERS = (("depsgraph_update_post", on_depsgraph_update), ("frame_change_post", on_frame_change),
            ("load_post", _on_load), ("undo_post", _on_undo), ("redo_post", _on_undo),
            ("save_pre", _before_save), ("save_post", _after_save))


def register():
    props.register()
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    for name, f in HANDLERS:
        getattr(bpy.app.handlers, name).append(f)
    if isinstance(bpy.data, bpy.types.BlendData):    # enabled on an open file: show what a record hides
        visibility.restore()
        live.after_load()                            # and live shows off: no timer runs yet


def unregister():
    from . import overlay
    overlay.uninstall()
    live.stop_all()
    if isinstance(bpy.data, bpy.types.BlendData):
        visibility.restore()
    SESSION.shutdown()
    for name, f in reversed(HANDLERS):
        h = getattr(bpy.app.handlers, name)
        if f in h:
            h.remove(f)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
    props.unregister()
