"""Blender's handlers (occ_addon/handlers.py): no file is saved with the add-on's hiding;
old files and enabling restore what a record hides."""

import os

import bpy
import numpy as np

from .common import MOD, WORK, addon, analyzed_objects, box, check, cull, drawn, hidden_by_addon, new_scene, update


def files_carry_no_hiding():
    """Files saved while culled carry no hiding; old files are restored; analyze sees all."""
    new_scene()
    box("target", (3, -1, 0), (4, 1, 1))
    update()
    cull()
    path = os.path.join(WORK, "saved_culled.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    check("save_keeps_culled", hidden_by_addon("target"), "")
    bpy.ops.preferences.addon_disable(module=MOD)
    bpy.ops.wm.open_mainfile(filepath=path)
    check("saved_file_opens_shown_without_addon", not bpy.data.objects["target"].hide_viewport, "")
    # an old file (an older version of the add-on saved its hiding): saved without
    # the save handlers, opened without the add-on, which is enabled afterwards
    bpy.ops.preferences.addon_enable(module=MOD)
    handlers = addon("handlers")
    saves = [(h, f) for h, f in ((bpy.app.handlers.save_pre, handlers.before_save),
                                 (bpy.app.handlers.save_post, handlers.after_save)) if f in h]
    for h, f in saves:
        h.remove(f)
    addon("visibility").apply(np.array([o.name == "target" for o in bpy.data.objects]))
    old = os.path.join(WORK, "old_culled.blend")
    bpy.ops.wm.save_as_mainfile(filepath=old)
    for h, f in saves:
        h.append(f)
    bpy.ops.preferences.addon_disable(module=MOD)
    bpy.ops.wm.open_mainfile(filepath=old)
    hidden_before = bpy.data.objects["target"].hide_viewport
    bpy.ops.preferences.addon_enable(module=MOD)        # enabled after the file loaded
    check("old_file_restored_on_enable", hidden_before and drawn("target"), hidden_before)
    bpy.ops.wm.open_mainfile(filepath=old)
    check("old_file_restored_on_load", drawn("target"), "")
    # analyze on a scene with a record (the add-on's hiding counts as shown)
    vis = addon("visibility")
    vis.apply(np.array([o.name == "target" for o in bpy.data.objects]))
    bpy.data.objects["wall"].location.z = -20.0        # target in view now
    update()
    seen = analyzed_objects("files")
    check("analyze_counts_hidden", seen.get("target", {}).get("frames_visible") == 1, seen)
