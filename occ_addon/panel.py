"""The sidebar panel, tab "Occlusion": buttons and the figures of the last pass."""

import bpy


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
        res = layout.box()
        res.label(text="Last pass")
        if s.last_rule:
            res.label(text=s.last_rule, icon="LIGHT")
        for label, value in (("Tested", f"{s.last_tested:,}"), ("Occluded", f"{s.last_occluded:,}"),
                             ("Outside view", f"{s.last_outside:,}"),
                             ("Tris hidden", f"{s.last_triangles_hidden:,}"),
                             ("Time", f"{s.last_ms:.1f} ms")):
            split = res.split(factor=0.55)
            split.label(text=label)
            split.label(text=value)


def _labelled(layout, data, prop, label):
    """Label left, field right: the sidebar is too narrow for Blender's own split labels."""
    split = layout.split(factor=0.38, align=True)
    split.label(text=label)
    split.prop(data, prop, text="")


CLASSES = (OCC_PT_panel,)
