"""Blender glue: settings, operators, panel, live mode, handlers.  Registers in
order and unregisters in reverse; no GPU or timer work happens here."""

import bpy
from bpy.app.handlers import persistent

from . import operators, panel, props, visibility
from .session import SESSION, on_depsgraph_update

CLASSES = operators.CLASSES + panel.CLASSES


@persistent
def _restore_on_load(_dummy):
    """A file saved while culled opens with everything the add-on hid shown again."""
    SESSION.reset()
    visibility.restore()


def register():
    props.register()
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.app.handlers.load_post.append(_restore_on_load)
    bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)


def unregister():
    from . import live, overlay
    overlay.uninstall()
    if bpy.context.scene is not None and getattr(bpy.context.scene, "occ", None) is not None:
        if bpy.context.scene.occ.live:
            live.stop(bpy.context)
    visibility.restore()
    SESSION.shutdown()
    for h, f in ((bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
                 (bpy.app.handlers.load_post, _restore_on_load)):
        if f in h:
            h.remove(f)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
    props.unregister()
