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
        col = layout.column(align=True)
        col.prop(s, "strategy")
        col.prop(s, "preset")
        col.prop(s, "max_resolution")
        box = layout.box()
        box.label(text="Never hide")
        box.prop(s, "exclude_collection")
        box.prop(s, "exclude_children")
        if context.object is not None:
            box.prop(context.object, "occ_never_cull", text=f"{context.object.name}: never cull")
        row = layout.row(align=True)
        row.operator("occ.cull", icon="HIDE_ON")
        row.operator("occ.restore", icon="HIDE_OFF")
        layout.operator("occ.live", text="Stop Live" if s.live else "Live", icon="PLAY",
                        depress=s.live)
        layout.prop(s, "show_overlay")
        layout.operator("occ.analyze", icon="RENDER_ANIMATION")
        res = layout.box()
        res.label(text="Last pass")
        grid = res.grid_flow(columns=2, align=True)
        for label, value in (("Tested", s.last_tested), ("Occluded", s.last_occluded),
                             ("Outside view", s.last_outside),
                             ("Triangles hidden", f"{s.last_triangles_hidden:,}"),
                             ("Time", f"{s.last_ms:.1f} ms")):
            grid.label(text=label)
            grid.label(text=str(value))


CLASSES = (OCC_PT_panel,)
