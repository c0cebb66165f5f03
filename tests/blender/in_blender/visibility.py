"""The hide record (occ_addon/visibility.py): the user owns every hide flag."""


import bpy

from .common import box, check, cull, hidden_by_addon, new_scene, update


def user_hide_wins():
    """A user's show then hide on an object the add-on hid is the user's hide."""
    new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    cull()
    t = bpy.data.objects["target"]
    hid = hidden_by_addon("target")
    t.hide_viewport = False
    update()
    t.hide_viewport = True
    update()
    bpy.ops.occ.restore()
    check("user_hide_kept_by_restore", hid and bpy.data.objects["target"].hide_viewport,
          (hid, bpy.data.objects["target"].hide_viewport))
    cull()
    bpy.ops.occ.restore()
    check("user_hide_kept_by_pass", bpy.data.objects["target"].hide_viewport
          and not bpy.data.objects["target"].occ_culled, "")
