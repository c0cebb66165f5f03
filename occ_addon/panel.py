"""The sidebar panel, tab "Occlusion": buttons and the figures of the last pass."""

import bpy

from . import bake
from .session import SESSION


class OCC_PT_panel(bpy.types.Panel):
    bl_label = "Occlusion Culling"
    bl_idname = "OCC_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Occlusion"

    def draw(self, context):
        s = context.scene.occ
        layout = self.layout
        layout.prop(s, "source", expand=True)
        for prop, label in (("strategy", "Method"), ("preset", "Accuracy"), ("max_resolution", "Query px")):
            _labelled(layout, s, prop, label)
        box = layout.box()
        _labelled(box, s, "exclude_collection", "Keep")
        box.prop(s, "exclude_children")
        if context.object is not None:
            box.prop(context.object, "occ_never_cull", text=f"{context.object.name}: never cull")
        row = layout.row(align=True)
        row.operator("occ.cull", icon="HIDE_ON")
        row.operator("occ.restore", icon="HIDE_OFF")
        layout.operator("occ.live", text="Stop Live" if s.live else "Live", icon="PLAY",
                        depress=s.live)
        layout.prop(s, "cull_raytraced")
        layout.prop(s, "show_overlay")
        layout.operator("occ.analyze", icon="RENDER_ANIMATION")
        _baked_shot(layout, context)
        res = layout.box()
        res.label(text="Last pass")
        last = SESSION.last          # the session's, not the scene's: a pass writes no figures there
        if last is None:
            res.label(text="None since the file opened or the last undo")
            return
        if last.rule:
            res.label(text=last.rule, icon="LIGHT")
        for label, value in (("Tested", f"{last.tested:,}"), ("Occluded", f"{last.occluded:,}"),
                             ("Outside view", f"{last.outside:,}"),
                             ("Tris hidden", f"{last.triangles_hidden:,}"),
                             ("Time", f"{last.ms:.1f} ms")):
            split = res.split(factor=0.55)
            split.label(text=label)
            split.label(text=value)


def _baked_shot(layout, context):
    """Bake Shot, Use Baked Shot and what the bake holds (or why it no longer does)."""
    b = context.scene.occ_bake
    box = layout.box()
    row = box.row(align=True)
    row.operator("occ.bake_shot", icon="REC")
    if b.hidden:
        row.operator("occ.bake_clear", text="", icon="TRASH")
        box.operator("occ.bake_use", text="Use Baked Shot", icon="PLAY", depress=b.use)
        row = box.row(align=True)
        row.operator("occ.render_baked", icon="RENDER_STILL")
        row.operator("occ.bake_render", text="Remove from Render" if b.render_keys else "Apply to Render",
                     icon="RENDER_ANIMATION", depress=bool(b.render_keys))
        box.label(text=b.summary)
        if b.render_note and not b.render_keys:
            box.label(text=f"Render keys {b.render_note}", icon="INFO")
        why = bake.STATE.stale if bake.STATE.known else None
        if why:
            box.label(text=f"Stale: {why}; bake again", icon="ERROR")
        elif bake.STATE.camera_off is not None:
            box.label(text=f"Frame {bake.STATE.camera_off}: the camera is not the baked one", icon="ERROR")
        elif b.use and bake.STATE.owns():
            # Blender's update after each frame's change: where it outgrows the draw it saves
            # (tens of thousands of objects), playback is faster without the bake
            box.label(text=f"Last frame: {bake.STATE.changed:,} changed, {bake.STATE.apply_ms:.0f} ms update")
            advice = bake.STATE.playback.advice()
            if advice is not None:
                box.label(text=f"The update ({advice[0]:.0f} ms a frame) outweighs the drawing", icon="ERROR")
                box.label(text=f"it saves (about {advice[1]:.0f} ms): play without the bake")


def _labelled(layout, data, prop, label):
    """Label left, field right: the sidebar is too narrow for Blender's own split labels."""
    split = layout.split(factor=0.38, align=True)
    split.label(text=label)
    split.prop(data, prop, text="")


CLASSES = (OCC_PT_panel,)
