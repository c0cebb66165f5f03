"""Set up the farm test inside Blender (bpy from PyPI): install the extension zip into the
user folder ``$BLENDER_USER_RESOURCES`` (what a farm worker has) and save a shot: a camera
walking past a wall over frames 1-7 with boxes behind it, one of them moving.

Usage: python farm_scene.py EXTENSION.zip OUT.blend
"""

import math
import sys

import bpy


def box(name, lo, hi):
    obj = bpy.data.objects.new(name, bpy.data.meshes.new(name))
    (x0, y0, z0), (x1, y1, z1) = (-0.5, -0.5, -0.5), (0.5, 0.5, 0.5)
    obj.data.from_pydata([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
                          (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], [],
                         [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)])
    bpy.context.scene.collection.objects.link(obj)
    obj.location = [(a + b) / 2 for a, b in zip(lo, hi, strict=True)]
    obj.scale = [b - a for a, b in zip(lo, hi, strict=True)]
    return obj


def main(zip_path, blend):
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 320, 180
    scene.frame_start, scene.frame_end = 1, 7
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)          # looking down +X
    for frame, y in ((1, -9.0), (7, 9.0)):                          # walking along the wall
        cam.location = (-10.0, y, 1.0)
        cam.keyframe_insert("location", frame=frame)
    box("wall", (0, -4, -2), (0.5, 4, 6))
    for i, y in enumerate((-8, -5, -2, 2, 5, 8)):
        box(f"behind_{i}", (3, y - 0.5, 0), (4, y + 0.5, 1))
    mover = box("mover", (2, -1, 0), (2.5, 0, 1))
    for frame, y in ((1, -7.0), (7, 7.0)):
        mover.location = (2.25, y, 0.5)
        mover.keyframe_insert("location", frame=frame)
    for ob in (cam, mover):
        for fc in ob.animation_data.action.fcurves if hasattr(ob.animation_data.action, "fcurves") else ():
            for k in fc.keyframe_points:
                k.interpolation = "LINEAR"
    scene.frame_set(1)
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    print("FARM_SCENE_SAVED", blend)


main(sys.argv[1], sys.argv[2])
