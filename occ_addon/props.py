"""Settings on ``scene.occ``, the per-object "never cull" flag and the hide records."""

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, PointerProperty

from ..core import REGISTRY
from ..core.settings import MAX_RESOLUTION
from . import bus

# The add-on's default is the best-culling conservative strategy, not the engine's
# "auto": auto weighs the engine's own drawing against its tests and may hide nothing
# occluded when the GPU draws fast, but here what is saved is Blender's drawing.  "gpu"
# keeps no more objects than om_coherent on any sample scene (R/V' 1.06-1.50 against
# 1.07-2.10) at a fraction of its CPU time, and is om_coherent where it cannot run (4.1).
ADDON_DEFAULT_STRATEGY = "gpu"
STRATEGY_ITEMS = [(info.name, info.label + (" (default)" if info.name == ADDON_DEFAULT_STRATEGY else ""),
                   info.description)
                  for info in REGISTRY.values() if not info.needs_truth and info.name != "auto"]


def _changed(_self, _context):
    """A setting that changes what may be hidden: announced on the change bus (live
    mode re-culls; the render keys are checked again: no depsgraph update reports it)."""
    bus.notify()
    bus.emit("setting")


class OccSettings(bpy.types.PropertyGroup):
    # No update callbacks here: bpy 4.2 (the PyPI module) segfaults at interpreter exit
    # once a PropertyGroup with one was registered, even after unregistering it (a farm
    # task would fail after its work).  Live mode polls the settings that change what may
    # be hidden instead (:func:`settings_key`, :mod:`.live`).
    source: EnumProperty(
        name="Source", default="VIEWPORT",
        items=[("VIEWPORT", "Viewport", "Cull for the active 3D viewport's view"),
               ("CAMERA", "Scene Camera", "Cull for the scene camera at the render resolution")])
    strategy: EnumProperty(name="Strategy", items=STRATEGY_ITEMS, default=ADDON_DEFAULT_STRATEGY)
    preset: EnumProperty(
        name="Accuracy", default="conservative",
        items=[("conservative", "Conservative", "Query at the display resolution: hides nothing visible"),
               ("fast", "Fast", "Query at half the display resolution against the display's farthest "
                                "depths: hides nothing visible; faster where queries, not drawing, "
                                "dominate (docs/performance.md)")])
    max_resolution: IntProperty(
        name="Max Query Size", default=1920, min=16, max=MAX_RESOLUTION,
        description="Longest side of the query buffer; larger displays are scaled down to it")
    exclude_collection: PointerProperty(
        name="Exclude", type=bpy.types.Collection,
        description="Objects of this collection are never hidden (they still hide others)")
    exclude_children: BoolProperty(name="Include Child Collections", default=True)
    live: BoolProperty(name="Live", default=False, description="Re-cull when the view changes")
    hide_in: EnumProperty(
        name="Hide In", default="AUTO",
        items=[("AUTO", "Auto", "In the culled 3D view only, in a window; everywhere in background mode "
                                "(scripts and viewport renders see hide_viewport)"),
               ("VIEW", "This View", "Only in the culled 3D view (its local view): other views, windows "
                                     "and scenes keep drawing everything"),
               ("EVERYWHERE", "Every View", "With the monitor icon (hide_viewport), in every view and "
                                            "viewport render; Blender rebuilds its dependency graph "
                                            "after each change (slower at scale)")])
    cull_raytraced: BoolProperty(
        name="Cull Under Ray Tracing", default=False,
        description="Hide occluded objects even where Blender traces rays (Cycles, EEVEE ray tracing): "
                    "their reflections and the light they give may then vanish")
    show_overlay: BoolProperty(name="Overlay", default=True,
                               description="Draw the culled boxes and the figures of the last pass")
    # (the last pass's figures are the session's, passes.LastPass: a pass writes none here)


CLASSES = (OccSettings,)


def settings_key(settings) -> tuple:
    """What of ``scene.occ`` changes what a pass may hide (the exclusion collection and
    its children, where it hides, ray tracing): live mode re-culls when it changes."""
    coll = settings.exclude_collection
    return (coll.name_full if coll is not None else None, settings.exclude_children, settings.hide_in,
            settings.cull_raytraced)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.occ = PointerProperty(type=OccSettings)
    bpy.types.Object.occ_never_cull = BoolProperty(
        name="Never Cull", default=False, description="The occlusion culler never hides this object",
        update=_changed)
    # The record of what the add-on hid (with hide_viewport True: see visibility.py).
    # Files are saved without it; one that carries it (older versions) is restored on load.
    bpy.types.Object.occ_culled = BoolProperty(name="Hidden by Occlusion Culling", default=False,
                                               options={"HIDDEN"})
    # The same for the culled 3D view's local-view bits (visibility.py, localview.py).
    bpy.types.Object.occ_view_culled = BoolProperty(name="Hidden in the Culled View", default=False,
                                                    options={"HIDDEN"})
    # Linked into "Never Visible" by an analysis (analysis.link_collection): the add-on
    # unlinks only what it linked; what the user put there is the user's.
    bpy.types.Object.occ_collected = BoolProperty(name="Collected as Never Visible", default=False,
                                                  options={"HIDDEN"})


def unregister():
    del bpy.types.Object.occ_collected
    del bpy.types.Object.occ_view_culled
    del bpy.types.Object.occ_culled
    del bpy.types.Object.occ_never_cull
    del bpy.types.Scene.occ
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
