"""Occlusion Culled Viewport: hides what the viewport or the scene camera cannot see.

This file only registers; the add-on lives in ``occ_addon`` and the engine in
``core``.  Nothing heavy is imported at module level.
"""

bl_info = {           # for Blender 3.4+ as a legacy add-on; 4.2+ reads blender_manifest.toml
    "name": "Occlusion Culled Viewport",
    "author": "Occlusion Culling Team",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D View > Sidebar > Occlusion",
    "description": "Hide the objects the viewport or the scene camera cannot see",
    "category": "3D View",
}


def register():
    from . import occ_addon
    occ_addon.register()


def unregister():
    from . import occ_addon
    occ_addon.unregister()
