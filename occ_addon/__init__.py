"""Blender glue: settings, operators, panel, live mode, handlers.  Registers in
order and unregisters in reverse; no GPU or timer work happens here.

Modules: :mod:`.session` (the engine's lifecycle and a pass), :mod:`.cameras`,
:mod:`.extract` (Blender to arrays: the candidates and the extractor) and what it reads
with: :mod:`.kinds` (what an object is), :mod:`.drawn` (what a view draws),
:mod:`.meshes`, :mod:`.instances` (geometry in bulk), :mod:`.fingerprints` (what a hidden
object's geometry was read from); :mod:`.policy` (what is never hidden),
:mod:`.visibility` (the hide record), :mod:`.passes` (what a pass leaves behind),
:mod:`.analysis`, :mod:`.bake` (baked shots), :mod:`.live`, :mod:`.handlers` (Blender's handlers), :mod:`.bus`
(the change bus), and the faces: :mod:`.operators`, :mod:`.panel`, :mod:`.overlay`, :mod:`.props`.
"""

import sys

import bpy

from . import bake, handlers, identity, live, localview, operators, panel, props, render_keys, visibility, worker
from .session import SESSION

CLASSES = operators.CLASSES + panel.CLASSES


def register():
    worker.guard_operator_calls(sys.modules["bpy.ops"])   # another add-on's operators wait for the engine
    props.register()
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    operators.register_keys()
    localview.subscribe()
    handlers.register()
    bake.register()                                  # after the add-on's own frame handler
    render_keys.register()                           # after the bake's: its state is reset first
    live.register()                                  # live mode listens on the change bus
    if isinstance(bpy.data, bpy.types.BlendData):    # enabled on an open file: show what a record hides
        identity.forget()                            # (records written while it was off: undo, redo)
        visibility.restore()
        # and render keys go: an edit made while the add-on was off was seen by nothing
        render_keys.remove("removed: the add-on was enabled on an open file (edits made while it was off "
                           "are not known); apply again")
        live.after_load()                            # and live shows off: no timer runs yet


def unregister():
    live.uninstall()
    live.stop_all()
    if isinstance(bpy.data, bpy.types.BlendData):
        visibility.restore()
    SESSION.shutdown()
    live.unregister()
    render_keys.unregister()
    bake.unregister()
    handlers.unregister()
    localview.unsubscribe()
    operators.unregister_keys()
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
    props.unregister()
    worker.unguard_operator_calls()
